/**
 * Frame -> features, composed: unwarp (Eq. 1, cv.remap), curves (Eq. 3), spectrum (cv.dft), the
 * quantised record. The same stages, order and arithmetic as the engine's extract.py, so a phone's
 * record matches what the server would compute from the same frame.
 */
import { extractCurves } from './curves';
import type { Lens } from '../shared/lens';
import { bandMap, type UnwarpMap } from './unwarp';
import { addLean, edgeLean, intensity, vectorMap } from './level';
import { nCurves, type FeatureSettings } from '../shared/settings';
import type { FrameSpectrum } from '../shared/record';
import { harmonics, quantise } from './spectrum';

// The slice of opencv.js we use: typed here so that the rest of the code is checked.
export interface CvMat {
  data: Uint8Array;
  data32F: Float32Array;
  rows: number;
  cols: number;
  delete(): void;
}
export interface Cv {
  Mat: new (...args: unknown[]) => CvMat;
  Scalar: new (...v: number[]) => unknown;
  CV_8UC4: number;
  CV_32FC1: number;
  INTER_LINEAR: number;
  BORDER_CONSTANT: number;
  BORDER_WRAP: number;
  DFT_ROWS: number;
  DFT_COMPLEX_OUTPUT: number;
  matFromArray(rows: number, cols: number, type: number, data: ArrayLike<number>): CvMat;
  remap(src: CvMat, dst: CvMat, mx: CvMat, my: CvMat, interp: number, border: number, value: unknown): void;
  dft(src: CvMat, dst: CvMat, flags: number, nonzeroRows: number): void;
}

export interface Extracted {
  spectrum: FrameSpectrum;
  /** Only with `keep`: the band panorama (RGBA) and the normalised curves, for golden checks. */
  pano?: Uint8Array;
  curves?: Float32Array;
}

export class Extractor {
  readonly map: UnwarpMap;
  private readonly mx: CvMat;
  private readonly my: CvMat;
  private readonly src: CvMat;
  private readonly pano: CvMat;
  private readonly curveMat: CvMat;
  private readonly dftMat: CvMat;
  private readonly coarse: UnwarpMap | null = null;
  private readonly cmx: CvMat | null = null;
  private readonly cmy: CvMat | null = null;
  private readonly cpano: CvMat | null = null;
  readonly nCurves: number;

  constructor(
    private readonly cv: Cv,
    readonly lens: Lens,
    readonly settings: FeatureSettings,
  ) {
    this.map = bandMap(lens, settings);
    const { rows, cols } = this.map;
    this.mx = cv.matFromArray(rows, cols, cv.CV_32FC1, this.map.mapX);
    this.my = cv.matFromArray(rows, cols, cv.CV_32FC1, this.map.mapY);
    if (settings.level_iters) {
      // level.ts estimates the tilt on the band's rows at one column a degree (level.estimate_map)
      this.coarse = bandMap(lens, { ...settings, oversample: 1 });
      this.cmx = cv.matFromArray(this.coarse.rows, this.coarse.cols, cv.CV_32FC1, this.coarse.mapX);
      this.cmy = cv.matFromArray(this.coarse.rows, this.coarse.cols, cv.CV_32FC1, this.coarse.mapY);
      this.cpano = new cv.Mat();
    }
    const [w, h] = lens.image_size;
    this.src = new cv.Mat(h, w, cv.CV_8UC4);
    this.pano = new cv.Mat();
    this.nCurves = nCurves(settings);
    this.curveMat = new cv.Mat(this.nCurves, settings.pano_width, cv.CV_32FC1);
    this.dftMat = new cv.Mat();
  }

  /** The frame in `src` through `m` into `dst` (the band panorama unless given another). */
  private remap(m: UnwarpMap, mx: CvMat, my: CvMat, dst: CvMat = this.pano): void {
    const { cv } = this;
    // bilinear, as the engine: the same fixed-point interpolation, so the same panorama bytes
    cv.remap(
      this.src,
      dst,
      mx,
      my,
      cv.INTER_LINEAR,
      m.wrap ? cv.BORDER_WRAP : cv.BORDER_CONSTANT,
      new cv.Scalar(0, 0, 0, 0),
    );
  }

