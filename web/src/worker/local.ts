/**
 * Local features of one frame, as the engine's verify.py `detect` makes them: ORB keypoints and
 * descriptors (opencv.js) of the frame's grey local panorama (every elevation the lens sees all
 * round, STEP_DEG a pixel), each keypoint as the azimuth and elevation it looks at. A verifying
 * venue's server checks the global answer with them (docs/formats.md, "Version 2: the local block").
 *
 * Notes
 * -----
 * The panorama's remap is the engine's `panorama_map`: the lens's directions every COARSE pixels
 * (one degree), interpolated bilinearly, with one coarse column beyond each end so that the
 * azimuth wraps. The frame is made grey first and the grey image remapped (a third of a colour
 * remap's work), in the WebAssembly heap: cv.remap and cv.ORB are the same OpenCV as the engine's.
 */
import { buildMap, panoramaElevations } from './unwarp';
import type { Lens } from '../shared/lens';
import { AZ_STEP_DEG, EL_STEP_DEG, type LocalBlock } from '../shared/record';

export const STEP_DEG = 0.25;
export const EL_TOP = 60;
export const EL_BOTTOM = -80;
export const COARSE = 4;
/** ORB's FAST corner thresholds: a frame with under DIM_SHARE of its keypoints at the first
 * (OpenCV's default) is detected again at the second, a dim frame's weaker corners too (verify.py's rule). */
export const FAST_THRESHOLD = 20;
export const FAST_DIM = 10;
export const DIM_SHARE = 0.5;
/** A lens that sees fewer rows than this all round gives no keypoints (verify.detect's rule). */
export const MIN_ROWS = 32;

/** The local panorama's remap (float32, rows x cols) and its first and last rows' elevations. */
export interface LocalMap {
  rows: number;
  cols: number;
  mapX: Float32Array;
  mapY: Float32Array;
  elTop: number;
  elBottom: number;
}

/**
 * cv2.remap(src, u, v, INTER_LINEAR, BORDER_REPLICATE) of a float32 image (rows x cols) into
 * `out` (us.length x ... rows x us.length columns): row i of `out` reads row vs[i], column j column
 * us[j]. The grid is separable, so each row's and column's cells and weights are found once.
 */
function bilinearGrid(
  src: Float32Array,
  rows: number,
  cols: number,
  us: Float32Array,
  vs: Float32Array,
  out: Float32Array,
): void {
  const n = us.length;
  const c0 = new Int32Array(n);
  const c1 = new Int32Array(n);
  const fu = new Float64Array(n);
  for (let j = 0; j < n; j++) {
    const iu = Math.floor(us[j]);
    c0[j] = Math.min(Math.max(iu, 0), cols - 1);
    c1[j] = Math.min(Math.max(iu + 1, 0), cols - 1);
    fu[j] = us[j] - iu;
  }
  for (let i = 0; i < vs.length; i++) {
    const iv = Math.floor(vs[i]);
    const fv = vs[i] - iv;
    const r0 = Math.min(Math.max(iv, 0), rows - 1) * cols;
    const r1 = Math.min(Math.max(iv + 1, 0), rows - 1) * cols;
    for (let j = 0, o = i * n; j < n; j++, o++) {
      const top = src[r0 + c0[j]] + fu[j] * (src[r0 + c1[j]] - src[r0 + c0[j]]);
      const bottom = src[r1 + c0[j]] + fu[j] * (src[r1 + c1[j]] - src[r1 + c0[j]]);
      out[o] = top + fv * (bottom - top);
    }
  }
}

