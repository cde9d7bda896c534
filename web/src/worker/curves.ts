/**
 * Omni-projection curves (the paper's Eq. 3), as the engine's curves.py computes them: column means
 * of colour channels over elevation bands, normalised to zero mean and unit variance, then softly
 * clipped where the venue's settings say so (`soft_clip_sd`).
 * Input is the unwarped band panorama as RGBA bytes (what canvas and opencv.js give us).
 */
import { bandChannels, nCurves, type FeatureSettings } from '../shared/settings';

export const CHANNELS = ['H', 'S', 'I', 'dH', 'dS', 'dI', 'O1', 'O2', 'dO1', 'dO2'] as const;
const EPS = 1e-6;
const f32 = Math.fround;

/** RGBA bytes -> three float32 planes in [0, 1] (the engine's `astype(float32) * (1 / 255)`). */
export function toFloat(rgba: Uint8Array | Uint8ClampedArray, n: number): [Float32Array, Float32Array, Float32Array] {
  const k = f32(1 / 255);
  const r = new Float32Array(n);
  const g = new Float32Array(n);
  const b = new Float32Array(n);
  for (let i = 0, p = 0; i < n; i++, p += 4) {
    r[i] = rgba[p] * k;
    g[i] = rgba[p + 1] * k;
    b[i] = rgba[p + 2] * k;
  }
  return [r, g, b];
}

/** Gray-world constancy: each channel times 0.5 / its mean over the pixels the lens sees. */
export function grayWorld(rgb: Float32Array[], valid: Uint8Array): void {
  let count = 0;
  const sums = [0, 0, 0];
  for (let i = 0; i < valid.length; i++) {
    if (!valid[i]) continue;
    count++;
    sums[0] += rgb[0][i];
    sums[1] += rgb[1][i];
    sums[2] += rgb[2][i];
  }
  for (let c = 0; c < 3; c++) {
    const mean = count ? f32(sums[c] / count) : 1;
    const gain = f32(0.5 / Math.max(mean, EPS));
    const plane = rgb[c];
    for (let i = 0; i < plane.length; i++) plane[i] = plane[i] * gain;
  }
}

/** Gonzalez & Woods HSI: hue in turns [0, 1), saturation, intensity. */
function hsi(r: Float32Array, g: Float32Array, b: Float32Array): { H: Float32Array; S: Float32Array; I: Float32Array } {
  const n = r.length;
  const H = new Float32Array(n);
  const S = new Float32Array(n);
  const I = new Float32Array(n);
  for (let i = 0; i < n; i++) {
    const R = r[i],
      G = g[i],
      B = b[i];
    const s3 = R + G + B;
    I[i] = s3 / 3;
    S[i] = 1 - (3 * Math.min(R, G, B)) / Math.max(s3, EPS);
    const num = 0.5 * (R - G + (R - B));
    const den = Math.sqrt((R - G) ** 2 + (R - B) * (G - B)) + EPS;
    const theta = Math.acos(Math.min(1, Math.max(-1, num / den)));
    H[i] = (B > G ? 2 * Math.PI - theta : theta) / (2 * Math.PI);
  }
  return { H, S, I };
}

/** |d/dx| along each row, circular (the panorama wraps); hue differences wrap at one turn. */
function hgrad(x: Float32Array, rows: number, cols: number, circularUnit: boolean): Float32Array {
  const out = new Float32Array(x.length);
  for (let i = 0; i < rows; i++) {
    const o = i * cols;
    for (let j = 0; j < cols; j++) {
      let d = f32(x[o + (j + 1 === cols ? 0 : j + 1)] - x[o + (j === 0 ? cols - 1 : j - 1)]);
      if (circularUnit) d = d + 0.5 - Math.floor(d + 0.5) - 0.5;
      out[o + j] = Math.abs(d) * 0.5;
    }
  }
  return out;
}

