// The TypeScript extractor (with the same opencv.js as the browser, here in Node) against the
// engine's golden files, stage by stage: panorama bytes, curves, and the record; and the local
// features (worker/local.ts against verify.py): the map, the grey panorama, the keypoints.
import { readFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { resolve } from 'node:path';
import { beforeAll, describe, expect, it } from 'vitest';
import { Extractor, readyCv, type Cv } from '../src/worker/extract';
import { LocalDetector, localMap, type LocalCv } from '../src/worker/local';
import type { Lens } from '../src/shared/lens';
import type { FeatureSettings } from '../src/shared/settings';
import {
  HEADER_BYTES,
  encodeRecord,
  fromHalf,
  MAX_LOCAL_KEYPOINTS,
  keypointsAlike,
  localBlock,
  recordFrame,
  recordLocal,
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

interface LocalCase {
  name: string;
  lens: Lens;
  n_features: number;
  shape: [number, number];
  el: [number, number];
  /** each frame's keypoints as the engine detected them (up to n_features; fewer in a dim frame) */
  frames: { stem: string; rgba: string; n: number }[];
}

// made once per run of this file, before its cases are listed (they come from golden.json)
const GOLDEN = makeGoldens();
const read = (f: string) => new Uint8Array(readFileSync(resolve(GOLDEN, f)));
const golden = () => JSON.parse(readFileSync(resolve(GOLDEN, 'golden.json'), 'utf8'));
const cases = (): Case[] => golden().cases;

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

describe('local features: parity with the engine (verify.py)', () => {
  for (const c of golden().local as LocalCase[]) {
    it(`${c.name}: the map, the grey panorama and the keypoints match`, () => {
      const [rows, cols] = c.shape;
      const m = localMap(c.lens)!;
      expect([m.rows, m.cols, m.elTop, m.elBottom]).toEqual([rows, cols, ...c.el]);
      const want = new Float32Array(read(`${c.name}.localmap`).buffer.slice(0));
      let d = 0;
      for (let i = 0; i < rows * cols; i++)
        d = Math.max(d, Math.abs(m.mapX[i] - want[i]), Math.abs(m.mapY[i] - want[rows * cols + i]));
      expect(d, 'remap tables (px)').toBeLessThan(1e-3);
      const det = new LocalDetector(cv as unknown as LocalCv, c.lens, c.n_features);
      det.prepare(); // as the worker does: the warm-up on a stand-in must leave the detections as they are
      try {
        for (const { stem, rgba, n } of c.frames) {
          const frame = read(`${rgba}.rgba`);
          const grey = det.grey(frame);
          const wg = read(`${stem}.lgrey`);
          let off = 0;
          for (let i = 0; i < wg.length; i++) off += Math.abs(grey[i] - wg[i]) > 0 ? 1 : 0;
          expect(grey.length).toBe(wg.length);
          expect(off / wg.length, `${stem}: grey pixels that differ`).toBeLessThan(1e-3);
          const got = det.detect(frame);
          const w = localBlock(read(`${stem}.local`));
          // both detect the venue's 900 (a dim frame fewer, again at FAST_DIM: within 2 %, the grey
          // pixels that differ move a few corners) and send the first 880 (ORB's order): what the
          // phone sends, its record's local block, against the engine's
          expect(
            Math.abs(got.az.length - n),
            `${stem}: keypoints ${got.az.length}, the engine's ${n}`,
          ).toBeLessThanOrEqual(Math.ceil(0.02 * n));
          const spectrum = recordFrame(read('donut-default-0.rec'));
          const sentNow = recordLocal(encodeRecord([spectrum], cases()[0].settings, 0, got))!;
          expect(Math.abs(sentNow.az.length - w.az.length)).toBeLessThanOrEqual(Math.ceil(0.02 * w.az.length));
          // each of the engine's keypoints sent by the phone too: the same bearing (within a unit,
          // a rounding tie) and descriptor (in another order: ORB keeps its best by a partial sort)
          expect(keypointsAlike(sentNow, w), `${stem}: the engine's keypoints the phone sends alike`).toBeGreaterThan(
            0.95,
          );
        }
      } finally {
        det.delete();
      }
    });
  }

  it('a version-2 record carries the keypoints as the engine writes them', () => {
    const c = (golden().local as LocalCase[])[0];
    const w = read(`${c.frames[0].stem}.local`);
    const local = localBlock(w);
    const spectrum = recordFrame(read('donut-default-0.rec'));
    const s = cases()[0];
    const rec = encodeRecord([spectrum], s.settings, s.settings_id, local);
    expect(rec[3]).toBe(2);
    expect(Array.from(rec.slice(rec.length - w.length))).toEqual(Array.from(w));
    expect(recordLocal(rec)!.az).toEqual(local.az);
    expect(recordLocal(encodeRecord([spectrum], s.settings, s.settings_id))).toBeNull();
    // more than a record holds: the first MAX_LOCAL_KEYPOINTS go, in order
    const n = MAX_LOCAL_KEYPOINTS + 20;
    const many = {
      az: Uint16Array.from({ length: n }, (_, i) => i),
      el: Int16Array.from({ length: n }, (_, i) => -i),
      desc: Uint8Array.from({ length: 32 * n }, (_, i) => i >> 5),
    };
    const cut = recordLocal(encodeRecord([spectrum], s.settings, s.settings_id, many))!;
    expect(cut.az).toEqual(many.az.slice(0, MAX_LOCAL_KEYPOINTS));
    expect(cut.el).toEqual(many.el.slice(0, MAX_LOCAL_KEYPOINTS));
    expect(cut.desc).toEqual(many.desc.slice(0, 32 * MAX_LOCAL_KEYPOINTS));
  });
});
