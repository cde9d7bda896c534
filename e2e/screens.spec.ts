// Every screen passes axe; the problems a user can meet are spoken with what to do about them.
import { readFileSync } from 'node:fs';
import { resolve } from 'node:path';
import { expect, test } from '@playwright/test';
import { TOKEN, WORK, base } from './env';
import { expectNoAxeViolations, spoken, spyOnSpeech, tabTo } from './helpers';

test('settings and about screens: reachable by role and name, no axe violation', async ({ page }) => {
  await page.goto(`${base()}/?venue=demo`);
  await expect(page.locator('#venue-line')).toContainText('Ready');
  await page.getByRole('button', { name: 'Settings' }).click();
  await expect(page.getByRole('heading', { name: 'Settings' })).toBeVisible();
  await expect(page.getByLabel('Venue')).toHaveValue('demo');
  await expect(page.getByLabel('Lens profile', { exact: true })).toHaveValue('donut');
  await expect(page.getByLabel(/Speech rate/)).toBeVisible();
  // the rate is said by its slider, not by a status region at every step
  const rate = page.getByRole('slider', { name: 'Speech rate' });
  await rate.fill('1.5');
  await expect(rate).toHaveAttribute('aria-valuetext', '1.5 times');
  await expect(page.locator('#screen-settings').getByRole('status')).toHaveCount(0);
  await rate.fill('1');
  await expectNoAxeViolations(page, 'the settings screen');
  // on a phone's width every radio and checkbox keeps its size beside a long label
  await page.setViewportSize({ width: 360, height: 740 });
  for (const box of await page
    .locator('#screen-settings input[type=radio], #screen-settings input[type=checkbox]')
    .all())
    expect((await box.boundingBox())?.width, (await box.getAttribute('value')) ?? 'a box').toBeGreaterThanOrEqual(23);
  await page.getByRole('button', { name: 'About' }).click();
  await expect(page.getByRole('heading', { name: 'About omninav' })).toBeVisible();
  await expectNoAxeViolations(page, 'the about screen');
});

test('a screen-reader user, keyboard only: the app stays silent, the answer is in the live region', async ({
  page,
}) => {
  await spyOnSpeech(page);
  await page.goto(`${base()}/?venue=demo`);
  await expect(page.locator('#venue-line')).toContainText('Ready');
  await tabTo(page, page.getByRole('button', { name: 'Settings' }), 'the Settings tab');
  await page.keyboard.press('Enter');
  await expect(page.getByRole('heading', { name: 'Settings' })).toBeFocused();
  // Tab enters the radio group on its checked button, the app's voice (the default); an arrow chooses
  await tabTo(page, page.getByRole('radio', { name: 'The app, in its own voice' }), 'the app voice option');
  await page.keyboard.press('ArrowDown');
  const reader = page.getByRole('radio', { name: /^My screen reader \(VoiceOver, TalkBack\)/ });
  await expect(reader).toBeChecked();
  // rate and voice tune only the app's voice: off now, and say why
  for (const c of [page.getByLabel(/Speech rate/), page.getByLabel('Voice', { exact: true })]) {
    await expect(c).toBeDisabled();
    await expect(c).toHaveAccessibleDescription(/app’s own voice only/);
  }
  await expectNoAxeViolations(page, 'the settings screen, the screen reader reading');
  // what the app says from here on goes to the live region only (the first key press unlocked speech)
  const before = await page.evaluate(() => window.__utterances.length);
  const live = page.locator('#live');
  await tabTo(page, page.getByRole('button', { name: 'Test speech' }), 'Test speech');
  await page.keyboard.press('Enter');
  await expect(live).toContainText('This is how omninav sounds.');

  await tabTo(page, page.getByRole('button', { name: 'Locate' }), 'the Locate tab');
  await page.keyboard.press('Enter');
  await tabTo(page, page.getByRole('button', { name: 'Where am I?' }), 'Where am I?');
  await page.keyboard.press('Enter');
  await expect(live).toContainText('You are in', { timeout: 30_000 });
  const sentence = (await live.textContent())!;
  await expect(page.locator('#answer-text')).toHaveText(sentence);
  expect(await page.evaluate(() => window.__vibrated.length)).toBeGreaterThan(0); // the cue still comes
  await tabTo(page, page.getByRole('button', { name: 'Repeat' }), 'Repeat');
  await page.keyboard.press('Enter');
  await expect(live).toHaveText(sentence);
  expect(await page.evaluate((n) => window.__utterances.slice(n), before)).toEqual([]);

  // the choice is kept: after a reload the app is still silent
  await page.reload();
  await expect(page.locator('#venue-line')).toContainText('Ready');
  await page.getByRole('button', { name: 'Settings' }).click();
  await expect(reader).toBeChecked();
  await page.getByRole('button', { name: 'Test speech' }).click();
  await expect(live).toContainText('This is how omninav sounds.');
  expect(await spoken(page)).toEqual([]);
  // and the app's voice, chosen again, speaks at once
  await page.getByRole('radio', { name: 'The app, in its own voice' }).check();
  await expect(page.getByLabel(/Speech rate/)).toBeEnabled();
  await page.getByRole('button', { name: 'Test speech' }).click();
  await expect.poll(() => spoken(page)).toContainEqual(expect.stringContaining('This is how omninav sounds.'));
});

