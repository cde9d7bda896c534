// What the specs share: a spy on speech and vibration, and axe-core run in the page.
import { readFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { resolve } from 'node:path';
import { expect, type Locator, type Page } from '@playwright/test';
import { WORK } from './env';

declare global {
  interface Window {
    __spoken: string[];
    __utterances: { text: string; inGesture: boolean }[];
    __vibrated: number[][];
  }
}

/** Record what the app asks the speech synthesiser to say, and each vibration pattern. */
export async function spyOnSpeech(page: Page): Promise<void> {
  await page.addInitScript(() => {
    window.__spoken = [];
    window.__utterances = [];
    window.__vibrated = [];
    const speak = speechSynthesis.speak.bind(speechSynthesis);
    speechSynthesis.speak = (u: SpeechSynthesisUtterance) => {
      window.__utterances.push({ text: u.text, inGesture: navigator.userActivation?.isActive ?? false });
      if (u.text.trim()) window.__spoken.push(u.text);
      speak(u);
    };
    navigator.vibrate = (p: VibratePattern) => {
      window.__vibrated.push(Array.isArray(p) ? [...p] : [p]);
      return true;
    };
  });
}

export const spoken = (page: Page): Promise<string[]> => page.evaluate(() => window.__spoken);

// Evaluated through the browser's debugging protocol, not added as a <script>: the app's
// Content-Security-Policy rightly refuses inline scripts, and the tests keep that policy on.
const axeSource = readFileSync(createRequire(__filename).resolve('axe-core/axe.min.js'), 'utf8') + '\n;0';

/** axe-core's WCAG 2.x A/AA rules and best practices on the page as it is now: no violation. */
export async function expectNoAxeViolations(page: Page, what: string): Promise<void> {
  await page.evaluate(axeSource);
  const violations = await page.evaluate(async () => {
    const axe = (
      window as unknown as {
        axe: {
          run: (
            c: unknown,
            o: unknown,
          ) => Promise<{ violations: { id: string; help: string; nodes: { target: unknown }[] }[] }>;
        };
      }
    ).axe;
    const r = await axe.run(document, {
      runOnly: { type: 'tag', values: ['wcag2a', 'wcag2aa', 'wcag21a', 'wcag21aa', 'wcag22aa', 'best-practice'] },
    });
    return r.violations.map((v) => `${v.id}: ${v.help} (${v.nodes.map((n) => JSON.stringify(n.target)).join(', ')})`);
  });
  expect(violations, `axe on ${what}`).toEqual([]);
}

/** Tab (only) until `target` has the focus. */
export async function tabTo(page: Page, target: Locator, what: string): Promise<void> {
  for (let i = 0; i < 40; i++) {
    if (await target.evaluate((el) => el === document.activeElement).catch(() => false)) return;
    await page.keyboard.press('Tab');
  }
  throw new Error(`Tab never reached ${what}`);
}

/** How many locate requests the page has sent so far (a live count). */
export function countLocates(page: Page): () => number {
  let n = 0;
  page.on('request', (r) => {
    if (r.url().includes('/locate')) n++;
  });
  return () => n;
}

/** Where the fake camera's clip was filmed, and facing which way (e2e/fixtures.py `clip`). */
export const clipTruth = (): { x: number; y: number; heading_deg: number } =>
  JSON.parse(readFileSync(resolve(WORK, 'clip/clip.json'), 'utf8'));

/** A locate answer within 2 m and 10 degrees of where the fake camera's clip was filmed. */
export function expectAnswerAtClip(ans: { x: number; y: number; heading_deg: number }): void {
  const t = clipTruth();
  const angle = Math.abs(((ans.heading_deg - t.heading_deg + 540) % 360) - 180);
  expect(Math.hypot(ans.x - t.x, ans.y - t.y), `answer (${ans.x}, ${ans.y})`).toBeLessThanOrEqual(2);
  expect(angle, `heading ${ans.heading_deg} vs ${t.heading_deg}`).toBeLessThanOrEqual(10);
}
