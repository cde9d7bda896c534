// Steps of the admin page that several specs take (admin-videos.spec.ts, admin-build.spec.ts): the
// admin API called directly for set-up, and the page driven as an admin drives it. The walk's truth
// comes from e2e/fixtures.py `admin` (data/e2e/admin/admin.json), rendered by global-setup.ts.
import { readFileSync } from 'node:fs';
import { resolve } from 'node:path';
import { expect, type Page } from '@playwright/test';
import { TOKEN, WORK, base } from './env';

/** What fixtures.py `admin` renders: plan.png, lens.json, walk.mp4, eval.mp4 and admin.json. */
export const ADMIN_DIR = resolve(WORK, 'admin');
export const adminFile = (name: string): string => resolve(ADMIN_DIR, name);

export interface TruthWaypoint {
  t?: number;
  frame?: number;
  x: number;
  y: number;
}
export interface TruthWalkPath {
  fps?: number;
  waypoints: TruthWaypoint[];
}
export interface AdminTruth {
  plan: { size_px: [number, number]; px_per_m: number };
  scale: { a_px: [number, number]; b_px: [number, number]; distance_m: number };
  places: { name: string; x?: number; y?: number; area?: [number, number, number, number] }[];
  walk: { walk_path: TruthWalkPath; frames: number; duration_s: number };
  eval: { walk_path: TruthWalkPath; frames: number; duration_s: number };
}

export const adminTruth = (): AdminTruth => JSON.parse(readFileSync(adminFile('admin.json'), 'utf8')) as AdminTruth;

/** An admin API call with the token (no If-Match: the last write wins, as for API clients). */
export async function adminApi<T = unknown>(method: string, path: string, body?: unknown): Promise<T> {
  const headers: Record<string, string> = { Authorization: `Bearer ${TOKEN}` };
  let data: BodyInit | undefined;
  if (body instanceof Uint8Array) {
    headers['Content-Type'] = 'image/png';
    data = body as unknown as BodyInit;
  } else if (body !== undefined) {
    headers['Content-Type'] = 'application/json';
    data = JSON.stringify(body);
  }
  const r = await fetch(`${base()}${path}`, { method, headers, body: data });
  if (!r.ok) throw new Error(`${method} ${path}: ${r.status} ${await r.text()}`);
  return (r.status === 204 ? null : await r.json()) as T;
}

/**
 * A venue with the admin fixture's plan (scaled), places and lens `donut`, made through the API
 * (for specs that start after the steps the page's other screens test). A venue of that id goes first.
 */
export async function venueByApi(id: string, name = `Admin test ${id}`): Promise<void> {
  const truth = adminTruth();
  await fetch(`${base()}/api/admin/venues/${id}`, { method: 'DELETE', headers: { Authorization: `Bearer ${TOKEN}` } });
  await adminApi('POST', '/api/admin/venues', { id, name });
  await adminApi('PUT', `/api/admin/venues/${id}/floors/1`, { name: 'Ground floor' });
  await adminApi('PUT', `/api/admin/venues/${id}/floors/1/plan`, new Uint8Array(readFileSync(adminFile('plan.png'))));
  await adminApi('PUT', `/api/admin/venues/${id}/floors/1`, { px_per_m: truth.plan.px_per_m });
  await adminApi(
    'PUT',
    `/api/admin/venues/${id}/places`,
    truth.places.map((p) => ({
      floor: '1',
      x: p.x ?? (p.area ? (p.area[0] + p.area[2]) / 2 : 0),
      y: p.y ?? (p.area ? (p.area[1] + p.area[3]) / 2 : 0),
      ...p,
    })),
  );
  await adminApi(
    'PUT',
    `/api/admin/venues/${id}/lenses/donut`,
    JSON.parse(readFileSync(adminFile('lens.json'), 'utf8')),
  );
}

/** Open the admin page and sign in with the suite's token. */
export async function signIn(page: Page, query = ''): Promise<void> {
  await page.goto(`${base()}/admin${query}`);
  await page.getByLabel('Admin token').fill(TOKEN);
  await page.getByRole('button', { name: 'Sign in' }).click();
  await expect(page.getByRole('button', { name: 'Sign out' })).toBeVisible();
}

/** Go to a screen of a venue (the page is signed in). */
export async function openScreen(page: Page, venue: string, screen: string, params = ''): Promise<void> {
  await page.evaluate((h) => (location.hash = h), `#/v/${venue}/${screen}${params ? `?${params}` : ''}`);
  await expect(page.locator('main h2').first()).toBeVisible();
}

/** Choose videos on the videos screen with a floor, lens and role. */
export async function chooseVideos(
  page: Page,
  files: string[],
  opts: { lens?: string; role?: 'model' | 'evaluation'; floor?: string } = {},
): Promise<void> {
  if (opts.floor) await page.getByLabel('Floor', { exact: true }).selectOption(opts.floor);
  if (opts.lens) await page.getByLabel('Lens', { exact: true }).selectOption(opts.lens);
  if (opts.role) await page.getByLabel('Role', { exact: true }).selectOption(opts.role);
  await page.getByLabel('Walk video files').setInputFiles(files);
}

