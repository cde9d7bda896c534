/**
 * Levelling (the engine's level.py, the same arithmetic in doubles): the lens's tilt found from the
 * leans of the picture's upright edges, and the band remap that undoes it. Why from the picture
 * and not from the phone's gravity: which way the lens and its image sit in the phone's frame
 * depends on the phone, the clip-on and the browser; the picture's door frames and corners say
 * the tilt by themselves.
 */
import { directionToPixel, radiusTable, type Lens } from '../shared/lens';
import type { UnwarpMap } from './unwarp';

/** The strongest tenth of the horizontal gradients are the edges whose lean counts. */
export const LEAN_PERCENTILE = 90;
/** An edge leaning more than this (deg of azimuth per deg of elevation) is not upright. */
export const LEAN_MAX = 0.5;
/** Fewer edge pixels than this: no estimate. */
export const MIN_EDGES = 200;
/** A larger estimate is capped. */
export const MAX_TILT_DEG = 15;

// numpy's deg2rad and rad2deg multiply by these (so does Python's math): the same bits as the engine
const RAD = Math.PI / 180;
const DEG = 180 / Math.PI;
/** The engine keeps a map's elevations as float32. */
const f32 = Math.fround;

/** RGBA panorama bytes -> the mean of R, G and B per pixel. */
export function intensity(rgba: Uint8Array | Uint8ClampedArray, n: number): Float64Array {
  const out = new Float64Array(n);
  for (let i = 0; i < n; i++) out[i] = (rgba[4 * i] + rgba[4 * i + 1] + rgba[4 * i + 2]) / 3;
  return out;
}

/** The k-th smallest of v (0-based), reordering v in place (Hoare's selection: O(n), no sort). */
function select(v: Float64Array, k: number): number {
  let lo = 0;
  let hi = v.length - 1;
  while (lo < hi) {
    const pivot = v[(lo + hi) >> 1];
    let i = lo;
    let j = hi;
    while (i <= j) {
      while (v[i] < pivot) i++;
      while (v[j] > pivot) j--;
      if (i <= j) {
        const t = v[i];
        v[i] = v[j];
        v[j] = t;
        i++;
        j--;
      }
    }
    if (k <= j) hi = j;
    else if (k >= i) lo = i;
    else break;
  }
  return v[k];
}

/** numpy.percentile (linear) of v (reordered in place): the two order statistics around the
 * percentile's position, interpolated from the nearer one as numpy does. */
export function percentile(v: Float64Array, q: number): number {
  const pos = (v.length - 1) * (q / 100);
  const lo = Math.floor(pos);
  const a = select(v, lo);
  let b = a;
  if (lo + 1 < v.length) {
    b = Infinity; // the smallest of those after the lo-th: the next order statistic
    for (let i = lo + 1; i < v.length; i++) if (v[i] < b) b = v[i];
  }
  const t = pos - lo;
  const d = b - a;
  return t >= 0.5 ? b - d * (1 - t) : a + d * t;
}

/** The upright edges' lean fit as (a sin az + b cos az) / cos^2 el, from n edge pixels (0: no fit). */
export function edgeLean(
  gray: Float64Array,
  rows: number,
  cols: number,
  elevations: Float64Array | Float32Array,
  valid: Uint8Array,
): { a: number; b: number; n: number } {
  const none = { a: 0, b: 0, n: 0 };
  if (rows < 3) return none;
  const daz = 360 / cols;
  const dEl = f32(f32(elevations[0]) - f32(elevations[1]));
  const gx = new Float64Array(rows * cols);
  const gy = new Float64Array(rows * cols);
  const ok = new Uint8Array(rows * cols);
  let nOk = 0;
  for (let i = 1; i < rows - 1; i++) {
    for (let j = 0; j < cols; j++) {
      const k = i * cols + j;
      const l = i * cols + ((j + cols - 1) % cols);
      const r = i * cols + ((j + 1) % cols);
      gx[k] = (gray[r] - gray[l]) / (2 * daz);
      gy[k] = (gray[k - cols] - gray[k + cols]) / (2 * dEl);
      if (valid[k] && valid[l] && valid[r] && valid[k - cols] && valid[k + cols]) {
        ok[k] = 1;
        nOk++;
      }
    }
  }
  if (nOk < MIN_EDGES) return none;
  const w = new Float64Array(nOk);
  for (let k = 0, m = 0; k < rows * cols; k++) if (ok[k]) w[m++] = gx[k] * gx[k];
  const thr = percentile(w, LEAN_PERCENTILE);
  let n = 0;
  let suu = 0;
  let suv = 0;
  let svv = 0;
  let su = 0;
  let sv = 0;
  for (let i = 1; i < rows - 1; i++) {
    const c2 = Math.cos(f32(elevations[i]) * RAD) ** 2;
    for (let j = 0; j < cols; j++) {
      const k = i * cols + j;
      const wk = gx[k] * gx[k];
      if (!ok[k] || wk < thr || !(wk > 0) || !(Math.abs(gy[k]) < LEAN_MAX * Math.abs(gx[k]))) continue;
      n++;
      const lean = -gy[k] / gx[k];
      const az = (j + 0.5) * daz * RAD;
      const u = Math.sin(az) / c2;
      const v = Math.cos(az) / c2;
      suu += wk * u * u;
      suv += wk * u * v;
      svv += wk * v * v;
      su += wk * u * lean;
      sv += wk * v * lean;
    }
  }
  if (n < MIN_EDGES) return none;
  const det = suu * svv - suv * suv;
  if (!(det > 1e-12 * Math.max(suu * svv, 1e-300))) return none;
  return { a: (svv * su - suv * sv) / det, b: (suu * sv - suv * su) / det, n };
}

