// The worker's bilinear remap (worker/unwarp.ts remapLinear) against opencv.js's cv.remap, which
// the engine's cv2.remap matches byte for byte (golden.test.ts): the same bytes, borders included.
import { createRequire } from 'node:module';
import { beforeAll, describe, expect, it } from 'vitest';
import { readyCv, type Cv } from '../src/worker/extract';
import { remapLinear } from '../src/worker/unwarp';

let cv: Cv;
beforeAll(async () => {
  cv = await readyCv(createRequire(import.meta.url)('@techstark/opencv-js'));
});

/** Park-Miller: the same numbers every run. */
function rng(seed: number): () => number {
  let s = seed;
  return () => (s = (s * 16807) % 2147483647) / 2147483647;
}

function viaOpenCv(
  src: Uint8Array,
  w: number,
  h: number,
  mx: Float32Array,
  my: Float32Array,
  wrap: boolean,
): Uint8Array {
  const s = new cv.Mat(h, w, cv.CV_8UC4);
  s.data.set(src);
  const x = cv.matFromArray(200, mx.length / 200, cv.CV_32FC1, mx);
  const y = cv.matFromArray(200, my.length / 200, cv.CV_32FC1, my);
  const d = new cv.Mat();
  try {
    cv.remap(s, d, x, y, cv.INTER_LINEAR, wrap ? cv.BORDER_WRAP : cv.BORDER_CONSTANT, new cv.Scalar(0, 0, 0, 0));
    return d.data.slice();
  } finally {
    for (const m of [s, x, y, d]) m.delete();
  }
}

describe('remapLinear', () => {
  for (const wrap of [false, true])
    it(`reads the bytes cv.remap reads (${wrap ? 'wrap' : 'constant'} border)`, () => {
      const r = rng(wrap ? 11 : 5);
      const [w, h] = [700, 300]; // coordinates past 128 and 256: fewer fraction bits
      const src = new Uint8Array(w * h * 4).map(() => Math.floor(r() * 256));
      const n = 200_000;
      const mx = new Float32Array(n);
      const my = new Float32Array(n);
      // inside; across every edge; on whole and half-step coordinates (x * 32 ending in .5)
      const at = (kind: number, size: number, step: number): number =>
        kind === 0
          ? r() * (size - 1)
          : kind === 1
            ? -3 + r() * (size + 6)
            : Math.floor(r() * size) + (kind === 2 ? 0 : step);
      for (let i = 0; i < n; i++) {
        mx[i] = at(i % 4, w, 1 / 64);
        my[i] = at(i % 4, h, 3 / 64);
      }
      const want = viaOpenCv(src, w, h, mx, my, wrap);
      const got = new Uint8Array(n * 4);
      remapLinear(src, w, h, { rows: 200, cols: n / 200, mapX: mx, mapY: my, wrap }, got);
      let bad = 0;
      for (let i = 0; i < n; i++) for (let c = 0; c < 3; c++) if (got[4 * i + c] !== want[4 * i + c]) bad++;
      expect(bad).toBe(0);
    });
});
