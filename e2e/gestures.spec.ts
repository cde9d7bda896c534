// Hands-free: a shake or a two-finger double tap asks "Where am I?" as the button does; the user's
// own lens profile, loaded from a file, is used for the features.
import { resolve } from 'node:path';
import { writeFileSync } from 'node:fs';
import { expect, test } from '@playwright/test';
import { WORK, base } from './env';
import { countLocates, spyOnSpeech } from './helpers';

test.use({ hasTouch: true });

test('a shake, then a two-finger double tap, each locate', async ({ page }) => {
  await spyOnSpeech(page);
  const posts = countLocates(page);
  await page.goto(`${base()}/?venue=demo`);
  await expect(page.locator('#venue-line')).toContainText('Ready');
  await page.evaluate(() => {
    for (let i = 0; i < 3; i++)
      window.dispatchEvent(
        new DeviceMotionEvent('devicemotion', { accelerationIncludingGravity: { x: 30, y: 4, z: 9.8 } }),
      );
  });
  await expect.poll(posts).toBe(1);
  await expect(page.locator('#live')).toContainText('You are in');
  await expect(page.getByRole('button', { name: 'Where am I?' })).not.toHaveAttribute('aria-busy', 'true');
  await page.evaluate(async () => {
    const touch = (id: number, x: number) =>
      new Touch({ identifier: id, target: document.body, clientX: x, clientY: 300 });
    for (let i = 0; i < 2; i++) {
      const touches = [touch(1, 100), touch(2, 200)];
      document.body.dispatchEvent(
        new TouchEvent('touchstart', { touches, changedTouches: touches, bubbles: true, cancelable: true }),
      );
      document.body.dispatchEvent(new TouchEvent('touchend', { touches: [], changedTouches: touches, bubbles: true }));
      await new Promise((r) => setTimeout(r, 120));
    }
  });
  await expect.poll(posts).toBe(2);
});

test("the user's own lens profile, loaded from a file, is offered and used; a bad file is refused aloud", async ({
  page,
}) => {
  await spyOnSpeech(page);
  const venue = await (await fetch(`${base()}/api/venues/demo`)).json();
  const good = resolve(WORK, 'my-lens.json');
  writeFileSync(good, JSON.stringify(venue.lenses.donut));
  const bad = resolve(WORK, 'not-a-lens.json');
  writeFileSync(
    bad,
    JSON.stringify({
      model: 'catadioptric',
      image_size: [480, 360],
      center: [1, 2],
      r_inner: 9,
      r_outer: 3,
      elevation_poly: [1],
    }),
  );
  await page.goto(`${base()}/?venue=demo`);
  await expect(page.locator('#venue-line')).toContainText('Ready');
  await page.getByRole('button', { name: 'Settings' }).click();
  await page.getByLabel(/own lens profile/).setInputFiles(bad);
  await expect(page.getByRole('alert')).toContainText(
    'not-a-lens.json is not a usable lens profile: it needs 0 <= r_inner < r_outer',
  );
  await page.getByLabel(/own lens profile/).setInputFiles(good);
  await expect(page.getByLabel('Lens profile', { exact: true })).toHaveValue('my lens');
  await page.getByRole('button', { name: 'Locate' }).click();
  await page.getByRole('button', { name: 'Where am I?' }).click();
  await expect(page.locator('#live')).toContainText('You are in');
  await expect(page.locator('#debug-facts')).toContainText('lens my lens');
});