/** The local panorama of `lens` (verify.panorama_map), or null where it sees under 2 rows all round. */
export function localMap(lens: Lens): LocalMap | null {
  const stepC = STEP_DEG * COARSE;
  const width = Math.round(360 / STEP_DEG);
  const cw = width / COARSE;
  const elC = panoramaElevations(EL_TOP, EL_BOTTOM, stepC);
  const coarse = buildMap(lens, elC, cw);
  const seen: number[] = [];
  for (let i = 0; i < coarse.rows; i++) {
    let all = true;
    for (let j = 0; j < cw && all; j++) all = coarse.valid[i * cw + j] === 1;
    if (all) seen.push(i);
  }
  if (seen.length < 2) return null;
  // the seen rows, one coarse column beyond each end: extended column e looks at azimuth (e - 0.5) * stepC
  const ew = cw + 2;
  const ex = new Float32Array(seen.length * ew);
  const ey = new Float32Array(seen.length * ew);
  seen.forEach((i, r) => {
    for (let e = 0; e < ew; e++) {
      const j = (e - 1 + cw) % cw;
      ex[r * ew + e] = coarse.mapX[i * cw + j];
      ey[r * ew + e] = coarse.mapY[i * cw + j];
    }
  });
  const elTop = elC[seen[0]];
  const el = panoramaElevations(elTop, elC[seen[seen.length - 1]], STEP_DEG);
  const rows = el.length;
  const us = new Float32Array(width);
  for (let j = 0; j < width; j++) us[j] = ((j + 0.5) * STEP_DEG) / stepC + 0.5;
  const vs = new Float32Array(rows);
  for (let i = 0; i < rows; i++) vs[i] = (elTop - el[i]) / stepC;
  const mapX = new Float32Array(rows * width);
  const mapY = new Float32Array(rows * width);
  bilinearGrid(ex, seen.length, ew, us, vs, mapX);
  bilinearGrid(ey, seen.length, ew, us, vs, mapY);
  return { rows, cols: width, mapX, mapY, elTop, elBottom: el[rows - 1] };
}

/** The keypoint's column and row in the local panorama -> its azimuth and elevation units (record.ts). */
export function keypointUnits(x: number, y: number, m: Pick<LocalMap, 'cols' | 'rows' | 'elTop'>): [number, number] {
  // np.interp over the columns' azimuths and the rows' elevations: linear, held at the ends
  const az = (Math.min(Math.max(x, 0), m.cols - 1) + 0.5) * STEP_DEG;
  const el = m.elTop - Math.min(Math.max(y, 0), m.rows - 1) * STEP_DEG;
  return [Math.round(az / AZ_STEP_DEG) % 65536, Math.round(el / EL_STEP_DEG)];
}

// The slice of opencv.js the detector uses (extract.ts types the rest).
interface LMat {
  data: Uint8Array;
  rows: number;
  cols: number;
  delete(): void;
}
interface LKeyPoint {
  pt: { x: number; y: number };
}
export interface LocalCv {
  Mat: new (...args: unknown[]) => LMat;
  Scalar: new (...v: number[]) => unknown;
  KeyPointVector: new () => { size(): number; get(i: number): LKeyPoint; delete(): void };
  ORB: new (n: number) => {
    detectAndCompute(img: LMat, mask: LMat, kp: unknown, desc: LMat): void;
    setFastThreshold(t: number): void;
    delete(): void;
  };
  CV_8UC1: number;
  CV_8UC4: number;
  CV_32FC1: number;
  CV_16SC2: number;
  COLOR_RGBA2GRAY: number;
  INTER_LINEAR: number;
  BORDER_CONSTANT: number;
  matFromArray(rows: number, cols: number, type: number, data: ArrayLike<number>): LMat;
  cvtColor(src: LMat, dst: LMat, code: number): void;
  convertMaps(mx: LMat, my: LMat, m1: LMat, m2: LMat, type: number, nearest: boolean): void;
  remap(src: LMat, dst: LMat, mx: LMat, my: LMat, interp: number, border: number, value: unknown): void;
}

/**
 * One lens's detector: its map and every OpenCV object made once; `detect` then costs the grey
 * conversion, the remap and ORB. `delete()` frees the WebAssembly memory.
 */
export class LocalDetector {
  readonly map: LocalMap | null;
  private readonly mats: LMat[] = [];
  private readonly orb: InstanceType<LocalCv['ORB']>;
  private readonly kp: InstanceType<LocalCv['KeyPointVector']>;

  constructor(
    private readonly cv: LocalCv,
    readonly lens: Lens,
    readonly nFeatures: number,
  ) {
    const m = localMap(lens);
    this.map = m && m.rows >= MIN_ROWS ? m : null;
    this.orb = new cv.ORB(nFeatures);
    this.kp = new cv.KeyPointVector();
  }

