// Every screen passes axe; the problems a user can meet are spoken with what to do about them.
import { expect, test } from '@playwright/test';
import { TOKEN, base } from './env';
import { expectNoAxeViolations, spoken, spyOnSpeech } from './helpers';

test('settings and about screens: reachable by role and name, no axe violation', async ({ page }) => {
  await page.goto(`${base()}/?venue=demo`);
  await expect(page.locator('#venue-line')).toContainText('Ready');
  await page.getByRole('button', { name: 'Settings' }).click();
  await expect(page.getByRole('heading', { name: 'Settings' })).toBeVisible();
  await expect(page.getByLabel('Venue')).toHaveValue('demo');
  await expect(page.getByLabel('Lens profile', { exact: true })).toHaveValue('donut');
  await expect(page.getByLabel(/Speech rate/)).toBeVisible();
  await expectNoAxeViolations(page, 'the settings screen');
  await page.getByRole('button', { name: 'About' }).click();
  await expect(page.getByRole('heading', { name: 'About omninav' })).toBeVisible();
  await expectNoAxeViolations(page, 'the about screen');
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

async function admin(path: string, method: string, body: unknown): Promise<void> {
  const r = await fetch(`${base()}/api/admin${path}`, {
    method,
    headers: { Authorization: `Bearer ${TOKEN}`, 'Content-Type': 'application/json' },
    body: JSON.stringify(body),
  });
  if (!r.ok && r.status !== 409) throw new Error(`${method} ${path}: ${r.status} ${await r.text()}`);
}

test('a venue without modelled frames: spoken, with what to do', async ({ page }) => {
  await admin('/venues', 'POST', { id: 'empty', name: 'Empty hall' });
  await spyOnSpeech(page);
  await page.goto(`${base()}/?venue=empty`);
  await expect(page.locator('#venue-line')).toContainText('Not modelled yet');
  await page.getByRole('button', { name: 'Where am I?' }).click();
  await expect(page.getByRole('alert')).toContainText('no modelled frames yet');
  await expect.poll(() => spoken(page)).toContainEqual(expect.stringContaining('Ask the venue’s administrator'));
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
  await page.goto(`${base()}/?venue=nope`);
  await expect(page.locator('#venue-line')).toContainText(
    'This server has no venue “nope”; showing Synthetic demo venue instead.',
  );
  await page.getByRole('button', { name: 'Settings' }).click();
  await expect(page.getByLabel('Venue')).toHaveValue('demo');
});