/** (a, b) of edgeLean -> the tilt (deg) and the camera azimuth it leans towards (deg). */
export function leanTilt(a: number, b: number): { tilt: number; toward: number } {
  const toward = (-Math.atan2(b, a) * DEG) % 360;
  return { tilt: Math.hypot(a, b) * DEG, toward: toward < 0 ? toward + 360 : toward };
}

/** Rotation (row-major 3x3) of camera vectors (forward, right, up) by `tilt` towards azimuth `toward`. */
export function tiltRotation(tiltDeg: number, towardDeg: number): number[] {
  const t = tiltDeg * RAD;
  const a = (towardDeg + 90) * RAD;
  const [kx, ky, kz] = [Math.cos(a), Math.sin(a), 0];
  const c = Math.cos(t);
  const s = Math.sin(t);
  const C = 1 - c;
  return [
    c + C * kx * kx,
    -s * kz + C * kx * ky,
    s * ky + C * kx * kz,
    s * kz + C * ky * kx,
    c + C * ky * ky,
    -s * kx + C * ky * kz,
    -s * ky + C * kz * kx,
    s * kx + C * kz * ky,
    c + C * kz * kz,
  ];
}

const trig = new Map<number, { cosA: Float64Array; sinA: Float64Array }>();
/** cos and sin of each column's azimuth ((j + 0.5) * 360 / cols), once per width. */
function columnTrig(cols: number): { cosA: Float64Array; sinA: Float64Array } {
  let t = trig.get(cols);
  if (!t) {
    const cosA = new Float64Array(cols);
    const sinA = new Float64Array(cols);
    for (let j = 0; j < cols; j++) {
      const a = (((j + 0.5) * 360) / cols) * RAD;
      cosA[j] = Math.cos(a);
      sinA[j] = Math.sin(a);
    }
    t = { cosA, sinA };
    trig.set(cols, t);
  }
  return t;
}

/** The band remap through a tilt; where the tilted direction is not seen, the upright cell. */
export function tiltedMap(lens: Lens, upright: UnwarpMap, rot: number[]): UnwarpMap {
  const { rows, cols } = upright;
  const mapX = new Float32Array(rows * cols);
  const mapY = new Float32Array(rows * cols);
  const radius = lens.model === 'catadioptric' ? radiusTable(lens) : null;
  const { cosA, sinA } = columnTrig(cols);
  for (let i = 0; i < rows; i++) {
    const e = f32(upright.elevations[i]) * RAD;
    const ce = Math.cos(e);
    const w2 = Math.sin(e);
    for (let j = 0; j < cols; j++) {
      const w0 = ce * cosA[j];
      const w1 = ce * sinA[j];
      // the row vector times rot: rot's transpose applied, the tilt undone
      const c0 = w0 * rot[0] + w1 * rot[3] + w2 * rot[6];
      const c1 = w0 * rot[1] + w1 * rot[4] + w2 * rot[7];
      const c2 = w0 * rot[2] + w1 * rot[5] + w2 * rot[8];
      let azc = Math.atan2(c1, c0) * DEG;
      azc = azc - Math.floor(azc / 360) * 360; // numpy.mod
      const elc = Math.asin(Math.min(1, Math.max(-1, c2))) * DEG;
      const [x, y] = directionToPixel(lens, radius, azc, elc);
      const k = i * cols + j;
      const ok = Number.isFinite(x) && Number.isFinite(y);
      mapX[k] = ok ? x : upright.mapX[k];
      mapY[k] = ok ? y : upright.mapY[k];
    }
  }
  return { ...upright, mapX, mapY };
}

/** The tilt so far as a vector, and one more pass's (a, b) added to it (capped at MAX_TILT_DEG). */
export function addLean(v: [number, number], a: number, b: number): [number, number] {
  const { tilt, toward } = leanTilt(a, b);
  let vx = v[0] + tilt * Math.cos(toward * RAD);
  let vy = v[1] + tilt * Math.sin(toward * RAD);
  const scale = Math.min(1, MAX_TILT_DEG / Math.max(Math.hypot(vx, vy), 1e-9));
  vx *= scale;
  vy *= scale;
  return [vx, vy];
}

/** The remap that levels a tilt vector (level_map: the angle as atan2 gives it, not wrapped). */
export function vectorMap(lens: Lens, upright: UnwarpMap, v: [number, number]): UnwarpMap {
  return tiltedMap(lens, upright, tiltRotation(Math.hypot(v[0], v[1]), Math.atan2(v[1], v[0]) * DEG));
}
