// Keypoints on a verifying venue, as a user meets them: the demo venue modelled again with the
// `verified` preset beside the plain one; the venue line says the building can double-check
// answers; the user turns keypoints on in Settings by keyboard; "Where am I?" then sends a version-2
// record (the curves and one frame's keypoints, within 32 KB) and is answered where the clip was
// filmed. Until then nothing but the curves leaves the phone.
import { execFileSync } from 'node:child_process';
import { resolve } from 'node:path';
import { expect, test, type Request } from '@playwright/test';
import { PYTHON, TOKEN, WORK, base } from './env';
import { expectAnswerAtClip, expectNoAxeViolations } from './helpers';
import { waitModelled } from './server.cjs';

const VENUE = 'demo-verified';

test.beforeAll(async () => {
  test.setTimeout(600_000);
  // the quick demo's walk as another venue of the same server, with the `verified` preset
  // (demo.py's set-up, into the server's own catalogue), modelled through the server's job queue
  const setUp = [
    'import sys',
    'from omninav.catalog import Catalog',
    'from omninav.config import load_config',
    'from omninav.demo import ensure_demo',
    'cat = Catalog.open(load_config({"DATA": sys.argv[1]}))',
    `print(ensure_demo(cat, quick=True, log=lambda m: None, venue_id="${VENUE}", preset="verified"))`,
  ].join('\n');
  const made = execFileSync(PYTHON, ['-c', setUp, resolve(WORK, 'server')], { encoding: 'utf8' }).trim();
  if (made === 'True') {
    const r = await fetch(`${base()}/api/admin/venues/${VENUE}/jobs`, {
      method: 'POST',
      headers: { Authorization: `Bearer ${TOKEN}`, 'Content-Type': 'application/json' },
      body: '{}',
    });
    expect(r.status, await r.text()).toBe(201);
  }
  await waitModelled(base(), VENUE);
});

test('keypoints: off until the user allows them, then sent with the last frame and answered', async ({ page }) => {
  test.setTimeout(120_000);
  const posts: Request[] = [];
  page.on('request', (r) => r.url().includes('/locate') && r.method() === 'POST' && posts.push(r));
  await page.goto(`${base()}/?venue=${VENUE}`);
  const line = page.locator('#venue-line');
  await expect(line).toContainText('Ready');
  await expect(line).toContainText('double-check answers if you turn on Send keypoints');

  // off by default: the curves alone (version 1)
  let answered = page.waitForResponse((r) => r.url().includes('/locate') && r.request().method() === 'POST');
  await page.getByRole('button', { name: 'Where am I?' }).click();
  const first = await answered;
  expect(first.status()).toBe(200);
  expect((await first.json()).verified).toBeUndefined(); // nothing to check it with
  let body = posts.at(-1)!.postDataBuffer()!;
  expect(body.subarray(0, 3).toString()).toBe('ONV');
  expect(body[3]).toBe(1);

  // Settings, by keyboard: the checkbox is found by its name and described by its hint
  await page.getByRole('button', { name: 'Settings' }).focus();
  await page.keyboard.press('Enter');
  const box = page.getByRole('checkbox', { name: /Send keypoints/ });
  await expect(box).not.toBeChecked();
  await expect(box).toHaveAccessibleDescription(/rough picture of the place could be rebuilt/);
  await box.focus();
  await page.keyboard.press('Space');
  await expect(box).toBeChecked();
  await expectNoAxeViolations(page, 'the settings screen with keypoints allowed');
  await page.getByRole('button', { name: 'Locate' }).click();
  await expect(line).not.toContainText('double-check answers');

  // allowed: version 2, the curves (the sizes the venue document states) and then the local block
  // ("LOC", N keypoints, 36 bytes each)
  const { features } = await (await fetch(`${base()}/api/venues/${VENUE}`)).json();
  answered = page.waitForResponse((r) => r.url().includes('/locate') && r.request().method() === 'POST');
  await page.getByRole('button', { name: 'Where am I?' }).click();
  const res = await answered;
  expect(res.status()).toBe(200);
  body = posts.at(-1)!.postDataBuffer()!;
  expect(body[3]).toBe(2);
  const frames = body.readUInt32LE(10);
  const at = features.record_header_bytes + features.record_bytes_per_frame * frames;
  expect(body.subarray(at, at + 4).toString('latin1')).toBe('LOC\0');
  const n = body.readUInt32LE(at + 4);
  expect(n).toBeGreaterThan(100);
  expect(n).toBeLessThanOrEqual(880);
  expect(body.length).toBe(at + 8 + 36 * n);
  expect(body.length - at).toBeLessThanOrEqual(32 * 1024);
  // the server checked the answer by them (it stands where the clip was filmed: confirmed), and
  // the details say so
  const answer = await res.json();
  expectAnswerAtClip(answer);
  expect(answer.verified).toBe('confirmed');
  await expect(page.locator('#debug-facts')).toContainText(`${n} of the last frame`);
  await expect(page.locator('#debug-facts')).toContainText('confirmed: the keypoints fit the answer');
  // the preference stays on the phone: after a reload the box is still ticked and a press still
  // sends keypoints
  await page.reload();
  await expect(line).toContainText('Ready');
  await expect(line).not.toContainText('double-check answers');
  answered = page.waitForResponse((r) => r.url().includes('/locate') && r.request().method() === 'POST');
  await page.getByRole('button', { name: 'Where am I?' }).click();
  expect((await answered).status()).toBe(200);
  expect(posts.at(-1)!.postDataBuffer()![3]).toBe(2);
  await page.getByRole('button', { name: 'Settings' }).click();
  await expect(page.getByRole('checkbox', { name: /Send keypoints/ })).toBeChecked();
});
