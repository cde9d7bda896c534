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

/** What the channels of a set need: HSI (hue or saturation), intensity alone, opponent colours. */
function needs(channels: readonly string[]): { hsi: boolean; i: boolean; o: boolean } {
  for (const ch of channels)
    if (!(CHANNELS as readonly string[]).includes(ch))
      throw new Error(`unknown channel ${ch}; known: ${CHANNELS.join(', ')}`);
  const hsi = channels.some((c) => ['H', 'S', 'dH', 'dS'].includes(c));
  return { hsi, i: !hsi && channels.some((c) => c === 'I' || c === 'dI'), o: channels.some((c) => /O[12]$/.test(c)) };
}

/**
 * extractCurves' working arrays for one (panorama size, settings): a row of each channel, a column
 * sum per curve, which rows each band sums. Made once per extractor and reused frame after frame.
 */
export interface CurveScratch {
  rows: number;
  cols: number;
  /** per band, the panorama rows it sums */
  inBand: number[][];
  /** per band, its curves: the channel and the accumulator (band-major, the curves' order) */
  curves: { ch: string; acc: Float64Array }[][];
  /** per band, each channel it sums with its gradient's, if any: one pass over the row for both */
  pairs: { base: string; plain: Float64Array | null; grad: Float64Array | null }[][];
  row: Map<string, Float32Array>;
  /** the frame's float32 value of each byte per colour (gray world's gain applied) */
  lut: Float32Array[];
}

export function curveScratch(rows: number, cols: number, elevations: Float64Array, s: FeatureSettings): CurveScratch {
  const per = bandChannels(s);
  const union = [...new Set(per.flat())];
  const need = needs(union);
  const row = new Map<string, Float32Array>();
  const names = ['R', 'G', 'B', ...union];
  if (need.hsi) names.push('H', 'S', 'I');
  if (need.i) names.push('I');
  if (need.o) names.push('O1', 'O2');
  for (const n of names) if (!row.has(n)) row.set(n, new Float32Array(cols));
  const inBand = s.bands.map(([lo, hi]) => {
    const rs: number[] = [];
    for (let i = 0; i < rows; i++) if (elevations[i] >= lo - 1e-6 && elevations[i] <= hi + 1e-6) rs.push(i);
    return rs;
  });
  const curves = per.map((chs) => chs.map((ch) => ({ ch, acc: new Float64Array(cols) })));
  const pairs = curves.map((band) => {
    const bases = [...new Set(band.map(({ ch }) => (ch[0] === 'd' ? ch.slice(1) : ch)))];
    return bases.map((base) => ({
      base,
      plain: band.find((c) => c.ch === base)?.acc ?? null,
      grad: band.find((c) => c.ch === `d${base}`)?.acc ?? null,
    }));
  });
  return { rows, cols, inBand, curves, pairs, row, lut: [0, 1, 2].map(() => new Float32Array(256)) };
}

const K255 = f32(1 / 255);

/** Each byte's float32 value per colour (the engine's `astype(float32) * (1 / 255)`), times gray
 * world's gain: 0.5 / the colour's mean over the pixels the lens sees (sums in doubles). */
function colourTables(
  rgba: Uint8Array | Uint8ClampedArray,
  n: number,
  valid: Uint8Array,
  grayWorld: boolean,
  lut: Float32Array[],
): void {
  for (let v = 0; v < 256; v++) lut[0][v] = v * K255;
  if (!grayWorld) {
    lut[1].set(lut[0]);
    lut[2].set(lut[0]);
    return;
  }
  const base = lut[0];
  let count = 0;
  let s0 = 0;
  let s1 = 0;
  let s2 = 0;
  for (let i = 0, p = 0; i < n; i++, p += 4) {
    if (!valid[i]) continue;
    count++;
    s0 += base[rgba[p]];
    s1 += base[rgba[p + 1]];
    s2 += base[rgba[p + 2]];
  }
  const sums = [s0, s1, s2];
  for (let c = 2; c >= 0; c--) {
    const mean = count ? f32(sums[c] / count) : 1;
    const gain = f32(0.5 / Math.max(mean, EPS));
    for (let v = 0; v < 256; v++) lut[c][v] = base[v] * gain;
  }
}

/** Gonzalez & Woods HSI of one row: hue in turns [0, 1), saturation, intensity. */
function hsiRow(
  r: Float32Array,
  g: Float32Array,
  b: Float32Array,
  H: Float32Array,
  S: Float32Array,
  I: Float32Array,
): void {
  for (let j = 0; j < r.length; j++) {
    const R = r[j],
      G = g[j],
      B = b[j];
    const s3 = R + G + B;
    I[j] = s3 / 3;
    S[j] = 1 - (3 * Math.min(R, G, B)) / Math.max(s3, EPS);
    const num = 0.5 * (R - G + (R - B));
    const den = Math.sqrt((R - G) ** 2 + (R - B) * (G - B)) + EPS;
    const theta = Math.acos(Math.min(1, Math.max(-1, num / den)));
    H[j] = (B > G ? 2 * Math.PI - theta : theta) / (2 * Math.PI);
  }
}