/** The upload's progress bar on the videos screen. */
export const uploadBar = (page: Page, name: string) => page.getByRole('progressbar', { name: `Upload of ${name}` });

/** Wait until the videos screen says `name` is uploaded and its turns and stops are found. */
export async function waitUploadedAndSuggested(page: Page, name: string, timeout = 120_000): Promise<void> {
  // what the status region says, as it says it (a later message replaces it)
  await page.evaluate(() => {
    const w = window as unknown as { __said?: string[] };
    if (w.__said) return;
    const said: string[] = (w.__said = []);
    const status = document.getElementById('status')!;
    new MutationObserver(() => status.textContent && said.push(status.textContent)).observe(status, {
      childList: true,
      characterData: true,
      subtree: true,
    });
  });
  const row = page.locator(`li.upload[data-name="${name}"]`);
  await expect(row.locator('.upload-status')).toHaveText(/uploaded/, { timeout });
  await expect(row).toContainText('suggested waypoints', { timeout });
  // the count said is the count the table shows (it was said before the suggestions were loaded: 0)
  const cell = page.locator(`#video-table tr[data-name="${name}"]`);
  await expect(cell).toContainText(/\d+ suggested waypoints/, { timeout });
  const shown = Number((await cell.textContent())!.match(/(\d+) suggested waypoints/)![1]);
  const found = new RegExp(`(\\d+) turns and stops found in ${name.replace('.', '\\.')}`);
  await expect
    .poll(async () =>
      (await page.evaluate(() => (window as unknown as { __said: string[] }).__said)).find((t) => found.test(t)),
    )
    .toBeTruthy();
  const said = (await page.evaluate(() => (window as unknown as { __said: string[] }).__said)).find((t) =>
    found.test(t),
  )!;
  expect(Number(said.match(found)![1]), said).toBe(shown);
  // the screen opened again (another screen, then back): what was said then is not said again
  const heard = async () => (await page.evaluate(() => (window as unknown as { __said: string[] }).__said)).length;
  const before = await heard();
  const screens = page.getByRole('navigation', { name: 'Venue screens' });
  await screens.getByRole('link', { name: 'Places', exact: true }).click();
  await expect(page.getByRole('heading', { name: 'Places', level: 2 })).toBeVisible();
  await screens.getByRole('link', { name: 'Videos', exact: true }).click();
  await expect(page.getByRole('heading', { name: 'Videos', level: 2 })).toBeVisible();
  await page.waitForTimeout(500);
  const again = (await page.evaluate(() => (window as unknown as { __said: string[] }).__said))
    .slice(before)
    .filter((t) => found.test(t) || t.includes(`${name} is uploaded`));
  expect(again).toEqual([]);
}

/** Where the true walk path has the walker at `t` (linear between waypoints, clamped to its ends). */
export function truthAt(walkPath: TruthWalkPath, t: number): { x: number; y: number } {
  const fps = walkPath.fps ?? 30;
  const w = walkPath.waypoints.map((p) => ({ t: p.t ?? (p.frame ?? 0) / fps, x: p.x, y: p.y }));
  if (t <= w[0].t) return w[0];
  for (let i = 1; i < w.length; i++)
    if (t <= w[i].t) {
      const k = (t - w[i - 1].t) / (w[i].t - w[i - 1].t);
      return { x: w[i - 1].x + k * (w[i].x - w[i - 1].x), y: w[i - 1].y + k * (w[i].y - w[i - 1].y) };
    }
  return w[w.length - 1];
}

/** Click the plan (the Leaflet map inside `container`) at (x, y) metres of a plan w_m x h_m metres. */
export async function clickPlanAt(page: Page, container: string, x: number, y: number, sizeM: [number, number]) {
  const img = page.locator(`${container} img.pm-plan`);
  await expect(img).toBeVisible();
  // a plan just shown is still being fitted into view (Leaflet animates the zoom for about 250 ms):
  // a point measured on the moving picture is not the point the map takes the click at. Wait
  // until no zoom animation runs and the picture stays where it is for a moment.
  await expect(page.locator(`${container}.leaflet-zoom-anim, ${container} .leaflet-zoom-anim`)).toHaveCount(0);
  await expect
    .poll(async () => {
      const before = await img.boundingBox();
      await page.waitForTimeout(120);
      return JSON.stringify(before) === JSON.stringify(await img.boundingBox());
    })
    .toBe(true);
  // the map may sit partly below the fold: bring the point itself into the viewport, then check
  // that it lies on the map (a click outside the window or the map's box would go elsewhere)
  const at = async () => {
    const box = await img.boundingBox();
    if (!box) throw new Error('the plan image has no box');
    return { px: box.x + (x / sizeM[0]) * box.width, py: box.y + (y / sizeM[1]) * box.height };
  };
  const view = page.viewportSize()!;
  const first = await at();
  if (first.py < 40 || first.py > view.height - 40)
    await page.evaluate((dy) => window.scrollBy(0, dy), first.py - view.height / 2);
  const { px, py } = await at();
  const map = await page.locator(container).boundingBox();
  if (!map || px < map.x || px > map.x + map.width || py < map.y || py > map.y + map.height)
    throw new Error(`(${x}, ${y}) m is not on the visible map of ${container}`);
  if (px < 0 || px > view.width || py < 0 || py > view.height)
    throw new Error(`(${x}, ${y}) m is outside the window even after scrolling`);
  await page.mouse.click(px, py);
}

