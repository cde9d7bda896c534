/**
 * Frame -> features, composed: unwarp (Eq. 1, the bilinear remap), curves (Eq. 3), spectrum (cv.dft),
 * the quantised record. The same stages, order and arithmetic as the engine's extract.py, so a phone's
 * record matches what the server would compute from the same frame.
 *
 * Notes
 * -----
 * Everything a frame needs is made once per (lens, settings): the remap tables, the tables that turn
 * them through a tilt, and every working array; a frame then reads the camera's pixels where they
 * are (remapLinear, no copy into the WebAssembly heap) and allocates only what it hands back.
 */
import { curveScratch, extractCurves, type CurveScratch } from './curves';
import type { Lens } from '../shared/lens';
import { bandMap, remapLinear, type UnwarpMap } from './unwarp';
import {
  addLean,
  edgeLean,
  intensity,
  leanScratch,
  tiltInto,
  tilter,
  vectorRotation,
  type LeanScratch,
  type Tilter,
} from './level';
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

/** Levelling's per-lens state: the coarse map it estimates through and its working arrays. */
interface Leveller {
  coarse: UnwarpMap;
  tiltCoarse: Tilter;
  tiltBand: Tilter;
  /** the coarse panorama (RGBA) and its intensity */
  pano: Uint8Array;
  gray: Float64Array;
  lean: LeanScratch;
  /** the coarse map and the band map through the tilt found so far */
  cx: Float32Array;
  cy: Float32Array;
  bx: Float32Array;
  by: Float32Array;
}

export class Extractor {
  readonly map: UnwarpMap;
  readonly nCurves: number;
  private readonly level: Leveller | null = null;
  private readonly pano: Uint8Array;
  private readonly curveWs: CurveScratch;
  private readonly curveMat: CvMat;
  private readonly dftMat: CvMat;

  constructor(
    private readonly cv: Cv,
    readonly lens: Lens,
    readonly settings: FeatureSettings,
  ) {
    this.map = bandMap(lens, settings);
    const { rows, cols } = this.map;
    this.pano = opaque(rows * cols);
    if (settings.level_iters) {
      // level.ts estimates the tilt on the band's rows at one column a degree (level.estimate_map)
      const coarse = bandMap(lens, { ...settings, oversample: 1 });
      const n = coarse.rows * coarse.cols;
      this.level = {
        coarse,
        tiltCoarse: tilter(lens, coarse),
        tiltBand: tilter(lens, this.map),
        pano: opaque(n),
        gray: new Float64Array(n),
        lean: leanScratch(n),
        cx: new Float32Array(n),
        cy: new Float32Array(n),
        bx: new Float32Array(rows * cols),
        by: new Float32Array(rows * cols),
      };
    }
    this.curveWs = curveScratch(rows, cols, this.map.elevations, settings);
    this.nCurves = nCurves(settings);
    this.curveMat = new cv.Mat(this.nCurves, settings.pano_width, cv.CV_32FC1);
    this.dftMat = new cv.Mat();
  }

  /**
   * Levelling (level.ts; the engine's level_map): `iters` passes, each estimating the tilt left on
   * the panorama the last estimate levels, read through the coarse map (one column a degree); then
   * the band map through the tilt found. -> the map the band panorama is read through.
   */
  private levelled(rgba: Uint8Array | Uint8ClampedArray, iters: number): UnwarpMap {
    const L = this.level!;
    const { coarse } = L;
    const [w, h] = this.lens.image_size;
    const n = coarse.rows * coarse.cols;
    let m: UnwarpMap = coarse;
    let v: [number, number] = [0, 0];
    for (let k = 0; k < iters; k++) {
      remapLinear(rgba, w, h, m, L.pano);
      intensity(L.pano, n, L.gray);
      const { a, b, n: edges } = edgeLean(L.gray, coarse.rows, coarse.cols, coarse.elevations, coarse.valid, L.lean);
      if (edges === 0) break;
      v = addLean(v, a, b);
      if (k + 1 < iters) {
        tiltInto(L.tiltCoarse, vectorRotation(v), L.cx, L.cy);
        m = { ...coarse, mapX: L.cx, mapY: L.cy };
      }
    }
    if (v[0] === 0 && v[1] === 0) return this.map;
    tiltInto(L.tiltBand, vectorRotation(v), L.bx, L.by);
    return { ...this.map, mapX: L.bx, mapY: L.by };
  }

  /** RGBA pixels of one frame (the lens's image size) -> its quantised spectrum. */
  extract(rgba: Uint8Array | Uint8ClampedArray, keep = false): Extracted {
    const { cv, settings: s } = this;
    const [w, h] = this.lens.image_size;
    if (rgba.length !== w * h * 4)
      throw new Error(`the frame has ${rgba.length} bytes, not the ${w}x${h} RGBA the lens profile is for`);
    const map = s.level_iters ? this.levelled(rgba, s.level_iters) : this.map;
    remapLinear(rgba, w, h, map, this.pano);
    // the curves straight into the DFT's input (a fresh view: the heap may have grown)
    const curves = extractCurves(
      this.pano,
      map.rows,
      map.cols,
      map.elevations,
      map.valid,
      s,
      this.curveWs,
      this.curveMat.data32F,
    );
    cv.dft(this.curveMat, this.dftMat, cv.DFT_ROWS | cv.DFT_COMPLEX_OUTPUT, 0);
    const { re, im } = harmonics(this.dftMat.data32F, this.nCurves, s.pano_width, s.n_harmonics);
    const out: Extracted = { spectrum: quantise(re, im) };
    if (keep) {
      out.pano = this.pano.slice();
      out.curves = curves.slice();
    }
    return out;
  }

  delete(): void {
    this.curveMat.delete();
    this.dftMat.delete();
  }
}

/** An RGBA buffer of n pixels, opaque: the remap writes R, G and B, and nothing reads alpha. */
function opaque(n: number): Uint8Array {
  const out = new Uint8Array(4 * n);
  for (let i = 3; i < out.length; i += 4) out[i] = 255;
  return out;
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