  /** The frame in `src` through a map made for this frame (its tables as opencv.js mats, then freed). */
  private remapThrough(m: UnwarpMap, dst: CvMat = this.pano): void {
    const { cv } = this;
    const mx = cv.matFromArray(m.rows, m.cols, cv.CV_32FC1, m.mapX);
    const my = cv.matFromArray(m.rows, m.cols, cv.CV_32FC1, m.mapY);
    try {
      this.remap(m, mx, my, dst);
    } finally {
      mx.delete();
      my.delete();
    }
  }

  /**
   * Levelling (level.ts; the engine's level_map): `level_iters` passes, each estimating the tilt
   * left on the panorama the last estimate levels, read through the coarse map (one column a
   * degree); then the band panorama through the tilt found. -> the map the band panorama was read
   * through.
   */
  private level(iters: number): UnwarpMap {
    const { map, lens } = this;
    const coarse = this.coarse!;
    let m = coarse;
    let v: [number, number] = [0, 0];
    for (let k = 0; k < iters; k++) {
      if (m === coarse) this.remap(coarse, this.cmx!, this.cmy!, this.cpano!);
      else this.remapThrough(m, this.cpano!);
      const px = intensity(this.cpano!.data, coarse.rows * coarse.cols);
      const { a, b, n } = edgeLean(px, coarse.rows, coarse.cols, coarse.elevations, m.valid);
      if (n === 0) break;
      v = addLean(v, a, b);
      if (k + 1 < iters) m = vectorMap(lens, coarse, v);
    }
    if (v[0] === 0 && v[1] === 0) {
      this.remap(map, this.mx, this.my);
      return map;
    }
    const levelled = vectorMap(lens, map, v);
    this.remapThrough(levelled);
    return levelled;
  }

  /** RGBA pixels of one frame (the lens's image size) -> its quantised spectrum. */
  extract(rgba: Uint8Array | Uint8ClampedArray, keep = false): Extracted {
    const { cv, settings: s } = this;
    this.src.data.set(rgba);
    let map = this.map;
    if (s.level_iters) map = this.level(s.level_iters);
    else this.remap(map, this.mx, this.my);
    const curves = extractCurves(this.pano.data, map.rows, map.cols, map.elevations, map.valid, s);
    this.curveMat.data32F.set(curves);
    cv.dft(this.curveMat, this.dftMat, cv.DFT_ROWS | cv.DFT_COMPLEX_OUTPUT, 0);
    const { re, im } = harmonics(this.dftMat.data32F, this.nCurves, s.pano_width, s.n_harmonics);
    const out: Extracted = { spectrum: quantise(re, im) };
    if (keep) {
      out.pano = this.pano.data.slice();
      out.curves = curves;
    }
    return out;
  }

  delete(): void {
    for (const m of [this.mx, this.my, this.src, this.pano, this.curveMat, this.dftMat]) m.delete();
    for (const m of [this.cmx, this.cmy, this.cpano]) m?.delete();
  }
}

/** opencv.js loads as a promise (5.x) or as a module that calls onRuntimeInitialized (4.x). */
export async function readyCv(mod: unknown): Promise<Cv> {
  let m = mod as { default?: unknown; then?: unknown; Mat?: unknown; onRuntimeInitialized?: () => void };
  if (m && m.default && !m.Mat && !m.then) m = m.default as typeof m;
  if (m && typeof m.then === 'function') {
    // a thenable that resolves to itself would loop in `await`: take it out of the chain
    const resolved = await new Promise<unknown>((res) => (m.then as (f: (v: unknown) => void) => void).call(m, res));
    const r = resolved as typeof m;
    if (r && typeof r.then === 'function') delete r.then;
    return r as unknown as Cv;
  }
  if (m && !m.Mat) await new Promise<void>((res) => (m.onRuntimeInitialized = res));
  return m as unknown as Cv;
}
