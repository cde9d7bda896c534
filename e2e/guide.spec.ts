// Route guidance end to end (issue 14): the fake camera plays a rendered walk through the demo venue
// (e2e/fixtures.py `walk`: the quick demo's L, from the entrance east past Room 1 to the lifts at
// the corner, then south to the stairs) while the app, on its Go to screen, guides the walker to
// "the stairs" against the real server's tracking and route guide. Each walk plays in its own
// Chromium (one fake camera file per browser), from when the app opens the camera (the route's
// preview): it stands still long enough for the preview and Start, and at its end for arrival.
// What the app says is checked as speech, in order, by each sentence's stable part (its kind and
// place, not its exact distances); the answers' guidance and the walk's truth go with a failure.
import { readFileSync } from 'node:fs';
import { expect, test, type Browser, type Locator, type Page } from '@playwright/test';
import { WALKS, base, chromiumArgs, chromiumPath, walkClip } from './env';
import { expectNoAxeViolations } from './helpers';

type Walk = (typeof WALKS)[number];

/** The sentences of the walk, by their stable parts (directions.ts guidanceSentence, clock style). */
const SAID = {
  preview: /^The stairs: \d+ metres?, 1 turn, after \d+ metres?\.$/,
  // standing at the start facing the right way: straight ahead (or nearly) to the corner
  first: /^(In \d+ metres?, )?(walk straight ahead|turn to (1|11|12) o'clock and walk) \d+ metres?, to the lifts\.$/i,
  reassure: /^Keep going, \d+ metres? to the (lifts|stairs)\.$/,
  // the corner: the turn right, said before it ("In 2 metres, turn to 3 o'clock ..."; or, said late,
  // already round it: straight on)
  turn: /^(In \d+ metres?, )?(turn to [234] o'clock and walk|walk straight ahead) \d+ metres?, to the stairs\.$/i,
  arrived: /^You have arrived at the stairs\b/,
  // the whole arrival sentence: the words of the server's guidance (the demo's stairs have no
  // sentence of their own), and nothing the app adds
  arrivedExactly: /^You have arrived at the stairs(; it is at \d+ o'clock, \d+ metres?)?\.$/,
  offRoute: /^You are off the route; (turn to \d+ o'clock|walk straight ahead)\.$/,
  instruction: /^(In \d+ metres?, )?(walk straight ahead|turn to \d+ o'clock and walk|keep going)/i,
  // a leg to walk: where to face, how far, to what
  step: /^(In \d+ metres?, )?(walk straight ahead|turn to \d+ o'clock and walk) \d+ metres?, to the /i,
};

declare global {
  interface Window {
    __walk: {
      /** performance.now() when the camera opened: the walk's time 0. */
      cam: number | null;
      said: { t: number; text: string }[];
      /** When each locate request was sent. */
      sent: number[];
      answers: { sent: number; got: number; a: Record<string, unknown> }[];
    };
  }
}

/** A timed log of what is said, when the camera opened and every locate answer (the page's clock). */
async function logWalk(page: Page): Promise<void> {
  await page.addInitScript(() => {
    const w = (window.__walk = { cam: null, said: [], sent: [], answers: [] } as Window['__walk']);
    const media = navigator.mediaDevices; // only on a secure page (http://127.0.0.1 is one)
    const gum = media?.getUserMedia.bind(media);
    if (gum)
      media.getUserMedia = async (c?: MediaStreamConstraints) => {
        const s = await gum(c);
        w.cam ??= performance.now();
        return s;
      };
    const speak = speechSynthesis.speak.bind(speechSynthesis);
    speechSynthesis.speak = (u: SpeechSynthesisUtterance) => {
      if (u.text.trim()) w.said.push({ t: performance.now(), text: u.text });
      speak(u);
    };
    const f = window.fetch.bind(window);
    window.fetch = async (input: RequestInfo | URL, init?: RequestInit) => {
      const sent = performance.now();
      const url = input instanceof Request ? input.url : String(input);
      if (url.includes('/locate')) w.sent.push(sent);
      const r = await f(input, init);
      if (url.includes('/locate'))
        void r
          .clone()
          .json()
          .then((a: Record<string, unknown>) => w.answers.push({ sent, got: performance.now(), a }))
          .catch(() => undefined);
      return r;
    };
  });
}

const said = async (page: Page): Promise<string[]> =>
  (await page.evaluate(() => window.__walk.said)).map((s) => s.text);

/** The walk's truth (e2e/fixtures.py): the pose every half second, and when each step starts. */
interface Truth {
  poses: [number, number, number, number][];
  marks: { t: number; what: string }[];
}
const truth = (w: Walk): Truth => JSON.parse(readFileSync(walkClip(w).replace(/\.y4m$/, '.json'), 'utf8'));

/** What happened, second by second of the walk: each answer (with the truth then) and each sentence. */
async function timeline(page: Page, w: Walk): Promise<string> {
  const log = await page.evaluate(() => window.__walk).catch(() => null);
  if (!log) return '(no log)';
  const t0 = log.cam ?? 0;
  const tr = truth(w);
  const at = (t: number) => tr.poses.reduce((a, p) => (Math.abs(p[0] - t) < Math.abs(a[0] - t) ? p : a));
  const rows: [number, string][] = log.said.map((s) => [s.t, `said   "${s.text}"`]);
  for (const { sent, got, a } of log.answers) {
    const g = a.guidance as Record<string, unknown> | undefined;
    const p = at((sent - t0) / 1000);
    const tk = a.tracking as Record<string, unknown> | undefined;
    rows.push([
      got,
      `answer sent ${((sent - t0) / 1000).toFixed(1)} s: (${Number(a.x).toFixed(1)}, ${Number(a.y).toFixed(1)}) ` +
        `${Math.round(Number(a.heading_deg))}° conf ${Number(a.confidence).toFixed(2)}, truth (${p[1]}, ${p[2]}) ${p[3]}°; ` +
        `${tk ? `updates ${tk.updates}${tk.restarted ? ` restarted: ${tk.reason}` : ''}; ` : ''}` +
        (g
          ? `${g.kind}${g.speak ? ' (speak)' : ''} "${g.sentence}"`
          : `no guidance: ${JSON.stringify(a).slice(0, 200)}`),
    ]);
  }
  rows.sort((a, b) => a[0] - b[0]);
  const marks = tr.marks.map((m) => `${m.t} s ${m.what}`).join('; ');
  return [`walk ${w}: ${marks}`, ...rows.map(([t, s]) => `${((t - t0) / 1000).toFixed(1).padStart(6)} s  ${s}`)].join(
    '\n',
  );
}

/** Each pattern matched by a sentence said after the one the pattern before it matched. */
function expectInOrder(sentences: string[], patterns: [string, RegExp][], log: string): void {
  let from = 0;
  for (const [what, re] of patterns) {
    const i = sentences.findIndex((s, k) => k >= from && re.test(s));
    expect(i, `${what} (${re}) said after ${JSON.stringify(sentences.slice(0, from))}\n${log}`).toBeGreaterThanOrEqual(
      0,
    );
    from = i + 1;
  }
}

/**
 * The venue as the app loads it says something else about the stairs on arrival than the server
 * (a place edited since the app loaded it): the app must say the guidance's words, not its own copy.
 */
const STALE_SAY = 'An old sentence about the stairs.';

async function staleVenue(page: Page): Promise<void> {
  await page.route(
    (url) => url.pathname === '/api/venues/demo',
    async (route) => {
      const res = await route.fetch();
      const v = (await res.json()) as { places: { name: string; say?: string }[] };
      const places = v.places.map((p) => (p.name === 'the stairs' ? { ...p, say: STALE_SAY } : p));
      await route.fulfill({ response: res, json: { ...v, places } });
    },
  );
}

/** A browser whose fake camera plays the walk `w`, its page on the demo venue, logged. */
async function open(
  playwright: { chromium: { launch: (o: object) => Promise<Browser> } },
  w: Walk,
  prepare?: (page: Page) => Promise<void>,
): Promise<{ browser: Browser; page: Page }> {
  const browser = await playwright.chromium.launch({ executablePath: chromiumPath(), args: chromiumArgs(walkClip(w)) });
  const page = await (await browser.newContext({ permissions: ['camera'] })).newPage();
  await logWalk(page);
  await prepare?.(page);
  await page.goto(`${base()}/?venue=demo`);
  await expect(page.locator('#venue-line')).toContainText('Ready');
  return { browser, page };
}

/** Tab (only) until `target` has the focus. */
async function tabTo(page: Page, target: Locator, what: string): Promise<void> {
  for (let i = 0; i < 40; i++) {
    if (await target.evaluate((el) => el === document.activeElement).catch(() => false)) return;
    await page.keyboard.press('Tab');
  }
  throw new Error(`Tab never reached ${what}`);
}

/** The walk's timeline beside the test's result (and printed with OMNINAV_E2E_TIMELINE=1). */
async function attach(page: Page, w: Walk): Promise<void> {
  const log = await timeline(page, w);
  await test.info().attach(`${w} timeline`, { body: log, contentType: 'text/plain' });
  if (process.env.OMNINAV_E2E_TIMELINE) console.log(log);
}

test.describe.configure({ timeout: 240_000 });

test('walking to the stairs: the preview, the first instruction, the turn in time, "keep going", arrival', async ({
  playwright,
}) => {
  const { browser, page } = await open(playwright, 'to-stairs', staleVenue);
  try {
    await page.getByRole('button', { name: 'Go to', exact: true }).click();
    await expect(page.getByRole('heading', { name: 'Go to a place' })).toBeVisible();
    const stairs = page.getByRole('button', { name: 'the stairs', exact: true });
    await expect(stairs).toBeVisible();
    await expectNoAxeViolations(page, 'the Go to screen, its places listed');
    // the walk starts playing now (the preview's answer opens the camera): it stands 8 s first
    await stairs.click();
    await expect.poll(() => said(page)).toContainEqual(expect.stringMatching(SAID.preview));
    await page.getByRole('button', { name: 'Start' }).click();
    await expect(page.locator('#goto-state')).toHaveText('You have arrived.', { timeout: 120_000 });
    const log = await timeline(page, 'to-stairs');
    expectInOrder(
      await said(page),
      [
        ['the route’s preview', SAID.preview],
        ['the first instruction', SAID.first],
        ['the turn at the lifts', SAID.turn],
        ['a reassurance round the corner', SAID.reassure],
        ['arrival', SAID.arrived],
      ],
      log,
    );
    // the answers agree: a turn was announced, early enough at this walk's 1 m/s to be heard
    // before the corner (route.py turn_ahead_m), and arrival was the last word
    const guided = await page.evaluate(() =>
      window.__walk.answers.map(
        (x) => x.a.guidance as { kind: string; speak: boolean; in_m: number | null } | undefined,
      ),
    );
    const kinds = guided.map((g) => g?.kind);
    expect(kinds, log).toContain('turn');
    const turn = guided.find((g) => g?.kind === 'turn' && g.speak);
    expect(turn?.in_m ?? 0, log).toBeGreaterThanOrEqual(5);
    expect(kinds.at(-1), log).toBe('arrived');
    // Start's request filmed 1 s, each after it 2 s, which the server's filter walked second by
    // second (two updates a request): no second of the walk unseen but the answers' time
    const updates = await page.evaluate(() =>
      window.__walk.answers.map((x) => (x.a.tracking as { updates: number } | undefined)?.updates ?? 0),
    );
    const steps = updates.slice(1).map((u, i) => u - updates[i]);
    expect(steps.length, log).toBeGreaterThan(3);
    // (2 s filmed is two parts; a camera slow enough to stretch it past 2.4 s makes three)
    expect(steps[0], log).toBe(1);
    expect(
      steps.slice(1).filter((d) => d < 2 || d > 3),
      log,
    ).toEqual([]);
    expect(await said(page), log).not.toContainEqual(expect.stringMatching(SAID.offRoute));
    // arrival said once, as the guidance's words have it: nothing appended from the app's venue
    const arrivals = (await said(page)).filter((s) => SAID.arrived.test(s));
    expect(arrivals, log).toHaveLength(1);
    expect(arrivals[0], log).toMatch(SAID.arrivedExactly);
    expect((await said(page)).join(' '), log).not.toContain(STALE_SAY);
    // guidance ended with arrival: no more requests, and the screen says so
    const n = kinds.length;
    await page.waitForTimeout(3000);
    expect(await page.evaluate(() => window.__walk.answers.length)).toBe(n);
    await expect(page.getByRole('button', { name: 'Stop guidance' })).toBeDisabled();
    await expect(page.locator('#goto-facts')).toContainText('To go');
    await expectNoAxeViolations(page, 'the Go to screen on arrival');
  } finally {
    await attach(page, 'to-stairs');
    await browser.close();
  }
});

test('the wrong way, keyboard only: "off the route", then a new instruction; What next? and Stop guidance', async ({
  playwright,
}) => {
  const { browser, page } = await open(playwright, 'wrong-way');
  try {
    await tabTo(page, page.getByRole('button', { name: 'Go to', exact: true }), 'the Go to tab');
    await page.keyboard.press('Enter');
    await tabTo(page, page.getByRole('button', { name: 'the stairs', exact: true }), 'the stairs');
    await page.keyboard.press('Enter'); // the walk starts playing: 8 s at Room 1, facing the right way
    await expect(page.getByRole('heading', { name: 'Route to the stairs' })).toBeFocused();
    await expect.poll(() => said(page)).toContainEqual(expect.stringMatching(SAID.preview));
    await tabTo(page, page.getByRole('button', { name: 'Start' }), 'Start');
    await page.keyboard.press('Enter');
    const whatNext = page.getByRole('button', { name: 'What next?' });
    await expect(whatNext).toBeFocused();
    // the walker turns round and walks away from the route (from 8 s on), stands, and walks back
    await expect.poll(() => said(page), { timeout: 60_000 }).toContainEqual(expect.stringMatching(SAID.offRoute));
    const afterOff = async () => {
      const s = await said(page);
      return s.slice(s.findIndex((x) => SAID.offRoute.test(x)) + 1).filter((x) => !SAID.offRoute.test(x));
    };
    await expect.poll(afterOff, { timeout: 60_000 }).toContainEqual(expect.stringMatching(SAID.step));
    let log = await timeline(page, 'wrong-way');
    expectInOrder(
      await said(page),
      [
        ['the route’s preview', SAID.preview],
        ['the first instruction', SAID.instruction],
        ['off the route', SAID.offRoute],
        ['a new instruction', SAID.step],
      ],
      log,
    );
    // What next? (still focused) says the current instruction again
    const before = (await said(page)).length;
    await page.keyboard.press('Enter');
    await expect
      .poll(async () => (await said(page)).slice(before))
      .toContainEqual(expect.stringMatching(new RegExp(`${SAID.instruction.source}|${SAID.offRoute.source}`, 'i')));
    // Stop guidance, from the keyboard: said, and nothing sent after it but the second being filmed
    await tabTo(page, page.getByRole('button', { name: 'Stop guidance' }), 'Stop guidance');
    const stopped = await page.evaluate(() => performance.now());
    await page.keyboard.press('Enter');
    await expect.poll(() => said(page)).toContain('Stopped guidance.');
    await expect(page.locator('#goto-state')).toHaveText('Guidance stopped.');
    await expect(page.locator('#goto-facts')).not.toContainText('Now'); // no instruction left standing
    await page.waitForTimeout(5000); // two turns of the loop
    log = await timeline(page, 'wrong-way');
    const late = (await page.evaluate(() => window.__walk.sent)).filter((t) => t > stopped + 1500);
    expect(late, log).toEqual([]);
    await expect(page.getByRole('button', { name: 'Start' })).toBeEnabled();
  } finally {
    await attach(page, 'wrong-way');
    await browser.close();
  }
});
