/**
 * Frame -> features, composed: unwarp (Eq. 1, cv.remap), curves (Eq. 3), spectrum (cv.dft), the
 * quantised record. The same stages, order and arithmetic as the engine's extract.py, so a phone's
 * record matches what the server would compute from the same frame.
 */
import { extractCurves } from './curves';
import type { Lens } from '../shared/lens';
import { bandMap, type UnwarpMap } from './unwarp';
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
    const [w, h] = lens.image_size;
    this.src = new cv.Mat(h, w, cv.CV_8UC4);
    this.pano = new cv.Mat();
    this.nCurves = nCurves(settings);
    this.curveMat = new cv.Mat(this.nCurves, settings.pano_width, cv.CV_32FC1);
    this.dftMat = new cv.Mat();
  }

  /** RGBA pixels of one frame (the lens's image size) -> its quantised spectrum. */
  extract(rgba: Uint8Array | Uint8ClampedArray, keep = false): Extracted {
    const { cv, map, settings: s } = this;
    this.src.data.set(rgba);
    // bilinear, as the engine: the same fixed-point interpolation, so the same panorama bytes
    cv.remap(
      this.src,
      this.pano,
      this.mx,
      this.my,
      cv.INTER_LINEAR,
      map.wrap ? cv.BORDER_WRAP : cv.BORDER_CONSTANT,
      new cv.Scalar(0, 0, 0, 0),
    );
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