test('the Go to screen: places by floor, a filter, reachable by role and name, no axe violation', async ({ page }) => {
  await page.goto(`${base()}/?venue=demo`);
  await expect(page.locator('#venue-line')).toContainText('Ready');
  await page.getByRole('button', { name: 'Go to', exact: true }).click();
  await expect(page.getByRole('heading', { name: 'Go to a place' })).toBeFocused();
  await expect(page.locator('#goto-status')).toContainText('to go to.');
  const places = page.locator('#goto-list button.dest');
  expect(await places.count()).toBeGreaterThan(0);
  await expectNoAxeViolations(page, 'the Go to screen');
  await page.getByLabel('Find a place').fill('no such place');
  await expect(page.locator('#goto-status')).toHaveText('No place matches “no such place”.');
  await expect(places).toHaveCount(0);
  await page.getByLabel('Find a place').fill('');
  await expect(places).not.toHaveCount(0);
  // Enter in the filter: of several places, the first takes the focus; the one listed is chosen
  await page.getByLabel('Find a place').press('Enter');
  await expect(places.first()).toBeFocused();
  // a name the filter lists alone (the list re-renders as each value is typed)
  let name = '';
  for (const n of await places.allTextContents()) {
    await page.getByLabel('Find a place').fill(n);
    if ((await places.count()) === 1) {
      name = n;
      break;
    }
  }
  expect(name, 'a place whose name lists it alone').not.toBe('');
  // a place chosen: the route panel (the preview, Start, What next?, Stop guidance) passes axe too
  await page.getByLabel('Find a place').press('Enter');
  await expect(page.getByRole('heading', { name: `Route to ${name}` })).toBeFocused();
  await expect(page.locator('#goto-state')).toHaveText('Press Start when you are ready to walk.', { timeout: 30_000 });
  await expect(page.getByRole('button', { name: 'Start' })).toBeEnabled();
  await expect(places.first()).toHaveAttribute('aria-current', 'true');
  await expectNoAxeViolations(page, 'the Go to screen with a route');
  await page.getByRole('button', { name: 'Stop guidance' }).click();
  await expect(page.locator('#goto-state')).toHaveText('Guidance stopped.');
});

test('camera denied: a spoken message that says how to allow it', async ({ browser }) => {
  const ctx = await browser.newContext({ permissions: [] });
  const page = await ctx.newPage();
  await spyOnSpeech(page);
  await page.goto(`${base()}/?venue=demo`);
  await expect(page.locator('#venue-line')).toContainText('Ready');
  await page.getByRole('button', { name: 'Where am I?' }).click();
  const alert = page.getByRole('alert');
  await expect(alert).toContainText('camera is blocked');
  await expect(alert).toContainText('Allow the camera');
  await expect.poll(() => spoken(page)).toContainEqual(expect.stringContaining('camera is blocked'));
  await expectNoAxeViolations(page, 'the camera-denied message');
  await ctx.close();
});

/** An admin API call; `raw` bytes go as `type`; `allow` lists error statuses that are fine (a retried test). */
async function admin(
  path: string,
  method: string,
  body: unknown,
  { raw, type = 'application/octet-stream', allow = [] }: { raw?: Buffer; type?: string; allow?: number[] } = {},
): Promise<Record<string, unknown>> {
  const r = await fetch(`${base()}/api/admin${path}`, {
    method,
    headers: { Authorization: `Bearer ${TOKEN}`, 'Content-Type': raw ? type : 'application/json' },
    body: raw ? new Uint8Array(raw) : body === undefined ? undefined : JSON.stringify(body),
  });
  if (!r.ok && !allow.includes(r.status)) throw new Error(`${method} ${path}: ${r.status} ${await r.text()}`);
  return r.json();
}

