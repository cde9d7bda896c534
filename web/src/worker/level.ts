/**
 * Levelling (the engine's level.py, the same arithmetic in doubles): the lens's tilt found from the
 * leans of the picture's upright edges, and the band remap that undoes it. Why from the picture
 * and not from the phone's gravity: which way the lens and its image sit in the phone's frame
 * depends on the phone, the clip-on and the browser; the picture's door frames and corners say
 * the tilt by themselves.
 */
import { directionToPixel, elevationSamples, sensorInto, type CatadioptricLens, type Lens } from '../shared/lens';
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
export function intensity(
  rgba: Uint8Array | Uint8ClampedArray,
  n: number,
  out: Float64Array = new Float64Array(n),
): Float64Array {
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

/** edgeLean's working arrays for a panorama of n cells, made once and reused frame after frame. */
export interface LeanScratch {
  gx: Float64Array;
  gy: Float64Array;
  ok: Uint8Array;
  w: Float64Array;
}

export function leanScratch(n: number): LeanScratch {
  return { gx: new Float64Array(n), gy: new Float64Array(n), ok: new Uint8Array(n), w: new Float64Array(n) };
}

/** The upright edges' lean fit as (a sin az + b cos az) / cos^2 el, from n edge pixels (0: no fit). */
export function edgeLean(
  gray: Float64Array,
  rows: number,
  cols: number,
  elevations: Float64Array | Float32Array,
  valid: Uint8Array,
  ws: LeanScratch = leanScratch(rows * cols),
): { a: number; b: number; n: number } {
  const none = { a: 0, b: 0, n: 0 };
  if (rows < 3) return none;
  const daz = 360 / cols;
  const dEl = f32(f32(elevations[0]) - f32(elevations[1]));
  const { gx, gy, ok } = ws;
  ok.fill(0, 0, cols);
  ok.fill(0, (rows - 1) * cols, rows * cols);
  let nOk = 0;
  for (let i = 1; i < rows - 1; i++) {
    for (let j = 0; j < cols; j++) {
      const k = i * cols + j;
      const l = j === 0 ? k + cols - 1 : k - 1;
      const r = j === cols - 1 ? k - cols + 1 : k + 1;
      gx[k] = (gray[r] - gray[l]) / (2 * daz);
      gy[k] = (gray[k - cols] - gray[k + cols]) / (2 * dEl);
      const good = valid[k] && valid[l] && valid[r] && valid[k - cols] && valid[k + cols] ? 1 : 0;
      ok[k] = good;
      nOk += good;
    }
  }
  if (nOk < MIN_EDGES) return none;
  const w = ws.w.subarray(0, nOk);
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

/** The lens's radius table (radiusTable: elevations ascending, their radii) with each segment's
 * slope and a bucket index into it, for `radiusAt`. */
export interface RadiusTable {
  /** the elevations, then +Infinity twice: the two steps past a bucket's start never read past it */
  e: Float64Array;
  r: Float64Array;
  slope: Float64Array;
  /** null where the segments differ too much in length for buckets: bisection then */
  start: Int32Array | null;
  scale: number;
}

export function radiusTableOf(lens: CatadioptricLens): RadiusTable {
  const { r, e } = elevationSamples(lens);
  const n = r.length;
  const ep = new Float64Array(n + 2).fill(Infinity);
  ep.set(e);
  const slope = new Float64Array(n - 1);
  for (let i = 0; i < n - 1; i++) slope[i] = (r[i + 1] - r[i]) / (e[i + 1] - e[i]);
  // buckets half as wide as the narrowest segment is long: a bucket holds at most one segment's
  // end, so its start (one segment back, for rounding) is at most two segments short
  let narrowest = Infinity;
  for (let i = 0; i < n - 1; i++) narrowest = Math.min(narrowest, e[i + 1] - e[i]);
  const nb = Math.ceil((2 * (e[n - 1] - e[0])) / narrowest);
  const scale = nb / (e[n - 1] - e[0]);
  if (!(nb > 0 && nb <= 1 << 20)) return { e: ep, r, slope, start: null, scale };
  const start = new Int32Array(nb);
  for (let b = 0, i = 0; b < nb; b++) {
    const edge = e[0] + b / scale;
    while (i + 1 < n - 1 && e[i + 1] <= edge) i++;
    start[b] = Math.max(0, i - 1);
  }
  return { e: ep, r, slope, start, scale };
}

/** numpy.interp(el, e, r, NaN, NaN) over the table: the segment found from the bucket index
 * rather than by bisection, then the same slope and sum, so the same value. */
export function radiusAt(t: RadiusTable, el: number): number {
  const { e, r } = t;
  const last = r.length - 1;
  if (!(el >= e[0] && el <= e[last])) return NaN;
  if (el === e[last]) return r[last];
  let lo = 0;
  if (t.start) {
    lo = t.start[Math.min(t.start.length - 1, Math.floor((el - e[0]) * t.scale))];
    lo += +(e[lo + 1] <= el) + +(e[lo + 2] <= el); // two steps at most, without branches
  } else {
    let hi = last;
    while (hi - lo > 1) {
      const mid = (lo + hi) >> 1;
      if (e[mid] <= el) lo = mid;
      else hi = mid;
    }
  }
  return t.slope[lo] * (el - e[lo]) + r[lo];
}

/** tiltInto turns a map exactly at columns this many degrees apart (level.py's ANCHOR_DEG) ... */
export const ANCHOR_DEG = 2;
/** ... and cell by cell between two whose pixels lie further apart than this (JUMP_PX). */
export const JUMP_PX = 64;

/** Columns from one exactly turned column to the next in a map `cols` wide (level.anchor_step). */
export function anchorStep(cols: number): number {
  const step = Math.trunc((cols * ANCHOR_DEG) / 360);
  return step > 1 && cols % step === 0 ? step : 1;
}

/** What turning one map through any tilt needs, made once per map: its rows' and columns' trig,
 * the lens's radius lookup, and the anchors' working array. */
export interface Tilter {
  lens: Lens;
  upright: UnwarpMap;
  cosE: Float64Array;
  sinE: Float64Array;
  cosA: Float64Array;
  sinA: Float64Array;
  radius: RadiusTable | null;
  step: number;
  /** one row's anchors, and one stretch's cells, x and y interleaved */
  anchors: Float64Array;
  cells: Float64Array;
}

export function tilter(lens: Lens, upright: UnwarpMap): Tilter {
  const { rows, cols } = upright;
  const cosE = new Float64Array(rows);
  const sinE = new Float64Array(rows);
  for (let i = 0; i < rows; i++) {
    const e = f32(upright.elevations[i]) * RAD;
    cosE[i] = Math.cos(e);
    sinE[i] = Math.sin(e);
  }
  const cosA = new Float64Array(cols);
  const sinA = new Float64Array(cols);
  for (let j = 0; j < cols; j++) {
    const a = (((j + 0.5) * 360) / cols) * RAD;
    cosA[j] = Math.cos(a);
    sinA[j] = Math.sin(a);
  }
  const radius = lens.model === 'catadioptric' ? radiusTableOf(lens) : null;
  const step = anchorStep(cols);
  const anchors = new Float64Array((2 * cols) / step);
  return { lens, upright, cosE, sinE, cosA, sinA, radius, step, anchors, cells: new Float64Array(2 * step) };
}

/** Cells' pixels through a tilt: row i's `count` cells from column j0, `dj` apart -> out[2c],
 * out[2c + 1] = x, y of the c-th (NaN where the lens does not see the turned direction). */
type RowTurn = (i: number, j0: number, dj: number, count: number, out: Float64Array) => void;

/**
 * The turn of `t`'s cells through `rot`, a row's cells at a time (tiltInto's exact cells).
 *
 * Notes
 * -----
 * Each cell's direction times rot (rot's transpose applied: the tilt undone) is (c0, c1, c2); its
 * elevation is asin(c2). A donut's pixel is then centre + r(el) (cos phi, sin phi) with phi =
 * forward + sign * azimuth, and the azimuth's cosine and sine are c0 / h and c1 / h (h the
 * horizontal length): no atan2, cos or sin per cell, the same point to a few units in the last
 * place (level.py turns it the same way). A 360 camera's column is linear in the azimuth: atan2.
 */
function rowTurn(t: Tilter, rot: number[]): RowTurn {
  const { lens, cosE, sinE, cosA, sinA, radius } = t;
  const [r0, r1, r2, r3, r4, r5, r6, r7, r8] = rot;
  if (lens.model !== 'catadioptric' || !radius)
    return (i, j0, dj, count, out) => {
      for (let c = 0, j = j0; c < count; c++, j += dj) {
        const w0 = cosE[i] * cosA[j];
        const w1 = cosE[i] * sinA[j];
        const w2 = sinE[i];
        const c0 = w0 * r0 + w1 * r3 + w2 * r6;
        const c1 = w0 * r1 + w1 * r4 + w2 * r7;
        const c2 = w0 * r2 + w1 * r5 + w2 * r8;
        const elc = Math.asin(Math.min(1, Math.max(-1, c2))) * DEG;
        let azc = Math.atan2(c1, c0) * DEG;
        azc = azc - Math.floor(azc / 360) * 360; // numpy.mod
        const [x, y] = directionToPixel(lens, null, azc, elc);
        out[2 * c] = x;
        out[2 * c + 1] = y;
      }
    };
  const sign = (lens.ccw ?? true) ? -1 : 1;
  const fwd = (lens.forward_deg ?? 0) * RAD;
  const cF = Math.cos(fwd);
  const sF = Math.sin(fwd);
  const [cx, cy] = lens.center;
  const sensor = lens.sensor;
  // radiusAt, inlined: this is levelling's largest cost
  const { e, r: rr, slope, start, scale } = radius;
  const e0 = e[0];
  const last = rr.length - 1;
  const eLast = e[last];
  const nb = start ? start.length - 1 : 0;
  return (i, j0, dj, count, out) => {
    const ce = cosE[i];
    const w2 = sinE[i];
    for (let c = 0, j = j0; c < count; c++, j += dj) {
      const w0 = ce * cosA[j];
      const w1 = ce * sinA[j];
      const c0 = w0 * r0 + w1 * r3 + w2 * r6;
      const c1 = w0 * r1 + w1 * r4 + w2 * r7;
      const c2 = w0 * r2 + w1 * r5 + w2 * r8;
      const elc = Math.asin(Math.min(1, Math.max(-1, c2))) * DEG;
      let r: number;
      if (!(elc >= e0 && elc <= eLast)) r = NaN;
      else if (elc === eLast) r = rr[last];
      else if (start) {
        let lo = start[Math.min(nb, Math.floor((elc - e0) * scale))];
        lo += +(e[lo + 1] <= elc) + +(e[lo + 2] <= elc); // two steps at most, without branches
        r = slope[lo] * (elc - e[lo]) + rr[lo];
      } else r = radiusAt(radius, elc);
      const hh = Math.sqrt(c0 * c0 + c1 * c1);
      const ca = hh > 0 ? c0 / hh : 1; // straight up or down: azimuth 0, as atan2(0, 0) says
      const sa = hh > 0 ? c1 / hh : 0;
      if (sensor) {
        sensorInto(sensor, r * (cF * ca - sign * sF * sa), r * (sF * ca + sign * cF * sa), out, 2 * c);
        out[2 * c] += cx;
        out[2 * c + 1] += cy;
      } else {
        out[2 * c] = cx + r * (cF * ca - sign * sF * sa);
        out[2 * c + 1] = cy + r * (sF * ca + sign * cF * sa);
      }
    }
  };
}

/**
 * The upright map through a tilt, into mapX and mapY (rows x cols); where the tilted direction is
 * not seen, the upright cell. The map is turned exactly at every column ANCHOR_DEG apart
 * (`anchorStep`) and linearly between, x0 + (x1 - x0) * (s / step), the last column's stretch to
 * the first (level.py's tilted_map: under 0.08 px off); a stretch whose ends are not both seen or
 * lie more than JUMP_PX apart (the 360 camera's seam) is turned cell by cell.
 */
export function tiltInto(t: Tilter, rot: number[], mapX: Float32Array, mapY: Float32Array): void {
  const { upright, step, anchors: a } = t;
  const { rows, cols } = upright;
  const ux = upright.mapX;
  const uy = upright.mapY;
  const turn = rowTurn(t, rot);
  const cells = t.cells;
  // `count` turned cells (x, y interleaved in `out`) into the map from cell k on; an unseen one
  // reads its upright cell
  const put = (out: Float64Array, k: number, count: number): void => {
    for (let c = 0; c < count; c++) {
      const x = out[2 * c];
      const y = out[2 * c + 1];
      const ok = Number.isFinite(x) && Number.isFinite(y);
      mapX[k + c] = ok ? x : ux[k + c];
      mapY[k + c] = ok ? y : uy[k + c];
    }
  };
  const n = cols / step;
  for (let i = 0, k0 = 0; i < rows; i++, k0 += cols) {
    turn(i, 0, step, n, a);
    if (step === 1) {
      put(a, k0, cols);
      continue;
    }
    for (let m = 0, k = k0; m < n; m++, k += step) {
      const m1 = m + 1 === n ? 0 : m + 1;
      const x0 = a[2 * m];
      const y0 = a[2 * m + 1];
      const dx = a[2 * m1] - x0;
      const dy = a[2 * m1 + 1] - y0;
      if (Math.abs(dx) <= JUMP_PX && Math.abs(dy) <= JUMP_PX)
        for (let s = 0; s < step; s++) {
          const f = s / step;
          mapX[k + s] = x0 + dx * f;
          mapY[k + s] = y0 + dy * f;
        }
      else {
        turn(i, m * step, 1, step, cells);
        put(cells, k, step);
      }
    }
  }
}

/** The band remap through a tilt (a new map; tiltInto writes into given tables). */
export function tiltedMap(lens: Lens, upright: UnwarpMap, rot: number[]): UnwarpMap {
  const mapX = new Float32Array(upright.rows * upright.cols);
  const mapY = new Float32Array(upright.rows * upright.cols);
  tiltInto(tilter(lens, upright), rot, mapX, mapY);
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

/** The rotation of a tilt vector (level.py _rotation: the angle as atan2 gives it, not wrapped). */
export function vectorRotation(v: [number, number]): number[] {
  return tiltRotation(Math.hypot(v[0], v[1]), Math.atan2(v[1], v[0]) * DEG);
}

/** The remap that levels a tilt vector. */
export function vectorMap(lens: Lens, upright: UnwarpMap, v: [number, number]): UnwarpMap {
  return tiltedMap(lens, upright, vectorRotation(v));
}