/** The per-pixel channel images the curves average, (rows x cols) each. */
export function channelImages(
  rgb: Float32Array[],
  rows: number,
  cols: number,
  channels: readonly string[],
): Map<string, Float32Array> {
  const [r, g, b] = rgb;
  const n = r.length;
  const base = new Map<string, Float32Array>();
  if (channels.some((c) => ['H', 'S', 'dH', 'dS'].includes(c))) {
    const { H, S, I } = hsi(r, g, b);
    base.set('H', H).set('S', S).set('I', I);
  } else if (channels.some((c) => c === 'I' || c === 'dI')) {
    const I = new Float32Array(n);
    for (let i = 0; i < n; i++) I[i] = (r[i] + g[i] + b[i]) / 3;
    base.set('I', I);
  }
  if (channels.some((c) => c.endsWith('O1') || c.endsWith('O2'))) {
    const o1 = new Float32Array(n);
    const o2 = new Float32Array(n);
    for (let i = 0; i < n; i++) {
      o1[i] = f32(r[i] - g[i]) * 0.5;
      o2[i] = f32(f32(r[i] + g[i]) - 2 * b[i]) * 0.25;
    }
    base.set('O1', o1).set('O2', o2);
  }
  const out = new Map<string, Float32Array>();
  for (const ch of channels) {
    if (ch === 'H' || ch === 'S' || ch === 'I' || ch === 'O1' || ch === 'O2') out.set(ch, base.get(ch)!);
    else if (ch.startsWith('d') && base.has(ch.slice(1)))
      out.set(ch, hgrad(base.get(ch.slice(1))!, rows, cols, ch === 'dH'));
    else throw new Error(`unknown channel ${ch}; known: ${CHANNELS.join(', ')}`);
  }
  return out;
}

/** Zero mean, unit (population) standard deviation per curve; a flat curve stays zero. */
export function normalise(curves: Float32Array, n: number, width: number): void {
  for (let c = 0; c < n; c++) {
    const o = c * width;
    let m = 0;
    for (let j = 0; j < width; j++) m += curves[o + j];
    m /= width;
    let v = 0;
    for (let j = 0; j < width; j++) v += (curves[o + j] - m) ** 2;
    const sd = Math.max(Math.sqrt(v / width), 1e-4);
    for (let j = 0; j < width; j++) curves[o + j] = (curves[o + j] - m) / sd;
  }
}

/** sd * tanh(curve / sd), normalised again (curves.py `soft_clip`): no few columns dominate. */
export function softClip(curves: Float32Array, n: number, width: number, sd: number): void {
  const c = f32(sd);
  for (let i = 0; i < n * width; i++) curves[i] = c * Math.tanh(curves[i] / c);
  normalise(curves, n, width);
}

/**
 * Band panorama (RGBA, rows x cols*oversample) -> nCurves x pano_width normalised curves,
 * band-major, each band's channels in the settings' order (`channels`, or the band's own list:
 * `band_channels`).
 */
export function extractCurves(
  rgba: Uint8Array | Uint8ClampedArray,
  rows: number,
  cols: number,
  elevations: Float64Array,
  valid: Uint8Array,
  s: FeatureSettings,
): Float32Array {
  const rgb = toFloat(rgba, rows * cols);
  if (s.gray_world) grayWorld(rgb, valid);
  const per = bandChannels(s);
  const imgs = channelImages(rgb, rows, cols, [...new Set(per.flat())]);
  const width = s.pano_width;
  const os = Math.floor(cols / width);
  const out = new Float32Array(nCurves(s) * width);
  const col = new Float64Array(cols);
  let k = 0;
  for (const [b, [lo, hi]] of s.bands.entries()) {
    const inBand: number[] = [];
    for (let i = 0; i < rows; i++) if (elevations[i] >= lo - 1e-6 && elevations[i] <= hi + 1e-6) inBand.push(i);
    for (const ch of per[b]) {
      const img = imgs.get(ch)!;
      col.fill(0);
      for (const i of inBand) {
        const o = i * cols;
        for (let j = 0; j < cols; j++) col[j] += img[o + j];
      }
      const o = k * width;
      for (let j = 0; j < width; j++) {
        let acc = 0;
        for (let q = 0; q < os; q++) acc += col[j * os + q];
        out[o + j] = acc / (inBand.length * os);
      }
      k++;
    }
  }
  normalise(out, k, width);
  if (s.soft_clip_sd) softClip(out, k, width, s.soft_clip_sd);
  return out;
}