/**
 * plain += one row of a channel, grad += its |d/dx| (circular: the panorama wraps; hue differences
 * wrap at one turn), in one pass; either may be null. The gradient is the engine's float32 `_hgrad`
 * value, added without being stored.
 */
function addPair(x: Float32Array, plain: Float64Array | null, grad: Float64Array | null, hue: boolean): void {
  const cols = x.length;
  if (!grad) {
    if (plain) for (let j = 0; j < cols; j++) plain[j] += x[j];
    return;
  }
  if (hue || cols < 3) {
    for (let j = 0; j < cols; j++) {
      let d = f32(x[j + 1 === cols ? 0 : j + 1] - x[j === 0 ? cols - 1 : j - 1]);
      if (hue) d = d + 0.5 - Math.floor(d + 0.5) - 0.5;
      grad[j] += f32(Math.abs(d) * 0.5);
      if (plain) plain[j] += x[j];
    }
    return;
  }
  grad[0] += f32(Math.abs(f32(x[1] - x[cols - 1])) * 0.5);
  grad[cols - 1] += f32(Math.abs(f32(x[0] - x[cols - 2])) * 0.5);
  if (plain) {
    plain[0] += x[0];
    plain[cols - 1] += x[cols - 1];
    for (let j = 1; j < cols - 1; j++) {
      grad[j] += f32(Math.abs(f32(x[j + 1] - x[j - 1])) * 0.5);
      plain[j] += x[j];
    }
  } else for (let j = 1; j < cols - 1; j++) grad[j] += f32(Math.abs(f32(x[j + 1] - x[j - 1])) * 0.5);
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
 * `band_channels`), into `out`.
 *
 * Notes
 * -----
 * One pass over the panorama's rows: each row's colours, channels and gradients, added to the
 * column sums of the bands that hold the row. The per-pixel values are the engine's float32 ones
 * (channel_images); the column sums are kept in doubles, row after row.
 */
export function extractCurves(
  rgba: Uint8Array | Uint8ClampedArray,
  rows: number,
  cols: number,
  elevations: Float64Array,
  valid: Uint8Array,
  s: FeatureSettings,
  ws: CurveScratch = curveScratch(rows, cols, elevations, s),
  out: Float32Array = new Float32Array(nCurves(s) * s.pano_width),
): Float32Array {
  if (ws.rows !== rows || ws.cols !== cols) throw new Error('curve scratch made for another panorama size');
  const { inBand, curves, pairs, row, lut } = ws;
  colourTables(rgba, rows * cols, valid, s.gray_world, lut);
  const [l0, l1, l2] = lut;
  const r = row.get('R')!;
  const g = row.get('G')!;
  const b = row.get('B')!;
  const hsi = row.has('H');
  const I = row.get('I');
  const O1 = row.get('O1');
  const O2 = row.get('O2');
  const bandsOf: number[][] = Array.from({ length: rows }, () => []);
  inBand.forEach((rs, bi) => rs.forEach((i) => bandsOf[i].push(bi)));
  for (const c of curves.flat()) c.acc.fill(0);
  for (let i = 0; i < rows; i++) {
    if (!bandsOf[i].length) continue;
    if (hsi) {
      for (let j = 0, p = 4 * i * cols; j < cols; j++, p += 4) {
        r[j] = l0[rgba[p]];
        g[j] = l1[rgba[p + 1]];
        b[j] = l2[rgba[p + 2]];
      }
      hsiRow(r, g, b, row.get('H')!, row.get('S')!, I!);
    }
    // the colours, intensity and opponent colours of each pixel, in one pass over the row
    for (let j = 0, p = 4 * i * cols; j < cols; j++, p += 4) {
      const R = l0[rgba[p]];
      const G = l1[rgba[p + 1]];
      const B = l2[rgba[p + 2]];
      if (I && !hsi) I[j] = (R + G + B) / 3;
      if (O1 && O2) {
        O1[j] = f32(R - G) * 0.5;
        O2[j] = f32(f32(R + G) - 2 * B) * 0.25;
      }
    }
    for (const bi of bandsOf[i])
      for (const { base, plain, grad } of pairs[bi]) addPair(row.get(base)!, plain, grad, base === 'H');
  }
  const width = s.pano_width;
  const os = Math.floor(cols / width);
  let k = 0;
  for (const [bi, band] of curves.entries()) {
    for (const { acc } of band) {
      const o = k * width;
      for (let j = 0; j < width; j++) {
        let a = 0;
        for (let q = 0; q < os; q++) a += acc[j * os + q];
        out[o + j] = a / (inBand[bi].length * os);
      }
      k++;
    }
  }
  normalise(out, k, width);
  if (s.soft_clip_sd) softClip(out, k, width, s.soft_clip_sd);
  return out;
}
