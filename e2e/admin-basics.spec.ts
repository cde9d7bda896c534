// The admin page, steps 1-5 (issue 11): sign in (a wrong token first), venues (create, rename,
// delete with what is lost), the floor plan and its scale by two clicks and a distance, places
// (click, drag, area, typed values, import, export, delete), a lens profile over a video's frame,
// and a second tab's stale save refused with "changed since you opened it". axe on every screen.
import { readFileSync, writeFileSync } from 'node:fs';
import { resolve } from 'node:path';
import { expect, test, type Locator, type Page } from '@playwright/test';
import { TOKEN, WORK, base } from './env';
import { expectNoAxeViolations } from './helpers';

/** Made by `fixtures.py admin` in global-setup: plan.png, lens.json, walk.mp4 and admin.json. */
const ADMIN = resolve(WORK, 'admin');
const VENUE = 'basics';
const AUTH = { Authorization: `Bearer ${TOKEN}` };

interface Facts {
  plan: { size_px: [number, number]; px_per_m: number };
  scale: { a_px: [number, number]; b_px: [number, number]; distance_m: number };
}

interface PublicVenue {
  revision: number;
  floors: { id: string; px_per_m: number | null; plan_size_px: [number, number] | null }[];
  places: { id: string; name: string; x: number; y: number; area?: number[]; kind?: string }[];
}

async function venueDoc(page: Page): Promise<PublicVenue> {
  const r = await page.request.get(`${base()}/api/venues/${VENUE}`);
  expect(r.ok()).toBe(true);
  return (await r.json()) as PublicVenue;
}

/** The screen point of a plan pixel: the plan image's box on screen, scaled from its natural size. */
async function screenOf(page: Page, px: readonly [number, number]): Promise<{ x: number; y: number }> {
  const img = page.locator('img.pm-plan');
  await expect(img).toBeVisible();
  // the whole map in view (a focused field beside it may have scrolled it), clear of the footer
  await page.locator('.planmap').evaluate((e) => e.scrollIntoView({ block: 'center' }));
  const box = (await img.boundingBox())!;
  const [w, h] = await img.evaluate((i: HTMLImageElement) => [i.naturalWidth, i.naturalHeight]);
  return { x: box.x + (px[0] * box.width) / w, y: box.y + (px[1] * box.height) / h };
}

/** The screen point of plan metres, at the floor's scale. */
const screenOfMetres = (page: Page, x: number, y: number, pxPerM: number) => screenOf(page, [x * pxPerM, y * pxPerM]);

async function signIn(page: Page): Promise<void> {
  await page.goto(`${base()}/admin`);
  await page.getByLabel('Admin token').fill(TOKEN);
  await page.getByRole('button', { name: 'Sign in' }).click();
  await expect(page.getByRole('heading', { name: 'Venues', level: 1 })).toBeVisible();
}

const nav = (page: Page, name: string): Locator =>
  page.getByRole('navigation', { name: 'Venue screens' }).getByRole('link', { name, exact: true });
/** The page's own status region (the checklist's news has another). */
const said = (page: Page): Locator => page.locator('#status');

