/**
 * Unwarp tables (the paper's Eq. 1), as the engine's unwarp.py builds them: rows are elevations,
 * columns azimuths; cv.remap in the worker then reads the band panorama through them.
 */
import { directionToPixel, linspace, radiusTable, type Lens } from '../shared/lens';

/** Remap tables (float32, rows x cols), the rows' elevations, and which directions the lens sees. */
export interface UnwarpMap {
  rows: number;
  cols: number;
  mapX: Float32Array;
  mapY: Float32Array;
  elevations: Float64Array;
  valid: Uint8Array;
  /** OpenCV border mode: constant (black) outside the donut, wrap across a 360-camera's seam. */
  wrap: boolean;
}

/** Elevations of the panorama's rows, top (highest) first (unwarp.panorama_elevations). */
export function panoramaElevations(top: number, bottom: number, step: number): Float64Array {
  return linspace(top, bottom, Math.round((top - bottom) / step) + 1);
}

/** The remap tables for a panorama of `width` columns; column j looks at azimuth (j + 0.5) * 360 / width. */
export function buildMap(lens: Lens, elevations: Float64Array, width: number): UnwarpMap {
  const rows = elevations.length;
  const mapX = new Float32Array(rows * width);
  const mapY = new Float32Array(rows * width);
  const valid = new Uint8Array(rows * width);
  const radius = lens.model === 'catadioptric' ? radiusTable(lens) : null;
  for (let i = 0; i < rows; i++) {
    for (let j = 0; j < width; j++) {
      const az = ((j + 0.5) * 360) / width;
      const [x, y] = directionToPixel(lens, radius, az, elevations[i]);
      const ok = Number.isFinite(x) && Number.isFinite(y);
      const k = i * width + j;
      valid[k] = ok ? 1 : 0;
      // unseen directions read a pixel outside the image, which the constant border makes black
      mapX[k] = ok ? x : -10;
      mapY[k] = ok ? y : -10;
    }
  }
  return { rows, cols: width, mapX, mapY, elevations, valid, wrap: lens.model !== 'catadioptric' };
}

/** The remap a feature preset needs: the rows of all its bands, at `oversample` x the columns. */
export function bandMap(
  lens: Lens,
  s: { bands: [number, number][]; row_step_deg: number; pano_width: number; oversample: number },
): UnwarpMap {
  const lo = Math.min(...s.bands.map((b) => b[0]));
  const hi = Math.max(...s.bands.map((b) => b[1]));
  return buildMap(lens, panoramaElevations(hi, lo, s.row_step_deg), s.pano_width * s.oversample);
}

const f32 = Math.fround;

/** Round half to even, as OpenCV's cvRound (lrintf) does: adding and taking away 1.5 * 2^52 leaves
 * the double's nearest whole number, ties to even (|v| < 2^51). */
const RINT = 6755399441055744;

/** The bilinear value of four bytes (OpenCV's float32 steps, warp_common.scalar.hpp), rounded. */
function lerp(p00: number, p01: number, p10: number, p11: number, sx: number, sy: number): number {
  const v0 = f32(p00 + f32(sx * (p01 - p00)));
  const v1 = f32(p10 + f32(sx * (p11 - p10)));
  return f32(v0 + f32(sy * f32(v1 - v0))) + RINT - RINT;
}

/** `lerp` where sx is a multiple of 2^-16 (x >= 128 in float32): the steps before sy's are then
 * exact in float32 (below 2^24 units of 2^-16) and need no rounding. */
function lerpFine(p00: number, p01: number, p10: number, p11: number, sx: number, sy: number): number {
  const v0 = p00 + sx * (p01 - p00);
  return f32(v0 + f32(sy * (p10 + sx * (p11 - p10) - v0))) + RINT - RINT;
}

