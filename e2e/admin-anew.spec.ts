// "Model anew" on the admin page, end to end: a venue modelled by an omninav from before its preset
// improved (e2e/fixtures.py `age`: its live frames' settings without the soft clipping, as such an
// omninav wrote them) says so on the modelling screen; its one button models every modelling walk
// again with the preset's settings, followed to 100 %; and a phone that read the venue before takes
// up the new settings by itself: its next "Where am I?" is refused once for the old settings (the
// app reads the venue again and films once more, saying nothing of it) and answered within 2 m.
//
// The venue is aged on disk between two runs of a server of its own (a running server keeps what it
// loaded), so admin-steps' helpers are pointed at that server while the test runs. The fixture
// `own` owns those servers and that setting: its teardown runs even when the test times out, and
// stops every server it started (each its own process group) and puts the suite's server back.
import { execFileSync } from 'node:child_process';
import { readFileSync, statSync } from 'node:fs';
import { resolve } from 'node:path';
import { expect, test as base } from '@playwright/test';
import { adminApi, adminFile, adminTruth, openScreen, signIn, venueByApi } from './admin-steps';
import { PYTHON, ROOT, TOKEN, WORK } from './env';
import { expectAnswerAtClip, expectNoAxeViolations, spoken, spyOnSpeech } from './helpers';
import { startServer } from './server.cjs';
import { MAP_UPDATED } from '../web/src/client/problems';

const VENUE = 'aged';
const DATA = resolve(WORK, 'server-anew');
const SERVE = { args: ['--demo', 'none', '--workers', '2'], env: { OMNINAV_ADMIN_TOKEN: TOKEN } };

type Server = Awaited<ReturnType<typeof startServer>>;

/** Start `omninav serve` on DATA (fresh: emptied first) and point admin-steps' helpers at it. */
type Own = { start: (fresh: boolean) => Promise<Server> };

const test = base.extend<{ own: Own }>({
  own: async ({}, use, testInfo) => {
    const suite = process.env.OMNINAV_E2E_URL;
    const started: Server[] = [];
    await use({
      start: async (fresh) => {
        const srv = await startServer(DATA, { ...SERVE, fresh });
        started.push(srv);
        process.env.OMNINAV_E2E_URL = srv.url;
        return srv;
      },
    });
    if (testInfo.status !== testInfo.expectedStatus)
      for (const [i, srv] of started.entries()) await testInfo.attach(`server-${i}.log`, { body: srv.log() });
    for (const srv of started) await srv.stop(); // stopping a stopped server does nothing
    if (suite === undefined) delete process.env.OMNINAV_E2E_URL;
    else process.env.OMNINAV_E2E_URL = suite;
  },
});

interface VenueDoc {
  settings_current: boolean;
  preset_settings_id: number;
  features: { settings_id: number; settings: Record<string, unknown> };
}