test('admin basics: sign in, venue, plan and scale, places, lens, a stale save, rename, delete', async ({
  page,
  browser,
}, info) => {
  test.setTimeout(300_000);
  const facts = JSON.parse(readFileSync(resolve(ADMIN, 'admin.json'), 'utf8')) as Facts;
  // a venue left by an earlier run of this spec on a kept server
  await page.request.delete(`${base()}/api/admin/venues/${VENUE}`, { headers: AUTH });

  await test.step('sign in: a wrong token is said clearly, the right one kept in this tab only', async () => {
    await page.goto(`${base()}/admin`);
    await expect(page.getByRole('heading', { name: 'Sign in to omninav admin' })).toBeVisible();
    await expectNoAxeViolations(page, 'the sign-in screen');
    await page.getByLabel('Admin token').fill('not-the-token');
    await page.getByRole('button', { name: 'Sign in' }).click();
    await expect(page.getByRole('alert')).toContainText('Wrong admin token');
    await expect(page.getByLabel('Admin token')).toHaveAttribute('aria-invalid', 'true');
    await expectNoAxeViolations(page, 'the sign-in screen with a wrong token');
    await page.getByLabel('Admin token').fill(TOKEN);
    await page.getByRole('button', { name: 'Sign in' }).click();
    await expect(page.getByRole('heading', { name: 'Venues', level: 1 })).toBeVisible();
    expect(await page.evaluate(() => sessionStorage.getItem('omninav-admin-token'))).toBe(TOKEN);
    expect(await page.evaluate(() => JSON.stringify(localStorage))).not.toContain(TOKEN);
    // the phone app's service worker does not answer /admin with the app
    await page.goto(`${base()}/`);
    await page.goto(`${base()}/admin#/venues`);
    await expect(page.getByRole('heading', { name: 'Venues', level: 1 })).toBeVisible();
  });

  await test.step('venues: list and create', async () => {
    await expect(page.locator('#venue-list')).toContainText('demo');
    await expectNoAxeViolations(page, 'the venues screen');
    // an id already taken: said, and the focus back on the id, marked invalid
    await page.getByLabel('Venue id').fill('demo');
    await page.getByRole('button', { name: 'Create the venue' }).click();
    await expect(page.getByRole('alert')).toContainText("venue 'demo' already exists");
    await expect(page.getByLabel('Venue id')).toBeFocused();
    await expect(page.getByLabel('Venue id')).toHaveAttribute('aria-invalid', 'true');
    await page.getByLabel('Venue id').fill(VENUE);
    await page.getByLabel('Name', { exact: true }).fill('Basics Hall');
    await page.getByRole('button', { name: 'Create the venue' }).click();
    await expect(page).toHaveURL(new RegExp(`#/v/${VENUE}/floor`));
    await expect(page.getByRole('heading', { name: 'Basics Hall', level: 1 })).toBeVisible();
    await expect(page.locator('.venue-facts')).toContainText('revision');
  });

  await test.step('floor: upload the plan, set the scale by two clicks and a distance', async () => {
    await expect(page.getByRole('heading', { name: 'Floor plan', level: 2 })).toBeVisible();
    await expect(page.locator('#floor-facts')).toContainText('no plan yet');
    // a plan that is not an image: refused by the page, and by the server when it claims to be one
    const notes = info.outputPath('notes.txt');
    writeFileSync(notes, 'not a plan');
    await page.getByLabel('Plan image (PNG or JPEG)').setInputFiles(notes);
    await page.getByRole('button', { name: 'Upload the plan' }).click();
    await expect(page.getByRole('alert')).toContainText('notes.txt is not a PNG or JPEG image');
    const fake = info.outputPath('fake.png');
    writeFileSync(fake, 'not a plan either');
    await page.getByLabel('Plan image (PNG or JPEG)').setInputFiles(fake);
    await page.getByRole('button', { name: 'Upload the plan' }).click();
    await expect(page.getByRole('alert')).toContainText('Uploading the plan: the floor plan is not a readable PNG');
    await page.getByLabel('Plan image (PNG or JPEG)').setInputFiles(resolve(ADMIN, 'plan.png'));
    await page.getByRole('button', { name: 'Upload the plan' }).click();
    await expect(said(page)).toContainText('Plan uploaded');
    await expect(page.locator('#floor-facts')).toContainText('the scale is not set');
    await expect(page.locator('.pm-scale-text')).toContainText('scale not set');
    await expectNoAxeViolations(page, 'the floor screen');

    await page.getByRole('button', { name: 'Pick the two points on the plan' }).click();
    const a = await screenOf(page, facts.scale.a_px);
    await page.mouse.click(a.x, a.y);
    await expect(said(page)).toContainText('Now click the second point');
    const b = await screenOf(page, facts.scale.b_px);
    await page.mouse.click(b.x, b.y);
    await expect(page.getByLabel('Distance between the points (metres)')).toBeFocused();
    const typed = await Promise.all(
      ['First point x', 'First point y', 'Second point x', 'Second point y'].map(async (l) =>
        Number(await page.getByLabel(l).inputValue()),
      ),
    );
    const want = [...facts.scale.a_px, ...facts.scale.b_px];
    typed.forEach((v, i) => expect(Math.abs(v - want[i]), `point ${i}: ${v} vs ${want[i]}`).toBeLessThan(3));
    await page.getByLabel('Distance between the points (metres)').fill(String(facts.scale.distance_m));
    await page.getByRole('button', { name: 'Save the scale' }).click();
    await expect(said(page)).toContainText('Scale saved');
    const stored = (await venueDoc(page)).floors[0].px_per_m!;
    expect(Math.abs(stored - facts.plan.px_per_m) / facts.plan.px_per_m).toBeLessThan(0.02);
    await expect(page.locator('#floor-facts')).toContainText('pixels per metre');
    await expect(page.locator('#floor-shown')).toContainText('0 places');
    await expect(page.locator('.pm-scale-text')).toHaveText(/^\d+(\.\d+)? m$/);

    // a zero distance is refused before anything is sent
    await page.getByLabel('Distance between the points (metres)').fill('0');
    await page.getByRole('button', { name: 'Save the scale' }).click();
    await expect(page.getByRole('alert')).toContainText('more than 0 m');
    // not a number ("1e" typed: the field reads as empty): what to type, not "more than 0 m"
    await page.getByLabel('Distance between the points (metres)').fill('');
    await page.getByLabel('Distance between the points (metres)').pressSequentially('1e');
    await page.getByRole('button', { name: 'Save the scale' }).click();
    await expect(page.getByRole('alert')).toContainText('in metres, as a number');
    await expect(page.getByLabel('Distance between the points (metres)')).toBeFocused();
  });

  let pxPerM = facts.plan.px_per_m;
  await test.step('places: click to add, drag to move, type a value, draw an area, delete', async () => {
    pxPerM = (await venueDoc(page)).floors[0].px_per_m!;
    await nav(page, 'Places').click();
    await expect(page.getByRole('heading', { name: 'Places', level: 2 })).toBeVisible();
    await expect(page.locator('#places-count')).toContainText('No place');
    await expectNoAxeViolations(page, 'the places screen');

    await page.getByRole('button', { name: 'Add a place on the plan' }).click();
    const p = await screenOfMetres(page, 11, 2, pxPerM);
    await page.mouse.click(p.x, p.y);
    await expect(page.getByLabel('Place name')).toBeFocused();
    // a click lands within a few screen pixels of the point (a loaded machine may still be easing the map)
    expect(Math.abs(Number(await page.getByLabel('Place x (m)').inputValue()) - 11)).toBeLessThan(0.5);
    await page.getByLabel('Place name').fill('Room 1');
    await page.getByLabel('Kind').selectOption('room');
    await page.getByRole('button', { name: 'Add the place' }).click();
    await expect(said(page)).toContainText('Added Room 1');
    let room = (await venueDoc(page)).places.find((q) => q.name === 'Room 1')!;
    expect(room.kind).toBe('room');
    expect(Math.abs(room.x - 11)).toBeLessThan(0.5);
    expect(Math.abs(room.y - 2)).toBeLessThan(0.5);
    await expectNoAxeViolations(page, 'the places screen with the editor open');

    // drag it 3 m to the right
    const from = await screenOfMetres(page, room.x, room.y, pxPerM);
    const to = await screenOfMetres(page, room.x + 3, room.y, pxPerM);
    await page.mouse.move(from.x, from.y);
    await page.mouse.down();
    await page.mouse.move((from.x + to.x) / 2, to.y, { steps: 5 });
    await page.mouse.move(to.x, to.y, { steps: 5 });
    await page.mouse.up();
    await expect(said(page)).toContainText('Moved Room 1');
    room = (await venueDoc(page)).places.find((q) => q.name === 'Room 1')!;
    expect(Math.abs(room.x - 14)).toBeLessThan(0.4);

    // every value is also typeable
    await page
      .locator('#place-list')
      .getByRole('button', { name: /^Room 1/ })
      .click();
    await page.getByLabel('Place x (m)').fill('12.5');
    await page.getByLabel('Place y (m)').fill('2.25');
    await page.getByRole('button', { name: 'Save the place' }).click();
    await expect(said(page)).toContainText('Saved Room 1');
    room = (await venueDoc(page)).places.find((q) => q.name === 'Room 1')!;
    expect([room.x, room.y]).toEqual([12.5, 2.25]);

    // an area: two corners
    await page.getByRole('button', { name: 'Draw an area on the plan' }).click();
    const c1 = await screenOfMetres(page, 1, 1, pxPerM);
    const c2 = await screenOfMetres(page, 21, 3, pxPerM);
    await page.mouse.click(c1.x, c1.y);
    await expect(said(page)).toContainText('opposite corner');
    await page.mouse.click(c2.x, c2.y);
    await page.getByLabel('Place name').fill('North corridor');
    await page.getByRole('button', { name: 'Add the place' }).click();
    await expect(said(page)).toContainText('Added North corridor');
    const corridor = (await venueDoc(page)).places.find((q) => q.name === 'North corridor')!;
    const area = corridor.area!;
    [1, 1, 21, 3].forEach((v, i) => expect(Math.abs(area[i] - v)).toBeLessThan(0.5));

    // a point inside the area, on the area's own centre marker: picking mode lets the click through
    await page.getByRole('button', { name: 'Add a place on the plan' }).click();
    const centre = await screenOfMetres(page, (area[0] + area[2]) / 2, (area[1] + area[3]) / 2, pxPerM);
    await page.mouse.click(centre.x, centre.y);
    await expect(page.getByRole('heading', { name: 'New place' })).toBeVisible();
    await page.getByLabel('Place name').fill('Room 2');
    await page.getByRole('button', { name: 'Add the place' }).click();
    await expect(said(page)).toContainText('Added Room 2');
    await page
      .locator('#place-list')
      .getByRole('button', { name: /^Room 2/ })
      .click();
    await page.getByRole('button', { name: 'Delete Room 2' }).click();
    await expect(said(page)).toContainText('Deleted Room 2');

    // delete
    await page
      .locator('#place-list')
      .getByRole('button', { name: /^Room 1/ })
      .click();
    await page.getByRole('button', { name: 'Delete Room 1' }).click();
    await expect(said(page)).toContainText('Deleted Room 1');
    expect((await venueDoc(page)).places.map((q) => q.name)).toEqual(['North corridor']);
  });

  await test.step('places: import a place file (a bad one refused with its place) and export', async () => {
    const bad = info.outputPath('bad-places.json');
    writeFileSync(
      bad,
      JSON.stringify([
        { name: 'ok', x: 1, y: 1 },
        { name: 'the lifts', x: 'here', y: 3 },
      ]),
    );
    await page.getByLabel('Place file (JSON)').setInputFiles(bad);
    await page.getByRole('button', { name: 'Import the places' }).click();
    await expect(page.getByRole('alert')).toContainText('place 2 (the lifts)');
    const good = info.outputPath('places.json');
    writeFileSync(
      good,
      JSON.stringify([
        { name: 'the lifts', floor: '1', x: 20, y: 2 },
        { name: 'Corridor 2', x: 20, y: 5.5, area: [18.8, 3.2, 21.2, 8.0] },
      ]),
    );
    await page.getByLabel('Place file (JSON)').setInputFiles(good);
    await page.getByRole('button', { name: 'Import the places' }).click();
    await expect(said(page)).toContainText('Imported 2 places');
    await expect(page.locator('#place-list li')).toHaveCount(3);
    const [download] = await Promise.all([
      page.waitForEvent('download'),
      page.getByRole('button', { name: 'Export the places' }).click(),
    ]);
    const exported = JSON.parse(readFileSync((await download.path())!, 'utf8')) as { name: string; area?: number[] }[];
    expect(exported.map((q) => q.name).sort()).toEqual(['Corridor 2', 'North corridor', 'the lifts']);
    expect(exported.find((q) => q.name === 'Corridor 2')!.area).toEqual([18.8, 3.2, 21.2, 8.0]);
  });

  await test.step('lenses: upload lens.json, see it over a frame of an uploaded video, and its values', async () => {
    await nav(page, 'Lenses').click();
    await expect(page.getByRole('heading', { name: 'Lens profiles', level: 2 })).toBeVisible();
    await page.getByLabel('Lens profile file (lens.json)').setInputFiles(resolve(ADMIN, 'lens.json'));
    await expect(page.getByLabel('Profile name')).toHaveValue('lens');
    await page.getByLabel('Profile name').fill('donut');
    await page.getByRole('button', { name: 'Upload the lens profile' }).click();
    await expect(said(page)).toContainText('Lens profile donut saved');
    const lens = JSON.parse(readFileSync(resolve(ADMIN, 'lens.json'), 'utf8')) as { r_outer: number };
    await expect(page.locator('#lens-table')).toContainText(`${lens.r_outer} pixels`);
    await expect(page.locator('#lens-frame svg circle.ring-outer')).toHaveCount(1);

    // a video through the API (the videos screen is another spec's), then its frame under the rings
    const mp4 = readFileSync(resolve(ADMIN, 'walk.mp4'));
    const made = await page.request.post(`${base()}/api/admin/venues/${VENUE}/videos`, {
      headers: AUTH,
      data: { name: 'walk', floor: '1', lens: 'donut', size: mp4.length },
    });
    expect(made.status(), await made.text()).toBe(201);
    const put = await page.request.put(`${base()}/api/admin/venues/${VENUE}/videos/walk/content`, {
      headers: { ...AUTH, 'Content-Type': 'application/octet-stream' },
      data: mp4,
    });
    expect(put.ok(), await put.text()).toBe(true);
    await nav(page, 'Places').click();
    await nav(page, 'Lenses').click();
    await expect(page.getByLabel('Video', { exact: true })).toHaveValue('walk');
    await page.getByLabel('Time in the video (seconds)').fill('2');
    await page.getByRole('button', { name: 'Show the frame' }).click();
    await expect(page.getByRole('img', { name: 'Frame of walk at 2.0 s' })).toBeVisible();
    await expect(page.locator('#lens-caption')).toContainText('over a frame of walk at 2.0 s');
    await expect(page.locator('#lens-frame svg circle.ring-inner')).toHaveCount(1);
    await expect(page.locator('#lens-frame svg line.forward')).toHaveCount(1);
    await expect(page.locator('#lens-warning')).toBeHidden();
    await expectNoAxeViolations(page, 'the lenses screen');
  });

  await test.step('a second tab with a stale revision: "changed since you opened it", then reload', async () => {
    await nav(page, 'Places').click();
    const other = await browser.newContext();
    await other.addInitScript((t) => sessionStorage.setItem('omninav-admin-token', t), TOKEN);
    const tab = await other.newPage();
    await tab.goto(`${base()}/admin#/v/${VENUE}/places`);
    await expect(tab.getByRole('heading', { name: 'Places', level: 2 })).toBeVisible();
    await expect(tab.locator('#place-list li')).toHaveCount(3);
    // the first tab saves first (its place chosen by keyboard: the marker is a button)
    await page.getByRole('button', { name: /^Place: the lifts/ }).focus();
    await page.keyboard.press('Enter');
    await expect(page.getByRole('heading', { name: 'Edit the lifts' })).toBeFocused();
    await page.getByLabel('Place y (m)').fill('2.5');
    await page.getByRole('button', { name: 'Save the place' }).click();
    await expect(said(page)).toContainText('Saved the lifts');
    // the second tab's save is refused, not a silent overwrite
    await tab.getByRole('button', { name: 'New place by typing' }).click();
    await tab.getByLabel('Place name').fill('Stale place');
    await tab.getByLabel('Place x (m)').fill('3');
    await tab.getByLabel('Place y (m)').fill('3');
    await tab.getByRole('button', { name: 'Add the place' }).click();
    await expect(tab.getByRole('alert')).toContainText('changed since you opened it');
    await expect(tab.locator('#banner')).toContainText('changed since you opened it');
    await expectNoAxeViolations(tab, 'the stale-save banner');
    expect((await venueDoc(page)).places.map((q) => q.name)).not.toContain('Stale place');
    await tab.getByRole('button', { name: 'Reload the venue' }).click();
    await expect(tab.locator('#banner')).toBeHidden();
    await expect(tab.locator('#place-list')).toContainText('the lifts — 20.0 m, 2.5 m');
    await other.close();
  });

  await test.step('floor: another floor of the building, with its own plan to come', async () => {
    await nav(page, 'Floor plan').click();
    await expect(page.getByRole('heading', { name: 'Floor plan', level: 2 })).toBeVisible();
    await page.getByLabel('New floor id').fill('2/3');
    await page.getByRole('button', { name: 'Add the floor' }).click();
    await expect(page.locator('#alert')).toContainText('A floor id is 1 to 32 letters');
    await page.getByLabel('New floor id').fill('2');
    await page.getByLabel('New floor name').fill('Second floor');
    await page.getByRole('button', { name: 'Add the floor' }).click();
    await expect(said(page)).toContainText('Floor Second floor added');
    await expect(page).toHaveURL(/floor=2/);
    await expect(page.locator('#floor-facts')).toContainText('no plan yet');
    await expect(page.getByLabel('Floor', { exact: true })).toHaveValue('2');
    const floors = (await venueDoc(page)).floors;
    expect(floors.map((f) => f.id)).toEqual(['1', '2']);
    expect(floors[1].plan_size_px).toBeNull();
    await expectNoAxeViolations(page, 'the floor screen of a floor without a plan');
  });

  await test.step('venues: rename, then delete after a confirmation naming what is lost', async () => {
    await page.getByRole('link', { name: 'omninav admin' }).click();
    await expect(page.getByRole('heading', { name: 'Venues', level: 1 })).toBeVisible();
    await page.getByRole('button', { name: 'Rename Basics Hall' }).click();
    await page.getByLabel(`New name for ${VENUE}`).fill('Basics Hall East');
    await page.getByRole('button', { name: 'Save the name' }).click();
    await expect(said(page)).toContainText('Renamed basics to Basics Hall East');
    await expect(page.locator('#venue-list')).toContainText('Basics Hall East');
    await page.getByRole('button', { name: 'Delete Basics Hall East…' }).click();
    const confirm = page.locator('.confirm');
    await expect(confirm).toContainText('1 video');
    await expect(confirm).toContainText('3 places');
    await expect(confirm).toContainText('modelled frames');
    await expect(confirm).toContainText('cannot be undone');
    await expectNoAxeViolations(page, 'the delete confirmation');
    await page.getByRole('button', { name: 'Delete Basics Hall East for good' }).click();
    await expect(said(page)).toContainText('Deleted Basics Hall East');
    await expect(page.locator('#venue-list')).not.toContainText('Basics Hall East');
    expect((await page.request.get(`${base()}/api/venues/${VENUE}`)).status()).toBe(404);
  });

  await test.step('sign out forgets the token', async () => {
    await page.getByRole('button', { name: 'Sign out' }).click();
    await expect(page.getByRole('heading', { name: 'Sign in to omninav admin' })).toBeVisible();
    expect(await page.evaluate(() => sessionStorage.getItem('omninav-admin-token'))).toBeNull();
  });
});

test('admin page: served at /admin with a strict policy, and the token gate holds', async ({ page }) => {
  const r = await page.request.get(`${base()}/admin`);
  expect(r.status()).toBe(200);
  const csp = r.headers()['content-security-policy'];
  expect(csp).toContain("script-src 'self'");
  expect(csp).not.toContain('unsafe-inline');
  expect(csp).not.toContain('unsafe-eval');
  // nothing of the phone app links to it
  expect(await (await page.request.get(`${base()}/`)).text()).not.toContain('/admin');
  await signIn(page);
  await page.evaluate(() => sessionStorage.setItem('omninav-admin-token', 'reset-elsewhere'));
  await page.reload();
  await page.getByLabel('Venue id').fill('gate');
  await page.getByRole('button', { name: 'Create the venue' }).click();
  await expect(page.getByRole('heading', { name: 'Sign in to omninav admin' })).toBeVisible();
  await expect(page.locator('#signin-problem')).toContainText('refused the admin token');
});
