// The user's flow: open the app, press "Where am I?", hear and read where they are. The fake camera
// plays a clip rendered at a known pose in the demo venue, which the server modelled from video.
import { expect, test, type Request } from '@playwright/test';
import { ELSEWHERE, base, chromiumArgs, chromiumPath } from './env';
import { clipTruth, countLocates, expectNoAxeViolations, spoken, spyOnSpeech } from './helpers';

const angle = (a: number, b: number) => Math.abs(((a - b + 540) % 360) - 180);

test('Where am I? answers within 2 m and 10 degrees, spoken and in the live region, from features only', async ({
  page,
}) => {
  await spyOnSpeech(page);
  const requests: Request[] = [];
  page.on('request', (r) => requests.push(r));
  await page.goto(`${base()}/?venue=demo`);
  // the live region is in the page before anything is said in it
  await expect(page.locator('#live[role=status][aria-live=polite]')).toHaveCount(1);
  await expect(page.locator('#venue-line')).toContainText('Ready');
  await expectNoAxeViolations(page, 'the locate screen before an answer');

  const answered = page.waitForResponse((r) => r.url().includes('/locate') && r.request().method() === 'POST');
  await page.getByRole('button', { name: 'Where am I?' }).click();
  const res = await answered;
  expect(res.status()).toBe(200);
  const a = await res.json();
  const t = clipTruth();
  expect(Math.hypot(a.x - t.x, a.y - t.y), `answer (${a.x}, ${a.y}) vs truth (${t.x}, ${t.y})`).toBeLessThanOrEqual(2);
  expect(angle(a.heading_deg, t.heading_deg), `heading ${a.heading_deg} vs ${t.heading_deg}`).toBeLessThanOrEqual(10);
  expect(a.low_confidence).toBe(false);
  expect(a.sent).toBe('features');

  // what the user hears is what the screen reader reads, and it names the place
  const live = page.locator('#live');
  await expect(live).toContainText('You are in');
  const sentence = (await live.textContent())!;
  expect(sentence).toMatch(/o'clock/); // the default direction style
  await expect.poll(() => spoken(page)).toContain(sentence);
  // speech was unlocked inside the first tap (iOS speaks only after that), before any answer
  const first = (await page.evaluate(() => window.__utterances))[0];
  expect(first).toEqual({ text: ' ', inGesture: true });
  await expect(page.locator('#answer-text')).toHaveText(sentence);
  expect(await page.evaluate(() => window.__vibrated.length)).toBeGreaterThan(0);

  // the request carried a feature record, not pictures: "ONV" header, 896 bytes per frame, the
  // sizes the venue document states
  const { features } = await (await fetch(`${base()}/api/venues/demo`)).json();
  expect(features.record_bytes_per_frame).toBe(896);
  const locates = requests.filter((r) => r.url().includes('/locate'));
  expect(locates).toHaveLength(1);
  const body = locates[0].postDataBuffer()!;
  expect(locates[0].headers()['content-type']).toBe('application/octet-stream');
  expect(body.subarray(0, 3).toString()).toBe('ONV');
  const frames = body.readUInt32LE(10);
  expect(frames).toBeGreaterThanOrEqual(8);
  expect(body.length).toBe(features.record_header_bytes + 896 * frames);
  for (const r of requests) expect(r.headers()['content-type'] ?? '', r.url()).not.toMatch(/image|video|multipart/);
  await expect(page.locator('#debug-facts')).toContainText('896');

  // the plan's text alternative tells the same answer; nothing is only on the map
  await expect(page.locator('#plan')).toHaveAttribute('aria-label', /you are in .*within about/);
  await expectNoAxeViolations(page, 'the locate screen with an answer');

  // Repeat says the last sentence again
  const before = (await spoken(page)).length;
  await page.getByRole('button', { name: 'Repeat' }).click();
  await expect.poll(async () => (await spoken(page)).slice(before)).toContain(sentence);

  // another direction style, chosen in Settings, rephrases the same answer
  await page.getByRole('button', { name: 'Settings' }).click();
  await page.getByLabel(/Left and right/).check();
  await page.getByRole('button', { name: 'Locate' }).click();
  await expect(page.locator('#answer-text')).not.toContainText("o'clock");
  await expect(page.locator('#answer-text')).toContainText(/ahead|right|left|behind/);
});

test('continuous mode tracks one session, re-locates and speaks only when something changed', async ({ page }) => {
  await spyOnSpeech(page);
  const posts = countLocates(page);
  // each request's query, and the server's tracking state in its answer
  const queries: URLSearchParams[] = [];
  const frames: number[] = [];
  const tracking: { session: string; restarted: boolean; updates: number }[] = [];
  page.on('request', (r) => {
    if (!r.url().includes('/locate')) return;
    queries.push(new URL(r.url()).searchParams);
    frames.push(r.postDataBuffer()!.readUInt32LE(10));
  });
  page.on('response', async (r) => {
    if (r.url().includes('/locate') && r.ok()) tracking.push((await r.json()).tracking);
  });
  await page.goto(`${base()}/?venue=demo`);
  await page.getByRole('button', { name: 'Settings' }).click();
  await page.getByLabel(/When telling continuously/).selectOption('2');
  await page.getByRole('button', { name: 'Locate' }).click();
  const toggle = page.getByRole('button', { name: 'Keep telling me' });
  await toggle.click();
  await expect(toggle).toHaveAttribute('aria-pressed', 'true');
  await expect.poll(posts, { timeout: 60_000 }).toBeGreaterThanOrEqual(3);
  await expectNoAxeViolations(page, 'the locate screen while telling continuously');
  await toggle.click();
  await expect(toggle).toHaveAttribute('aria-pressed', 'false');
  // the user stood still: three answers, one sentence (then "Stopped telling you.")
  const said = (await spoken(page)).filter((s) => s.startsWith('You are'));
  expect(said).toHaveLength(1);
  await expect(page.locator('#answer-text')).toHaveText(said[0]);

  // consecutive answers come from the tracking filter: one session, the phone's clock going on;
  // the first turn films ~1 s, every turn after an answered one ~2 s (KEEP_SECONDS), never 3 s
  const session = queries[0].get('session')!;
  expect(session).toMatch(/^[A-Za-z0-9_-]{8,64}$/);
  expect(queries.map((q) => q.get('session'))).toEqual(queries.map(() => session));
  const t = queries.map((q) => Number(q.get('t')));
  for (let i = 1; i < t.length; i++) expect(t[i], `t of request ${i}`).toBeGreaterThan(t[i - 1]);
  expect(frames[0], 'frames of the first turn').toBeLessThanOrEqual(12);
  for (const n of frames.slice(1)) {
    expect(n, 'frames of a later turn').toBeGreaterThanOrEqual(15);
    expect(n, 'frames of a later turn').toBeLessThanOrEqual(24);
  }
  await expect.poll(() => tracking.length).toBeGreaterThanOrEqual(3);
  expect(tracking[0]).toMatchObject({ session, restarted: true, updates: 1 });
  expect(tracking[1]).toMatchObject({ session, restarted: false });
  // a 2 s turn is walked second by second: two updates (three where a slow camera stretched it)
  const steps = tracking.slice(1).map((k, i) => k.updates - tracking[i].updates);
  expect(
    steps.filter((d) => d < 2 || d > 3),
    `updates ${tracking.map((k) => k.updates)}`,
  ).toEqual([]);

  // started again: a new session
  const before = queries.length;
  await toggle.click();
  await expect.poll(() => queries.length, { timeout: 60_000 }).toBeGreaterThan(before);
  await toggle.click();
  const next = queries[before].get('session');
  expect(next).toMatch(/^[A-Za-z0-9_-]{8,64}$/);
  expect(next).not.toBe(session);
});

test('a clip from a building the venue has never seen: "not sure", not a wrong place', async ({ playwright }) => {
  const browser = await playwright.chromium.launch({ executablePath: chromiumPath(), args: chromiumArgs(ELSEWHERE) });
  const page = await (await browser.newContext({ permissions: ['camera'] })).newPage();
  try {
    await spyOnSpeech(page);
    await page.goto(`${base()}/?venue=demo`);
    await expect(page.locator('#venue-line')).toContainText('Ready');
    const answered = page.waitForResponse((r) => r.url().includes('/locate'));
    await page.getByRole('button', { name: 'Where am I?' }).click();
    expect((await (await answered).json()).low_confidence).toBe(true);
    await expect(page.locator('#live')).toHaveText('Not sure where you are; turn slowly and try again.');
    await expect.poll(() => spoken(page)).toContain('Not sure where you are; turn slowly and try again.');
    await expect(page.locator('#answer-facts')).not.toContainText('Nearest place');
    await expect(page.locator('#plan')).toHaveAttribute(
      'aria-label',
      /no position shown, the last answer was not sure/,
    );
  } finally {
    await browser.close();
  }
});

test('a venue modelled with a setting this app does not know: told to update, no features sent', async ({ page }) => {
  // a newer server's venue document (levelling was such a setting for the apps before it): the
  // sizes all agree, so without the check the app would send curves made without the setting
  await page.route(
    (u) => u.pathname === '/api/venues/demo',
    async (route) => {
      const res = await route.fetch();
      const doc = await res.json();
      doc.features.feature_keys = [...doc.features.feature_keys, 'sky_mask'];
      await route.fulfill({ response: res, json: doc });
    },
  );
  await spyOnSpeech(page);
  const posts = countLocates(page);
  await page.goto(`${base()}/?venue=demo`);
  const said = 'This copy of omninav is older than this building’s map. Close omninav and open it again to update it.';
  await expect(page.locator('#venue-line')).toHaveText(`Venue: Synthetic demo venue. ${said}`); // before anything is asked
  await page.getByRole('button', { name: 'Where am I?' }).click();
  await expect(page.getByRole('alert')).toHaveText(said); // an error is an alert, spoken at once
  await expect.poll(() => spoken(page)).toContain(said);
  expect(posts()).toBe(0);
});

test('with the camera open, a press answers at once from the second kept before it', async ({ page }) => {
  await page.addInitScript(() => {
    // the moment of each press, on the page's clock
    document.addEventListener(
      'click',
      (e) => {
        if ((e.target as Element).id === 'where')
          (window as unknown as { __pressed: number }).__pressed = performance.now();
      },
      true,
    );
    const speak = speechSynthesis.speak.bind(speechSynthesis);
    (window as unknown as { __saidAt: number[] }).__saidAt = [];
    speechSynthesis.speak = (u: SpeechSynthesisUtterance) => {
      if (u.text.startsWith('You are')) (window as unknown as { __saidAt: number[] }).__saidAt.push(performance.now());
      speak(u);
    };
  });
  const posts = countLocates(page);
  await page.goto(`${base()}/?venue=demo`);
  await expect(page.locator('#venue-line')).toContainText('Ready');
  const where = page.locator('#where');
  await where.click(); // the camera opens: this press films its own second
  await expect(page.locator('#debug-facts')).toContainText('filmed after the press');
  await expect(where).toHaveText('Where am I?');
  await page.waitForTimeout(1500); // the camera stays open: the last second is kept meanwhile
  expect(posts(), 'standing by sends nothing').toBe(1);
  await where.click();
  await expect(page.locator('#debug-facts')).toContainText('kept before the press');
  await expect(page.locator('#debug-facts')).toContainText(/Standing by.*the worker busy \d+ % of the time/);
  const ms = await page.evaluate(() => {
    const w = window as unknown as { __pressed: number; __saidAt: number[] };
    return w.__saidAt[w.__saidAt.length - 1] - w.__pressed;
  });
  expect(ms, 'press to the first word, the camera open').toBeLessThanOrEqual(500);
  expect(posts()).toBe(2);

  // turned off in Settings: each press films its own second again
  await page.getByRole('button', { name: 'Settings' }).click();
  await page.getByLabel('Keep the last second ready').uncheck();
  await page.getByRole('button', { name: 'Locate' }).click();
  await page.waitForTimeout(1500);
  await where.click();
  await expect(page.locator('#debug-facts')).toContainText('filmed after the press');
});
