import { defineConfig } from '@playwright/test';
import { CLIP, chromiumArgs, chromiumPath } from './env';

// One real `omninav serve` (the quick demo venue, modelled through its job queue) for the whole
// run, started by global-setup.ts; Debian's Chromium with a fake camera playing CLIP.
export default defineConfig({
  testDir: '.',
  testMatch: /.*\.spec\.ts/,
  globalSetup: './global-setup.ts',
  timeout: 120_000,
  expect: { timeout: 30_000 },
  workers: 1, // one server, a 2-core machine: tests take turns
  forbidOnly: !!process.env.CI,
  retries: process.env.CI ? 1 : 0, // a retry is reported as flaky, with its trace kept
  reporter: [['list']],
  use: {
    launchOptions: { executablePath: chromiumPath(), args: chromiumArgs(CLIP) },
    permissions: ['camera'],
    serviceWorkers: 'allow',
    trace: 'on-first-retry',
  },
});