  /**
   * The OpenCV objects, made on first use (or by `prepare`): a lens the page never asks keypoints
   * of costs no WebAssembly memory. The remap tables are OpenCV's fixed-point pair (convertMaps),
   * which cv.remap makes of float tables anyway, block by block, on every call (3x the time).
   */
  private work(): LMat[] {
    if (!this.mats.length && this.map) {
      const { cv, map } = this;
      const [w, h] = this.lens.image_size;
      const made: LMat[] = [];
      const mat = (m: LMat): LMat => (made.push(m), m);
      try {
        const mx = mat(cv.matFromArray(map.rows, map.cols, cv.CV_32FC1, map.mapX));
        const my = mat(cv.matFromArray(map.rows, map.cols, cv.CV_32FC1, map.mapY));
        const [m1, m2] = [mat(new cv.Mat()), mat(new cv.Mat())];
        cv.convertMaps(mx, my, m1, m2, cv.CV_16SC2, false);
        const src = mat(new cv.Mat(h, w, cv.CV_8UC4));
        const [grey, pano, mask, desc] = [0, 0, 0, 0].map(() => mat(new cv.Mat()));
        this.mats.push(src, grey, pano, m1, m2, mask, desc);
        mx.delete();
        my.delete();
      } catch (e) {
        for (const m of made) m.delete(); // a failure part way leaves nothing behind
        this.mats.length = 0;
        throw e;
      }
    }
    return this.mats;
  }

  /**
   * Make everything a frame needs now, off a press's path: the OpenCV objects, and (once a worker)
   * one detection on a textured stand-in panorama, so that the browser has compiled ORB's
   * WebAssembly in its optimising tier before the first real frame (by hand the first press's
   * keypoints took 69 ms in Chromium, later ones ~40 ms, with a server beside it).
   */
  prepare(): void {
    const mats = this.work();
    if (!mats.length || LocalDetector.warm) return;
    const [, , , , , mask, desc] = mats;
    const { rows, cols } = this.map!;
    const stand = new this.cv.Mat(rows, cols, this.cv.CV_8UC1);
    try {
      const d = stand.data; // (a getter that makes a new view at each read)
      let x = 12345; // a fixed pseudo-random texture (a linear congruential sequence)
      for (let i = 0; i < d.length; i++) d[i] = (x = (Math.imul(x, 1103515245) + 12345) >>> 0) >>> 24;
      this.orb.detectAndCompute(stand, mask, this.kp, desc);
      LocalDetector.warm = true;
    } finally {
      stand.delete();
    }
  }

  /** ORB has run once in this worker (WebAssembly is optimised per function: once covers all detectors). */
  private static warm = false;

  /** The grey local panorama of an RGBA frame (the lens's image size), rows x cols bytes. */
  grey(rgba: Uint8Array | Uint8ClampedArray): Uint8Array {
    if (!this.map) return new Uint8Array(0);
    const [src, grey, pano, mx, my] = this.work();
    if (rgba.length !== src.data.length)
      throw new Error(`the frame has ${rgba.length} bytes, not the ${src.cols}x${src.rows} RGBA the lens is for`);
    src.data.set(rgba);
    this.cv.cvtColor(src, grey, this.cv.COLOR_RGBA2GRAY);
    this.cv.remap(grey, pano, mx, my, this.cv.INTER_LINEAR, this.cv.BORDER_CONSTANT, new this.cv.Scalar());
    return pano.data;
  }

  /** An RGBA frame -> its keypoints' azimuth and elevation units and ORB descriptors, in ORB's order. */
  detect(rgba: Uint8Array | Uint8ClampedArray): LocalBlock {
    if (!this.map) return { az: new Uint16Array(0), el: new Int16Array(0), desc: new Uint8Array(0) };
    this.grey(rgba);
    const [, , pano, , , mask, desc] = this.work();
    this.orb.setFastThreshold(FAST_THRESHOLD);
    this.orb.detectAndCompute(pano, mask, this.kp, desc);
    if (this.kp.size() < DIM_SHARE * this.nFeatures) {
      this.orb.setFastThreshold(FAST_DIM); // a dim frame: its weaker corners too
      this.orb.detectAndCompute(pano, mask, this.kp, desc);
    }
    const n = desc.rows ? this.kp.size() : 0;
    const az = new Uint16Array(n);
    const el = new Int16Array(n);
    for (let i = 0; i < n; i++) {
      const { x, y } = this.kp.get(i).pt;
      [az[i], el[i]] = keypointUnits(x, y, this.map);
    }
    return { az, el, desc: desc.data.slice(0, 32 * n) };
  }

  delete(): void {
    for (const m of this.mats) m.delete();
    this.mats.length = 0;
    this.orb.delete();
    this.kp.delete();
  }
}
