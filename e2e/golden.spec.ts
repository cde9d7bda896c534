// Golden-file parity in a real Chromium: the engine's frames through the app's own feature worker
// (ImageBitmap -> OffscreenCanvas -> opencv.js WebAssembly) give the engine's records.
import { readFileSync } from 'node:fs';
import { resolve } from 'node:path';
import { expect, test } from '@playwright/test';
import type { SelfTestResult } from '../web/src/client/selftest';
import { keypointsAlike, localBlock, recordFrame, relativeError } from '../web/src/shared/record';
import { GOLDEN, base } from './env';

test("the browser extracts the engine's records (relative error <= 1e-3) and its curves", async ({ page }) => {
  await page.route(
    (u) => u.pathname.startsWith('/golden/'),
    (route) => route.fulfill({ path: resolve(GOLDEN, new URL(route.request().url()).pathname.split('/').pop()!) }),
  );
  await page.goto(`${base()}/selftest.html?golden=/golden/golden.json&repeats=20`);
  const r: SelfTestResult = await page.evaluate(
    () => (window as unknown as { selftest: Promise<SelfTestResult> }).selftest,
  );
  const cases = JSON.parse(readFileSync(resolve(GOLDEN, 'golden.json'), 'utf8')).cases;
  expect(r.cases.map((c) => c.name)).toEqual(cases.map((c: { name: string }) => c.name));
  let checked = 0;
  for (const c of r.cases) {
    for (const f of c.frames) {
      const want = recordFrame(new Uint8Array(readFileSync(resolve(GOLDEN, `${f.stem}.rec`))));
      const got = { mag: Uint16Array.from(f.mag), phase: Int16Array.from(f.phase) };
      expect(relativeError(got, want), `${f.stem}: record relative error`).toBeLessThanOrEqual(1e-3);
      const curves = new Float32Array(readFileSync(resolve(GOLDEN, `${f.stem}.curves`)).buffer.slice(0));
      let worst = 0;
      curves.forEach((v, i) => (worst = Math.max(worst, Math.abs(v - f.curves[i]))));
      expect(worst, `${f.stem}: curves`).toBeLessThan(1e-4);
      checked++;
    }
  }
  // donut-default 3 frames, donut-six 1, donut-wide 1, equirect-default 1, donut-before-bands 1,
  // donut-tilted 3, donut-sensor 2 (a real mirror's profile) (e2e/fixtures.py golden)
  expect(checked).toBe(12);
  expect(r.timing.width).toBe(960);
  test.info().annotations.push({
    type: 'extraction',
    description: `${r.timing.medianMs.toFixed(1)} ms median per 960x720 frame`,
  });
  // local features (worker/local.ts): of the engine's keypoints, the share the browser finds alike
  // (a unit of bearing, the same descriptor); opencv.js's ORB picks its last few otherwise at ties
  expect(r.local.frames.map((f) => f.stem)).toEqual([
    'local-donut-0',
    'local-donut-1',
    'local-donut-2',
    'local-equirect-0',
    'local-dim-0', // a dim frame: detected again at the lower FAST threshold, in both
  ]);
  for (const f of r.local.frames) {
    const w = localBlock(new Uint8Array(readFileSync(resolve(GOLDEN, `${f.stem}.local`))));
    const got = { az: Uint16Array.from(f.az), el: Int16Array.from(f.el), desc: Uint8Array.from(f.desc) };
    expect(keypointsAlike(got, w), `${f.stem}: the engine's keypoints found alike`).toBeGreaterThan(0.95);
  }
  test.info().annotations.push({
    type: 'local features',
    description: `${r.local.timing.medianMs.toFixed(1)} ms median, p90 ${r.local.timing.p90Ms.toFixed(1)} ms per 960x720 donut frame`,
  });
});
