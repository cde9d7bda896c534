// The TypeScript extractor (with the same opencv.js as the browser, here in Node) against the
// engine's golden files, stage by stage: panorama bytes, curves, and the record.
import { readFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { resolve } from 'node:path';
import { beforeAll, describe, expect, it } from 'vitest';
import { Extractor, readyCv, type Cv } from '../src/worker/extract';
import type { Lens } from '../src/shared/lens';
import type { FeatureSettings } from '../src/shared/settings';
import {
  HEADER_BYTES,
  encodeRecord,
  fromHalf,
  recordFrame,
  relativeError,
  type FrameSpectrum,
} from '../src/shared/record';
import { makeGoldens } from './global-setup';

interface Case {
  name: string;
  lens: Lens;
  settings: FeatureSettings;
  settings_id: number;
  pano_shape: [number, number, number];
  frames: { stem: string }[];
}

// made once per run of this file, before its cases are listed (they come from golden.json)
const GOLDEN = makeGoldens();
const read = (f: string) => new Uint8Array(readFileSync(resolve(GOLDEN, f)));
const cases = (): Case[] => JSON.parse(readFileSync(resolve(GOLDEN, 'golden.json'), 'utf8')).cases;

let cv: Cv;
beforeAll(async () => {
  cv = await readyCv(createRequire(import.meta.url)('@techstark/opencv-js'));
});

describe('golden parity with the Python engine', () => {
  for (const c of cases()) {
    it(`${c.name}: panorama, curves and record match`, () => {
      const ext = new Extractor(cv, c.lens, c.settings);
      const [rows, cols] = c.pano_shape;
      expect([ext.map.rows, ext.map.cols]).toEqual([rows, cols]);
      const spectra: FrameSpectrum[] = [];
      for (const { stem } of c.frames) {
        const got = ext.extract(read(`${stem}.rgba`), true);
        // panorama: the same remap tables and fixed-point interpolation -> the same bytes
        const want = read(`${stem}.pano`);
        let maxDiff = 0;
        for (let i = 0, p = 0; i < rows * cols; i++, p += 4)
          for (let ch = 0; ch < 3; ch++) maxDiff = Math.max(maxDiff, Math.abs(got.pano![p + ch] - want[i * 3 + ch]));
        expect(maxDiff, `${stem} panorama`).toBe(0);
        const wc = new Float32Array(read(`${stem}.curves`).buffer.slice(0));
        let cd = 0;
        for (let i = 0; i < wc.length; i++) cd = Math.max(cd, Math.abs(got.curves![i] - wc[i]));
        expect(cd, `${stem} curves (unit variance)`).toBeLessThan(1e-4);
        const err = relativeError(got.spectrum, recordFrame(read(`${stem}.rec`)));
        expect(err, `${stem} record relative error`).toBeLessThanOrEqual(1e-3);
        spectra.push(got.spectrum);
      }
      // the whole clip's record: same header, same size, every magnitude within a float16 step
      const rec = encodeRecord(spectra, c.settings, c.settings_id);
      const want = read(`${c.name}.rec`);
      expect(rec.length).toBe(want.length);
      expect(Array.from(rec.slice(0, HEADER_BYTES))).toEqual(Array.from(want.slice(0, HEADER_BYTES)));
      const a = recordFrame(rec, spectra.length - 1);
      const b = recordFrame(want, spectra.length - 1);
      for (let i = 0; i < a.mag.length; i++)
        expect(Math.abs(fromHalf(a.mag[i]) - fromHalf(b.mag[i]))).toBeLessThan(2e-3);
      ext.delete();
    });
  }
});
