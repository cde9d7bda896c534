// Installed once, the app opens with no server: the service worker serves the shell and the WASM,
// and the app says plainly that the server cannot be reached.
import { resolve } from 'node:path';
import { expect, test } from '@playwright/test';
import { TOKEN, WORK } from './env';
import { expectNoAxeViolations, spoken, spyOnSpeech } from './helpers';
import { startServer } from './server.cjs';

test('offline start from the service worker, with a spoken "cannot reach the server"', async ({ page }) => {
  const srv = await startServer(resolve(WORK, 'server-offline'), {
    args: ['--demo', 'none', '--workers', '2'],
    env: { OMNINAV_ADMIN_TOKEN: TOKEN },
    fresh: true,
  });
  try {
    await spyOnSpeech(page);
    await page.goto(`${srv.url}/`);
    await expect(page.locator('#venue-line')).toContainText('no venues');
    // wait until the service worker controls the page and has precached the app (opencv.js too)
    await page.evaluate(async () => {
      await navigator.serviceWorker.ready;
      if (!navigator.serviceWorker.controller)
        await new Promise((r) => navigator.serviceWorker.addEventListener('controllerchange', r, { once: true }));
    });
    const cached = await page.evaluate(async () => {
      const names = await caches.keys();
      const urls: string[] = [];
      for (const n of names) for (const r of await (await caches.open(n)).keys()) urls.push(new URL(r.url).pathname);
      return urls;
    });
    expect(cached).toContain('/index.html');
    // installable: Chromium finds nothing missing in the manifest, icons or service worker (a test
    // context is a private window, which Chromium never installs from: that one reason is expected)
    const cdp = await page.context().newCDPSession(page);
    const { installabilityErrors } = await cdp.send('Page.getInstallabilityErrors');
    expect(installabilityErrors.map((e) => e.errorId)).toEqual(['in-incognito']);
    expect(cached.some((u) => /\/assets\/worker-.*\.js$/.test(u))).toBe(true);
  } finally {
    await srv.stop();
  }
  // the server is gone: the app still opens, and says so when asked
  await page.reload();
  await expect(page.getByRole('button', { name: 'Where am I?' })).toBeVisible();
  await expect(page.locator('#venue-line')).toContainText('Cannot reach the omninav server');
  await page.getByRole('button', { name: 'Where am I?' }).click();
  await expect(page.getByRole('alert')).toContainText('Cannot reach the omninav server');
  await expect.poll(() => spoken(page)).toContainEqual(expect.stringContaining('Wi-Fi'));
  await expectNoAxeViolations(page, 'the app offline');
});