/** Model venue `id` from the demo's own modelling video, through the admin API as an administrator would. */
async function modelFromDemoVideo(id: string): Promise<void> {
  const src = resolve(WORK, 'server/demo-src-quick');
  const video = readFileSync(resolve(src, 'model.mp4'));
  await admin(`/venues/${id}/floors/1`, 'PUT', { name: 'Hall', px_per_m: 20 });
  await admin(`/venues/${id}/floors/1/plan`, 'PUT', null, {
    raw: readFileSync(resolve(src, 'floorplan.png')),
    type: 'image/png',
  });
  await admin(`/venues/${id}/lenses/donut`, 'PUT', JSON.parse(readFileSync(resolve(src, 'model_lens.json'), 'utf8')));
  const walkPath = JSON.parse(readFileSync(resolve(src, 'model_walk_path.json'), 'utf8'));
  await admin(`/venues/${id}/videos`, 'POST', {
    name: 'walk.mp4',
    floor: '1',
    size: video.length,
    walk_path: walkPath,
    lens: 'donut',
  });
  await admin(`/venues/${id}/videos/walk.mp4/content`, 'PUT', null, { raw: video });
  const job = await admin(`/venues/${id}/jobs`, 'POST', { videos: ['walk.mp4'] });
  await expect
    .poll(async () => (await admin(`/jobs/${job.id}`, 'GET', undefined)).state, { timeout: 120_000 })
    .toBe('done');
}

test('a venue without modelled frames: spoken, with what to do; once modelled, it answers', async ({ page }) => {
  await admin('/venues', 'POST', { id: 'empty', name: 'Empty hall' }, { allow: [409] });
  await spyOnSpeech(page);
  await page.goto(`${base()}/?venue=empty`);
  await expect(page.locator('#venue-line')).toContainText('Not modelled yet');
  await page.getByRole('button', { name: 'Where am I?' }).click();
  await expect(page.getByRole('alert')).toContainText('no modelled frames yet');
  await expect.poll(() => spoken(page)).toContainEqual(expect.stringContaining('Ask the venue’s administrator'));
  // the administrator models it while the app stays open: the next press answers
  await modelFromDemoVideo('empty');
  await page.getByRole('button', { name: 'Where am I?' }).click();
  await expect(page.locator('#live')).toContainText('You are on Hall.');
  await expect(page.locator('#venue-line')).toContainText('Ready');
  // a place, but no area drawn: the answer says how far it is and which way, not the floor alone
  await admin('/venues/empty/places', 'PUT', [{ name: 'the far door', floor: '1', x: 400, y: 400 }]);
  await page.getByRole('button', { name: 'Where am I?' }).click();
  await expect(page.locator('#live')).toContainText(
    /^You are (probably )?on Hall, \d+ metres from the far door at \d+ o’?'?clock\./,
  );
});

test('the wrong lens: the camera picture does not fit the chosen profile', async ({ page }) => {
  await admin('/venues/demo/lenses/theta', 'PUT', {
    model: 'equirectangular',
    image_size: [1920, 960],
    forward_x: 960,
  });
  await spyOnSpeech(page);
  await page.goto(`${base()}/?venue=demo`);
  await expect(page.locator('#venue-line')).toContainText('Ready');
  await page.getByRole('button', { name: 'Settings' }).click();
  await page.getByLabel('Lens profile', { exact: true }).selectOption('theta');
  await page.getByRole('button', { name: 'Locate' }).click();
  await page.getByRole('button', { name: 'Where am I?' }).click();
  await expect(page.getByRole('alert')).toContainText('lens profile “theta” is for 1920 by 960');
  await expect.poll(() => spoken(page)).toContainEqual(expect.stringContaining('Attach the lens'));
});

test('an unknown venue in the address: said, and the first venue shown instead', async ({ page }) => {
  // the first venue the server lists (the demo, unless another spec left one of its own)
  const first = ((await (await fetch(`${base()}/api/venues`)).json()) as { venues: { id: string; name: string }[] })
    .venues[0];
  await page.goto(`${base()}/?venue=nope`);
  await expect(page.locator('#venue-line')).toContainText(
    `This server has no venue “nope”; showing ${first.name} instead.`,
  );
  await page.getByRole('button', { name: 'Settings' }).click();
  await expect(page.getByLabel('Venue')).toHaveValue(first.id);
});