/**
 * cv.remap(src, dst, mapX, mapY, INTER_LINEAR, border) of an RGBA frame (w x h), R, G and B only,
 * into `out` (rows x cols RGBA; alpha is left as it is): the same float32 steps as OpenCV 5's
 * scalar bilinear kernel, which opencv.js runs, so the same panorama bytes, without copying the
 * frame into the WebAssembly heap.
 *
 * Notes
 * -----
 * The cells are read column by column: a donut's column is a ray from the ring's inside out, and
 * the next ray reads nearly the same pixels, still in the cache; row by row, each row is a circle
 * round the whole ring, which fetches every line of the frame again. The values are never outside
 * [0, 255] (each is between its bytes), so OpenCV's saturation leaves them as they are.
 */
export function remapLinear(
  src: Uint8Array | Uint8ClampedArray,
  w: number,
  h: number,
  m: Pick<UnwarpMap, 'rows' | 'cols' | 'mapX' | 'mapY' | 'wrap'>,
  out: Uint8Array,
): void {
  const { rows, cols, mapX, mapY, wrap } = m;
  if (src.length !== 4 * w * h || out.length !== 4 * rows * cols || mapX.length !== rows * cols)
    throw new Error('remapLinear: the frame, the map and the panorama do not fit together');
  const px = src instanceof Uint8Array ? src : new Uint8Array(src.buffer, src.byteOffset, src.length);
  const stride = 4 * w;
  for (let j = 0; j < cols; j++) {
    for (let k = j, o = 4 * j; k < rows * cols; k += cols, o += 4 * cols) {
      const fx = mapX[k];
      const fy = mapY[k];
      const ix = Math.floor(fx);
      const iy = Math.floor(fy);
      if (ix >= 0 && ix < w - 1 && iy >= 0 && iy < h - 1) {
        // a non-negative float32 less its floor is a float32: no rounding
        const sx = fx - ix;
        const sy = fy - iy;
        const a = iy * stride + 4 * ix;
        const c = a + stride;
        if (fx >= 128) {
          out[o] = lerpFine(px[a], px[a + 4], px[c], px[c + 4], sx, sy);
          out[o + 1] = lerpFine(px[a + 1], px[a + 5], px[c + 1], px[c + 5], sx, sy);
          out[o + 2] = lerpFine(px[a + 2], px[a + 6], px[c + 2], px[c + 6], sx, sy);
        } else {
          out[o] = lerp(px[a], px[a + 4], px[c], px[c + 4], sx, sy);
          out[o + 1] = lerp(px[a + 1], px[a + 5], px[c + 1], px[c + 5], sx, sy);
          out[o + 2] = lerp(px[a + 2], px[a + 6], px[c + 2], px[c + 6], sx, sy);
        }
        continue;
      }
      const sx = f32(fx - ix);
      const sy = f32(fy - iy);
      if (!wrap && (ix < -1 || ix >= w || iy < -1 || iy >= h)) {
        out[o] = out[o + 1] = out[o + 2] = 0; // the constant border: black
        continue;
      }
      // some of the four neighbours lie outside: black (constant) or across the seam (wrap)
      const a = fetch(ix, iy, w, h, wrap);
      const b = fetch(ix + 1, iy, w, h, wrap);
      const c = fetch(ix, iy + 1, w, h, wrap);
      const d = fetch(ix + 1, iy + 1, w, h, wrap);
      for (let ch = 0; ch < 3; ch++)
        out[o + ch] = lerp(
          a < 0 ? 0 : px[a + ch],
          b < 0 ? 0 : px[b + ch],
          c < 0 ? 0 : px[c + ch],
          d < 0 ? 0 : px[d + ch],
          sx,
          sy,
        );
    }
  }
}

/** Byte offset of pixel (x, y) of an RGBA frame; outside it: -1 (black), or wrapped (BORDER_WRAP). */
function fetch(x: number, y: number, w: number, h: number, wrap: boolean): number {
  if (x < 0 || x >= w || y < 0 || y >= h) {
    if (!wrap) return -1;
    x = ((x % w) + w) % w;
    y = ((y % h) + h) % h;
  }
  return 4 * (y * w + x);
}