/** The plan's size in metres, from the fixture's truth. */
export function planSizeM(truth = adminTruth()): [number, number] {
  return [truth.plan.size_px[0] / truth.plan.px_per_m, truth.plan.size_px[1] / truth.plan.px_per_m];
}

/**
 * On the walk path screen of a video: accept the suggestions in order, clicking the plan where the
 * walker truly was at each suggested moment; -> how many plan clicks it took.
 */
export async function tagBySuggestions(page: Page, walkPath: TruthWalkPath, sizeM = planSizeM()): Promise<number> {
  // what the status region says, as a screen reader hears it: each text it is given
  await page.evaluate(() => {
    const w = window as unknown as { heard: string[] };
    w.heard = [];
    const region = document.getElementById('status')!;
    new MutationObserver(() => {
      if (region.textContent) w.heard.push(region.textContent);
    }).observe(region, { childList: true, characterData: true, subtree: true });
  });
  await page.getByRole('button', { name: 'Tag the suggestions in order' }).click();
  let clicks = 0;
  for (; clicks < 50; clicks++) {
    const current = page.locator('#suggestions button[aria-current="true"]');
    if ((await current.count()) === 0) break;
    const t = Number(await current.getAttribute('data-t'));
    const at = truthAt(walkPath, t);
    await clickPlanAt(page, '#walk-path-plan', at.x, at.y, sizeM);
    // the click is taken: that suggestion is tagged (and the next one, if any, is current)
    await expect(page.locator(`#suggestions li.tagged button[data-t="${t}"]`)).toHaveCount(1);
  }
  // each tag is said once, with what comes next, not alone and then again with it
  const heard = () => page.evaluate(() => (window as unknown as { heard: string[] }).heard);
  const tags = async () => (await heard()).filter((h) => h.includes(' tagged at ')).length;
  await expect.poll(tags).toBeGreaterThanOrEqual(clicks); // the last is said a moment after its click
  await page.waitForTimeout(300);
  expect(await tags(), `tags heard: ${(await heard()).join(' | ')}`).toBe(clicks);
  return clicks;
}

/**
 * The walk path the server keeps for a video: each waypoint where the walker truly was at its time,
 * within `tolM` (the clicks land where they were aimed, the snapping to corridor lines moves them
 * little); -> the largest distance. A click measured against a moving plan would land metres off
 * and make every later figure (modelling, evaluation) wrong for a reason those steps cannot name.
 */
export async function expectSavedWalkPathNear(
  venue: string,
  name: string,
  truth: TruthWalkPath,
  tolM = 1.0,
): Promise<number> {
  const saved = await adminApi<TruthWalkPath>('GET', `/api/admin/venues/${venue}/videos/${name}/walk-path`);
  const fps = saved.fps ?? 30;
  const off = saved.waypoints.map((p) => {
    const t = p.t ?? (p.frame ?? 0) / fps;
    const at = truthAt(truth, t);
    return { t, d: Math.hypot(p.x - at.x, p.y - at.y) };
  });
  const worst = Math.max(...off.map((o) => o.d));
  const far = off.filter((o) => o.d > tolM).map((o) => `${o.t.toFixed(1)} s: ${o.d.toFixed(2)} m`);
  expect(far, `waypoints of ${name} further than ${tolM} m from the walk (largest ${worst.toFixed(2)} m)`).toEqual([]);
  return worst;
}

/** Save the walk path on the walk path screen and wait for the server's yes. */
export async function saveWalkPath(page: Page, name: string): Promise<void> {
  await page.getByRole('button', { name: 'Save the walk path' }).click();
  await expect(page.locator('#walk-path-status')).toContainText(`Walk path of ${name} saved`);
  // disabled while it saved, the button has the focus back, not the page
  await expect(page.getByRole('button', { name: 'Save the walk path' })).toBeFocused();
}

/** On the modelling screen: model the waiting videos and watch the progress bar reach 100 %. */
export async function modelAndWait(page: Page, timeout = 300_000): Promise<void> {
  await page.locator('#model-start').click();
  const bar = page.getByRole('progressbar', { name: 'Modelling progress' });
  await expect(bar).toBeVisible();
  await expect(bar).toHaveAttribute('aria-valuetext', '100 %', { timeout });
  await expect(page.locator('#model-outcome')).toContainText('Modelling done', { timeout: 30_000 });
  // the button was disabled while the job ran: the keyboard's place is on what happened
  await expect(page.locator('#model-outcome')).toBeFocused();
  await expect(page.locator('#live-generation')).toContainText(/generation \d+/);
}