test('Model anew: the modelling screen offers it, runs it, and a phone takes the new settings by itself', async ({
  page,
  browser,
  own,
}) => {
  test.setTimeout(600_000);
  const truth = adminTruth();
  let srv = await own.start(true);
  // the token came from the environment: the banner says so, not "printed on the first start"
  expect(srv.log()).toContain('(sign in with OMNINAV_ADMIN_TOKEN)');
  await test.step('a venue modelled from walk.mp4 through the admin API', async () => {
    await venueByApi(VENUE);
    const walk = adminFile('walk.mp4');
    await adminApi('POST', `/api/admin/venues/${VENUE}/videos`, {
      name: 'walk.mp4',
      size: statSync(walk).size,
      lens: 'donut',
      role: 'model',
      walk_path: truth.walk.walk_path,
    });
    const put = await fetch(`${srv.url}/api/admin/venues/${VENUE}/videos/walk.mp4/content`, {
      method: 'PUT',
      headers: { Authorization: `Bearer ${TOKEN}`, 'Content-Type': 'application/octet-stream' },
      body: readFileSync(walk),
    });
    expect(put.status, await put.text()).toBe(200);
    const job = await adminApi<{ id: string }>('POST', `/api/admin/venues/${VENUE}/jobs`, {});
    await expect
      .poll(async () => (await adminApi<{ state: string }>('GET', `/api/admin/jobs/${job.id}`)).state, {
        timeout: 300_000,
      })
      .toBe('done');
  });

  await test.step('aged on disk as an omninav from before the soft clipping left it', async () => {
    await srv.stop();
    execFileSync(PYTHON, [resolve(ROOT, 'e2e/fixtures.py'), 'age', DATA, VENUE], { stdio: 'inherit' });
    srv = await own.start(false);
    const doc = await adminApi<VenueDoc>('GET', `/api/admin/venues/${VENUE}`);
    expect(doc.settings_current).toBe(false);
    expect(doc.features.settings_id).not.toBe(doc.preset_settings_id);
  });

  // a phone that reads the venue now, with its older settings, before the modelling anew
  const context = await browser.newContext({ permissions: ['camera'] });
  try {
    const phone = await context.newPage();
    await spyOnSpeech(phone);
    await phone.goto(`${srv.url}/?venue=${VENUE}`);
    await expect(phone.locator('#venue-line')).toContainText('Ready');

    await test.step('the modelling screen says why, and its one button models the walk again', async () => {
      await signIn(page);
      await openScreen(page, VENUE, 'modelling');
      await expect(page.locator('#model-anew-box')).toBeVisible();
      const why = page.locator('#model-anew-why');
      await expect(why).toContainText('modelled with older feature settings than its preset has now');
      await expect(why).toContainText('Modelling anew models walk.mp4 again with them');
      const anew = page.getByRole('button', { name: 'Model anew with the current settings' });
      await expect(anew).toBeEnabled();
      // a screen reader hears the reason with the button
      await expect(anew).toHaveAccessibleDescription(/older feature settings/);
      // nothing else to model: the plain button has nothing to do
      await expect(page.locator('#model-start')).toBeDisabled();
      await expectNoAxeViolations(page, 'the modelling screen offering a modelling anew');
      await anew.click();
      const bar = page.getByRole('progressbar', { name: 'Modelling progress' });
      await expect(bar).toBeVisible();
      await expect(bar).toHaveAttribute('aria-valuetext', '100 %', { timeout: 300_000 });
      const outcome = page.locator('#model-outcome');
      await expect(outcome).toContainText('with the current feature settings', { timeout: 30_000 });
      // the button that had the focus is gone with its box: the focus is on what happened
      await expect(page.locator('#model-anew-box')).toBeHidden();
      await expect(outcome).toBeFocused();
      const doc = await adminApi<VenueDoc>('GET', `/api/admin/venues/${VENUE}`);
      expect(doc.settings_current).toBe(true);
      expect(doc.features.settings_id).toBe(doc.preset_settings_id);
      expect(doc.features.settings).toHaveProperty('soft_clip_sd');
      await expectNoAxeViolations(page, 'the modelling screen after a modelling anew');
    });

    await test.step('the phone that read the old settings is answered within 2 m, saying nothing of it', async () => {
      const statuses: number[] = [];
      phone.on('response', (r) => {
        if (r.url().includes('/locate') && r.request().method() === 'POST') statuses.push(r.status());
      });
      const answered = phone.waitForResponse(
        (r) => r.url().includes('/locate') && r.request().method() === 'POST' && r.status() === 200,
      );
      await phone.getByRole('button', { name: 'Where am I?' }).click();
      const ans = await (await answered).json();
      // its first record was made with the settings it read: refused, naming the settings now
      expect(statuses[0]).toBe(400);
      expectAnswerAtClip(ans);
      await expect(phone.locator('#live')).toContainText('You are in');
      expect(await spoken(phone)).not.toContain(MAP_UPDATED);
    });
  } finally {
    await context.close();
  }
});
