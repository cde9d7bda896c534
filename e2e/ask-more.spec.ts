// "Ask for more" (issue 13): when the first second's answer is not sure, the app says so, films two
// seconds more and sends the three seconds as one record: one more request, answered from all of it.
// Keyboard only; what is said is checked as speech and as the polite status.
import { expect, test, type Page, type Request } from '@playwright/test';
import { ELSEWHERE, base, chromiumArgs, chromiumPath } from './env';
import { spoken, spyOnSpeech } from './helpers';

const KEEP_TURNING = 'Not sure yet. Keep turning slowly.';
const UNSURE = 'Not sure where you are; turn slowly and try again.';

/** What was said from `first` on (the lens check may have said something before). */
const from = (said: string[], first: string): string[] => said.slice(Math.max(0, said.indexOf(first)));

/** The locate requests the page sends, as they go. */
function locates(page: Page): Request[] {
  const out: Request[] = [];
  page.on('request', (r) => {
    if (r.url().includes('/locate') && r.method() === 'POST') out.push(r);
  });
  return out;
}

/** Frames in a request's binary feature record (its header's frame count), checked against its length. */
function framesOf(r: Request, bytesPerFrame: number, headerBytes: number): number {
  const body = r.postDataBuffer()!;
  expect(body.subarray(0, 3).toString()).toBe('ONV');
  const n = body.readUInt32LE(10);
  expect(body.length).toBe(headerBytes + bytesPerFrame * n);
  return n;
}

async function features(): Promise<{ record_bytes_per_frame: number; record_header_bytes: number }> {
  return (await (await fetch(`${base()}/api/venues/demo`)).json()).features;
}

/**
 * The first second made ambiguous: the server's own answer to the first request, marked not sure
 * (the demo venue knows the fake camera's place too well to be unsure of it by itself). Later
 * requests go to the server untouched.
 */
async function firstAnswerUnsure(page: Page): Promise<void> {
  let n = 0;
  await page.route('**/api/venues/*/locate**', async (route) => {
    if (n++ > 0) return route.continue();
    const res = await route.fetch();
    const a = await res.json();
    await route.fulfill({ response: res, json: { ...a, confidence: 0.3, low_confidence: true, accuracy_m: null } });
  });
}

/** "Where am I?" pressed from the keyboard. */
async function press(page: Page): Promise<void> {
  await page.getByRole('button', { name: 'Where am I?' }).focus();
  await page.keyboard.press('Enter');
}

/** The demo venue opened, "Where am I?" pressed with the first answer made unsure: the requests sent. */
async function pressUnsure(page: Page): Promise<Request[]> {
  await spyOnSpeech(page);
  const sent = locates(page);
  await firstAnswerUnsure(page);
  await page.goto(`${base()}/?venue=demo`);
  await expect(page.locator('#venue-line')).toContainText('Ready');
  await press(page);
  return sent;
}

test('an unsure first second: "keep turning", then one 30-frame request, and the answer from it', async ({ page }) => {
  const sent = await pressUnsure(page);
  // said politely, while the same button now stops the filming
  await expect(page.locator('#live')).toHaveText(KEEP_TURNING);
  await expect(page.getByRole('button', { name: 'Stop' })).toBeFocused();
  await expect(page.locator('#live')).toContainText('You are in', { timeout: 30_000 });
  const sentence = (await page.locator('#live').textContent())!;
  await expect.poll(async () => from(await spoken(page), KEEP_TURNING)).toEqual([KEEP_TURNING, sentence]);
  await expect(page.getByRole('button', { name: 'Where am I?' })).toBeEnabled();
  const f = await features();
  expect(sent.map((r) => framesOf(r, f.record_bytes_per_frame, f.record_header_bytes))).toEqual([10, 30]);
  // the 20 frames were filmed on while the first second was answered: 30 frames, no gap, ~10 a second
  const fps = Number(new URL(sent[1].url()).searchParams.get('fps'));
  expect(fps).toBeGreaterThan(8);
  expect(fps).toBeLessThan(11);
  await expect(page.locator('#answer-facts')).toContainText('Nearest place');
  await expect(page.locator('#debug-facts')).toContainText('for 30 frames');
});

test('Stop, pressed while it films on, ends it: nothing more is sent', async ({ page }) => {
  const sent = await pressUnsure(page);
  await expect(page.locator('#live')).toHaveText(KEEP_TURNING);
  await page.keyboard.press('Enter'); // the focused button is Stop now
  await expect(page.locator('#live')).toHaveText('Stopped.');
  await expect(page.getByRole('button', { name: 'Where am I?' })).toBeFocused();
  await page.waitForTimeout(3000); // the 2 s it would have filmed, and a request
  expect(sent).toHaveLength(1);
  expect(from(await spoken(page), KEEP_TURNING)).toEqual([KEEP_TURNING, 'Stopped.']);
  await expect(page.locator('#answer-text')).toHaveText('No answer yet.');
});

test('a building the venue has never seen: unsure twice, the usual "not sure", no third request', async ({
  playwright,
}) => {
  const browser = await playwright.chromium.launch({ executablePath: chromiumPath(), args: chromiumArgs(ELSEWHERE) });
  const page = await (await browser.newContext({ permissions: ['camera'] })).newPage();
  try {
    await spyOnSpeech(page);
    const sent = locates(page);
    await page.goto(`${base()}/?venue=demo`);
    await expect(page.locator('#venue-line')).toContainText('Ready');
    await press(page);
    await expect(page.locator('#live')).toHaveText(UNSURE, { timeout: 30_000 });
    await expect.poll(async () => from(await spoken(page), KEEP_TURNING)).toEqual([KEEP_TURNING, UNSURE]);
    const f = await features();
    expect(sent.map((r) => framesOf(r, f.record_bytes_per_frame, f.record_header_bytes))).toEqual([10, 30]);
    await page.waitForTimeout(2000);
    expect(sent).toHaveLength(2);
  } finally {
    await browser.close();
  }
});
