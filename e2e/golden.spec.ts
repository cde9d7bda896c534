// Golden-file parity in a real Chromium: the engine's frames through the app's own feature worker
// (ImageBitmap -> OffscreenCanvas -> opencv.js WebAssembly) give the engine's records.
import { readFileSync } from 'node:fs';
import { resolve } from 'node:path';
import { expect, test } from '@playwright/test';
import type { SelfTestResult } from '../web/src/client/selftest';
import { GOLDEN, base } from './env';

const half = (h: number) => {
  const e = (h >> 10) & 0x1f;
  const m = h & 0x3ff;
  const s = h & 0x8000 ? -1 : 1;
  return e === 0 ? s * m * 2 ** -24 : s * (1 + m / 1024) * 2 ** (e - 15);
};

/** (re, im) of a one-frame record made by the engine. */
function engineSpectrum(stem: string): { re: number[]; im: number[] } {
  const b = readFileSync(resolve(GOLDEN, `${stem}.rec`));
  const ck = b.readUInt16LE(4) * b.readUInt16LE(6);
  const re: number[] = [];
  const im: number[] = [];
  for (let i = 0; i < ck; i++) {
    const m = half(b.readUInt16LE(20 + 2 * i));
    const p = (b.readInt16LE(20 + 2 * ck + 2 * i) * Math.PI) / 32768;
    re.push(m * Math.cos(p));
    im.push(m * Math.sin(p));
  }
  return { re, im };
}

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
      const want = engineSpectrum(f.stem);
      let num = 0;
      let den = 0;
      f.mag.forEach((m, i) => {
        const p = (f.phase[i] * Math.PI) / 32768;
        num += (half(m) * Math.cos(p) - want.re[i]) ** 2 + (half(m) * Math.sin(p) - want.im[i]) ** 2;
        den += want.re[i] ** 2 + want.im[i] ** 2;
      });
      expect(Math.sqrt(num / den), `${f.stem}: record relative error`).toBeLessThanOrEqual(1e-3);
      const curves = new Float32Array(readFileSync(resolve(GOLDEN, `${f.stem}.curves`)).buffer.slice(0));
      let worst = 0;
      curves.forEach((v, i) => (worst = Math.max(worst, Math.abs(v - f.curves[i]))));
      expect(worst, `${f.stem}: curves`).toBeLessThan(1e-4);
      checked++;
    }
  }
  expect(checked).toBe(5);
  expect(r.timing.width).toBe(960);
  test.info().annotations.push({
    type: 'extraction',
    description: `${r.timing.medianMs.toFixed(1)} ms median per 960x720 frame`,
  });
});
