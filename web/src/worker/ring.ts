/**
 * The donut's ring in a camera frame, found without any target: a port of the engine's
 * calib/ring.py, whose docstring states the algorithm (steps A1-A9, B1-B7, C) and constants; the
 * same numbers here, so that the phone and `omninav calib ring` agree within 0.5 px (they agree
 * within 0.01 px on the golden frames). opencv.js does the image work (cvtColor, resize,
 * GaussianBlur, Canny); Sobel at the edge pixels, votes, coverage, profiles and circle fits are
 * plain loops. Every Mat is deleted in a finally. No picture leaves the worker: only these numbers do.
 */
import type { CatadioptricLens, Lens } from '../shared/lens';
import type { Look } from '../shared/protocol';
import type { Cv, CvMat } from './extract';
import C from '../../../backend/omninav/calib/ring_constants.json';

/** A Mat that can give a window of itself. */
interface RingMat extends CvMat {
  roi(rect: unknown): RingMat;
  copyTo(dst: CvMat): void;
}

/** The slice of opencv.js the ring finder needs on top of the extractor's. */
export interface RingCv extends Cv {
  Mat: new (...args: unknown[]) => RingMat;
  Size: new (w: number, h: number) => unknown;
  Rect: new (x: number, y: number, w: number, h: number) => unknown;
  COLOR_RGBA2GRAY: number;
  INTER_AREA: number;
  BORDER_DEFAULT: number;
  cvtColor(src: CvMat, dst: CvMat, code: number, dstCn: number): void;
  resize(src: CvMat, dst: CvMat, size: unknown, fx: number, fy: number, interp: number): void;
  GaussianBlur(src: CvMat, dst: CvMat, size: unknown, sx: number, sy: number, border: number): void;
  Canny(src: CvMat, dst: CvMat, t1: number, t2: number, aperture: number, l2: boolean): void;
}

/** A ring in full-resolution pixels (ring.py's `Ring`, the fields a phone needs). */
export interface Ring {
  image_size: [number, number];
  center: [number, number];
  /** 0 when there is no inner edge (a fisheye). */
  r_inner: number;
  r_outer: number;
  /** Share (0..1) of the outer circle's circumference inside the image. */
  visible: number;
  frames_used?: number;
  frames_total?: number;
  /** A9: the outer edge has a darker surround, or a brighter one (a bright housing, a wall). */
  surround?: 'darker' | 'brighter';
  /** A9: the radius of a complete circle outside the scene taken for the housing (0: none). */
  housing?: number;
  /** A9: the scene annulus's texture over its surround's (0: no surround seen). */
  texture_ratio?: number;
}

// ring.py's constants, read from the one file both languages read (ring.py's docstring says what
// each does)
export const COARSE_MAX: number = C.COARSE_MAX;
const COARSE_SIGMA: number = C.COARSE_SIGMA;
const CANNY = C.CANNY as [number, number];
const CANNY_FAINT = C.CANNY_FAINT as [number, number]; // A8's second look for a dim scene's inner edge
const VOTE_STEP: number = C.VOTE_STEP;
const VOTE_EVERY: number = C.VOTE_EVERY;
const VOTE_BOX: number = C.VOTE_BOX;
const OUTER_WINDOWS: number[] = C.OUTER_WINDOWS;
const MIN_VOTES: number = C.MIN_VOTES;
const RADIAL_COS: number = C.RADIAL_COS;
const N_BINS: number = C.N_BINS;
const MIN_COVERAGE: number = C.MIN_COVERAGE;
const OUTER_PICK: number = C.OUTER_PICK;
const FINE_SIGMA: number = C.FINE_SIGMA;
const N_PROFILES: number = C.N_PROFILES;
const PROFILE_STEP: number = C.PROFILE_STEP;
const MIN_EDGE: number = C.MIN_EDGE;
const MIN_SHARE: number = C.MIN_SHARE;
const EDGE_BIAS_PX: number = C.EDGE_BIAS_PX;
const N_VISIBLE: number = C.N_VISIBLE;
const MIN_SIDE: number = C.MIN_SIDE;
const SCENE_SHARE: number = C.SCENE_SHARE;
const SCENE_SMOOTH: number = C.SCENE_SMOOTH;
const GAP = C.GAP as [number, number];
const TEXTURE_FLOOR: number = C.TEXTURE_FLOOR;
const INNER_WINDOW: number = C.INNER_WINDOW;
const INNER_OFFSET: number = C.INNER_OFFSET;
const INNER_DARK: number = C.INNER_DARK;
const INNER_STEP: number = C.INNER_STEP;
/** Pixels around the coarse circle that the sub-pixel stage may read (its profiles reach 6 px out). */
const WINDOW_MARGIN = 12;

type Circle = [number, number, number];
const f32 = Math.fround;
/** Every length of the algorithm: sqrt(dx^2 + dy^2) as ring.py sums it, never Math.hypot (the two differ in the last bit). */
const dist = (dx: number, dy: number) => Math.sqrt(dx * dx + dy * dy);

/**
 * cos and sin of 2 pi (k + 0.5 if half else k) / n, rounded to multiples of 2^-40 as ring.py's
 * unit_circle rounds them (V8's Math and the C library differ in the last bit at some angles).
 */
export function unitCircle(n: number, half: boolean): [Float64Array, Float64Array] {
  const key = `${n}:${half}`;
  let got = UNIT.get(key);
  if (!got) {
    const round = (v: number) => Math.floor(v * 2 ** 40 + 0.5) / 2 ** 40;
    const t = (k: number) => (2 * Math.PI * (k + (half ? 0.5 : 0))) / n;
    got = [
      Float64Array.from(range(n), (k) => round(Math.cos(t(k)))),
      Float64Array.from(range(n), (k) => round(Math.sin(t(k)))),
    ];
    UNIT.set(key, got);
  }
  return got;
}
const UNIT = new Map<string, [Float64Array, Float64Array]>();

/** B7: share of the circle's circumference inside a w x h image (which spans -0.5 .. w - 0.5). */
export function visibleShare(center: readonly [number, number], r: number, w: number, h: number): number {
  let inside = 0;
  const [cos, sin] = unitCircle(N_VISIBLE, true);
  for (let k = 0; k < N_VISIBLE; k++) {
    const x = center[0] + r * cos[k];
    const y = center[1] + r * sin[k];
    if (x >= -0.5 && x <= w - 0.5 && y >= -0.5 && y <= h - 0.5) inside++;
  }
  return inside / N_VISIBLE;
}

const median = (v: ArrayLike<number>): number => {
  const s = Float64Array.from(v).sort();
  const k = s.length >> 1;
  return s.length % 2 ? s[k] : 0.5 * (s[k - 1] + s[k]);
};

/** Solve the 3x3 system A s = b (Gaussian elimination with partial pivoting); null when singular. */
function solve3(A: number[], b: number[]): [number, number, number] | null {
  const m = [A.slice(0, 3).concat(b[0]), A.slice(3, 6).concat(b[1]), A.slice(6, 9).concat(b[2])];
  for (let c = 0; c < 3; c++) {
    let p = c;
    for (let r = c + 1; r < 3; r++) if (Math.abs(m[r][c]) > Math.abs(m[p][c])) p = r;
    if (Math.abs(m[p][c]) < 1e-300) return null;
    [m[c], m[p]] = [m[p], m[c]];
    for (let r = c + 1; r < 3; r++) {
      const f = m[r][c] / m[c][c];
      for (let k = c; k < 4; k++) m[r][k] -= f * m[c][k];
    }
  }
  const x = [0, 0, 0];
  for (let r = 2; r >= 0; r--) {
    let v = m[r][3];
    for (let k = r + 1; k < 3; k++) v -= m[r][k] * x[k];
    x[r] = v / m[r][r];
  }
  return [x[0], x[1], x[2]];
}

/** Kasa's circle fit: least squares of x^2 + y^2 + D x + E y + F = 0, about the points' mean. */
export function fitCircleAlgebraic(xs: ArrayLike<number>, ys: ArrayLike<number>, idx: ArrayLike<number>): Circle {
  const n = idx.length;
  let mx = 0;
  let my = 0;
  for (let i = 0; i < n; i++) {
    mx += xs[idx[i]];
    my += ys[idx[i]];
  }
  mx /= n;
  my /= n;
  const A = [0, 0, 0, 0, 0, 0, 0, 0, 0];
  const b = [0, 0, 0];
  for (let i = 0; i < n; i++) {
    const u = xs[idx[i]] - mx;
    const v = ys[idx[i]] - my;
    const row = [u, v, 1];
    const rhs = -(u * u + v * v);
    for (let a = 0; a < 3; a++) {
      b[a] += row[a] * rhs;
      for (let c = 0; c < 3; c++) A[a * 3 + c] += row[a] * row[c];
    }
  }
  const sol = solve3(A, b) ?? [0, 0, 0];
  const cx = -sol[0] / 2;
  const cy = -sol[1] / 2;
  return [cx + mx, cy + my, Math.sqrt(Math.max(cx * cx + cy * cy - sol[2], 0))];
}

/** Gauss-Newton on the geometric residuals |p - c| - r, from `init`. */
export function fitCircleGeometric(
  xs: ArrayLike<number>,
  ys: ArrayLike<number>,
  idx: ArrayLike<number>,
  init: Circle,
): Circle {
  let [cx, cy, r] = init;
  for (let it = 0; it < 20; it++) {
    const A = [0, 0, 0, 0, 0, 0, 0, 0, 0];
    const b = [0, 0, 0];
    for (let i = 0; i < idx.length; i++) {
      const dx = xs[idx[i]] - cx;
      const dy = ys[idx[i]] - cy;
      const d = Math.max(Math.sqrt(dx * dx + dy * dy), 1e-9);
      const e = d - r;
      const j = [-dx / d, -dy / d, -1];
      for (let a = 0; a < 3; a++) {
        b[a] -= j[a] * e;
        for (let c = 0; c < 3; c++) A[a * 3 + c] += j[a] * j[c];
      }
    }
    const step = solve3(A, b);
    if (!step) break;
    cx += step[0];
    cy += step[1];
    r += step[2];
    if (Math.max(Math.abs(step[0]), Math.abs(step[1]), Math.abs(step[2])) < 1e-6) break;
  }
  return [cx, cy, r];
}

const range = (n: number): number[] => Array.from({ length: n }, (_, i) => i);

/** B3: circle fit with two rounds of 3-sigma rejection; -> (circle, indices kept). */
function fitRobust(xs: Float64Array, ys: Float64Array): [Circle, number[]] {
  let keep = range(xs.length);
  let c = fitCircleGeometric(xs, ys, keep, fitCircleAlgebraic(xs, ys, keep));
  for (let round = 0; round < 2; round++) {
    const e = Float64Array.from(xs, (x, i) => Math.abs(dist(x - c[0], ys[i] - c[1]) - c[2]));
    const sigma = Math.max(0.05, 1.4826 * median(keep.map((i) => e[i])));
    keep = keep.filter((i) => e[i] <= 3 * sigma);
    if (keep.length < 3) break;
    c = fitCircleGeometric(xs, ys, keep, fitCircleAlgebraic(xs, ys, keep));
  }
  return [c, keep];
}

/** A4: the coarse frame's edge pixels (row-major) and their unit gradients (towards the brighter side). */
interface Edges {
  x: Float64Array;
  y: Float64Array;
  ux: Float64Array;
  uy: Float64Array;
  n: number;
  /** A3's blurred coarse image (cols x rows), for A9's texture and A8's dark inside. */
  blur: Uint8Array;
  cols: number;
  rows: number;
}

/** A reflected index (OpenCV's BORDER_DEFAULT) into 0 .. n - 1. */
const refl = (v: number, n: number) => (v < 0 ? Math.min(1, n - 1) : v >= n ? Math.max(n - 2, 0) : v);

/** A3's Sobel (3x3, reflected border) of a uint8 image at one pixel: exactly cv.Sobel's values there. */
function sobelAt(g: Uint8Array, cols: number, rows: number, px: number, py: number): [number, number] {
  const xm = refl(px - 1, cols);
  const xp = refl(px + 1, cols);
  const ym = refl(py - 1, rows) * cols;
  const y0 = py * cols;
  const yp = refl(py + 1, rows) * cols;
  return [
    g[ym + xp] - g[ym + xm] + 2 * (g[y0 + xp] - g[y0 + xm]) + g[yp + xp] - g[yp + xm],
    g[yp + xm] - g[ym + xm] + 2 * (g[yp + px] - g[ym + px]) + g[yp + xp] - g[ym + xp],
  ];
}

/**
 * A7: a (rmax + 3) x N_BINS table of radial edge points around `center` (inward: gradient towards
 * the centre; outward: away), and which points were radial in that sense, with their distances.
 */
function hits(e: Edges, center: [number, number], rmax: number, outward: boolean) {
  const table = new Uint8Array((rmax + 3) * N_BINS);
  const sel = new Uint8Array(e.n);
  const far = new Float64Array(e.n);
  for (let i = 0; i < e.n; i++) {
    const dx = e.x[i] - center[0];
    const dy = e.y[i] - center[1];
    const d = dist(dx, dy);
    far[i] = d;
    if (!(d > 0)) continue;
    const c = (e.ux[i] * dx + e.uy[i] * dy) / Math.max(d, 1e-9);
    if (outward ? !(c > RADIAL_COS) : !(c < -RADIAL_COS)) continue;
    const q = Math.floor(d + 0.5);
    if (q > rmax + 2) continue;
    let ang = Math.atan2(dy, dx) % (2 * Math.PI);
    if (ang < 0) ang += 2 * Math.PI;
    const n = Math.min(N_BINS - 1, Math.max(0, Math.floor((ang / (2 * Math.PI)) * N_BINS)));
    table[q * N_BINS + n] = 1;
    sel[i] = 1;
  }
  return { table, sel, dist: far };
}

const [BIN_COS, BIN_SIN] = unitCircle(N_BINS, true);

/** A7: per radius, the share of the visible angle bins with an edge hit at r - win .. r + win. */
function coverage(
  table: Uint8Array,
  center: [number, number],
  radii: number[],
  cw: number,
  ch: number,
  win: number,
): Float64Array {
  // hits per bin up to each radius: "a hit within r +- win" is then one difference
  const rows = table.length / N_BINS;
  const upto = new Int32Array((rows + 1) * N_BINS);
  for (let q = 0; q < rows; q++)
    for (let n = 0; n < N_BINS; n++) upto[(q + 1) * N_BINS + n] = upto[q * N_BINS + n] + table[q * N_BINS + n];
  const out = new Float64Array(radii.length);
  radii.forEach((r, k) => {
    let vis = 0;
    let cov = 0;
    const hi = (r + win + 1) * N_BINS;
    const lo = (r - win) * N_BINS;
    for (let n = 0; n < N_BINS; n++) {
      const x = center[0] + r * BIN_COS[n];
      const y = center[1] + r * BIN_SIN[n];
      if (!(x >= -0.5 && x <= cw - 0.5 && y >= -0.5 && y <= ch - 0.5)) continue;
      vis++;
      if (upto[hi + n] > upto[lo + n]) cov++;
    }
    out[k] = vis >= 36 ? cov / Math.max(vis, 1) : 0;
  });
  return out;
}

/**
 * A3-A4: edge pixels of the coarse grey image, with their unit gradients. Sobel (3x3, reflected
 * border as OpenCV's BORDER_DEFAULT) is evaluated at the edge pixels only: on uint8 input its
 * sums are small integers, so these are exactly the values cv.Sobel would give, at a tenth of the cost.
 */
function coarseEdges(cv: RingCv, small: CvMat, canny: readonly [number, number] = CANNY): Edges {
  const blur = new cv.Mat();
  const edges = new cv.Mat();
  try {
    cv.GaussianBlur(small, blur, new cv.Size(5, 5), COARSE_SIGMA, COARSE_SIGMA, cv.BORDER_DEFAULT);
    cv.Canny(blur, edges, canny[0], canny[1], 3, false);
    const { rows, cols } = small;
    const ed = edges.data;
    const g = blur.data;
    const idx: number[] = [];
    for (let i = 0; i < rows * cols; i++) if (ed[i]) idx.push(i);
    const x = new Float64Array(idx.length);
    const y = new Float64Array(idx.length);
    const ux = new Float64Array(idx.length);
    const uy = new Float64Array(idx.length);
    let n = 0;
    for (const i of idx) {
      const px = i % cols;
      const py = (i / cols) | 0;
      const [gx, gy] = sobelAt(g, cols, rows, px, py);
      if (gx === 0 && gy === 0) continue;
      const m = Math.sqrt(gx * gx + gy * gy);
      x[n] = px;
      y[n] = py;
      ux[n] = gx / m;
      uy[n] = gy / m;
      n++;
    }
    return { x, y, ux, uy, n, blur: g.slice(), cols, rows };
  } finally {
    blur.delete();
    edges.delete();
  }
}

/**
 * A running sum over +-h along one axis of a grid: `n` cells a line, `lines` lines; cell i of line
 * j is at j * lineStep + i * step. Cells off the grid count 0 (A6's box sum, one axis at a time).
 */
function boxSum(v: Int32Array, n: number, lines: number, step: number, lineStep: number, h: number): Int32Array {
  const out = new Int32Array(v.length);
  for (let j = 0; j < lines; j++) {
    const o = j * lineStep;
    let s = 0;
    for (let i = 0; i <= Math.min(h, n - 1); i++) s += v[o + i * step];
    for (let i = 0; i < n; i++) {
      out[o + i * step] = s;
      if (i + h + 1 < n) s += v[o + (i + h + 1) * step];
      if (i - h >= 0) s -= v[o + (i - h) * step];
    }
  }
  return out;
}

/** Stage A's ring, in coarse pixels, and what A9 decided about its edges (ring.py's `Coarse`). */
interface Coarse {
  center: [number, number];
  rInner: number;
  rOuter: number;
  /** (sx, sy): coarse / full resolution. */
  scale: [number, number];
  /** B2's sign for the outer edge: -1 darker outside, +1 brighter. */
  outerSign: number;
  housing: number;
  textureRatio: number;
  /** A8: the dark centre's own centre. */
  innerCenter: [number, number] | null;
}

const gapPx = (r: number) => GAP[0] * r + GAP[1];

/** A9: T(r) for r = 0 .. rmax, the mean tangential gradient along the circle (NaN: under 36 angles in the image). */
function texture(e: Edges, c: [number, number], rmax: number): Float64Array {
  const { blur, cols, rows } = e;
  const out = new Float64Array(rmax + 1);
  for (let r = 0; r <= rmax; r++) {
    let n = 0;
    let total = 0;
    for (let k = 0; k < N_BINS; k++) {
      const u = Math.floor(c[0] + r * BIN_COS[k] + 0.5);
      const v = Math.floor(c[1] + r * BIN_SIN[k] + 0.5);
      if (u < 0 || u >= cols || v < 0 || v >= rows) continue;
      const [gx, gy] = sobelAt(blur, cols, rows, u, v);
      total += Math.abs(-BIN_SIN[k] * gx + BIN_COS[k] * gy);
      n++;
    }
    out[r] = n >= 36 ? total / Math.max(n, 1) : NaN;
  }
  return out;
}

/** A9: Ts, the mean of the defined T over r - SCENE_SMOOTH .. r + SCENE_SMOOTH. */
function smooth(t: Float64Array): Float64Array {
  const out = new Float64Array(t.length);
  for (let r = 0; r < t.length; r++) {
    let total = 0;
    let count = 0;
    for (let j = Math.max(0, r - SCENE_SMOOTH); j <= Math.min(t.length - 1, r + SCENE_SMOOTH); j++)
      if (!Number.isNaN(t[j])) [total, count] = [total + t[j], count + 1];
    out[r] = count > 0 ? total / count : NaN;
  }
  return out;
}

/** A9: [s, e], the radii in 1 .. rHi where the smoothed texture stays above SCENE_SHARE of its peak. */
function sceneRun(ts: Float64Array, rHi: number): [number, number] | null {
  let rp = -1;
  for (let r = 1; r <= Math.min(rHi, ts.length - 1); r++)
    if (!Number.isNaN(ts[r]) && (rp < 0 || ts[r] > ts[rp])) rp = r;
  if (rp < 0) return null;
  const floor = SCENE_SHARE * ts[rp];
  let e = rp;
  while (e + 1 <= rHi && ts[e + 1] >= floor) e++;
  let s = rp;
  while (s - 1 >= 1 && ts[s - 1] >= floor) s--;
  return [s, e];
}

/** A9: the most complete circle of radial edges of either kind, r in lo..hi: [score, r, sign] (-1 inward, +1 outward). */
function either(
  e: Edges,
  c: [number, number],
  lo: number,
  hi: number,
  cw: number,
  ch: number,
): [number, number, number] {
  let best: [number, number, number] = [0, 0, 0];
  if (hi < lo) return best;
  const radii = range(hi - lo + 1).map((i) => i + lo);
  for (const [outward, sign] of [
    [false, -1],
    [true, 1],
  ] as const) {
    const sc = coverage(hits(e, c, hi + 1, outward).table, c, radii, cw, ch, 1);
    let k = 0;
    for (let i = 1; i < sc.length; i++) if (sc[i] > sc[k]) k = i;
    if (sc[k] > best[0]) best = [sc[k], radii[k], sign];
  }
  return best;
}

/** A9, outer: [circle, sign, housing], A7's circle unless it lies outside the scene and an edge where the scene ends replaces it. */
function sceneOuter(e: Edges, circle: Circle, ts: Float64Array, cw: number, ch: number): [Circle, number, number] {
  const [a1, b1, r1] = circle;
  const run = sceneRun(ts, Math.floor(r1));
  const gap = gapPx(r1);
  if (!run || r1 - run[1] <= gap) return [circle, -1, 0];
  const end = run[1];
  const lo = Math.max(2, Math.floor(end - gap));
  const hi = Math.floor(r1 - gap);
  const [score, r, sign] = either(e, [a1, b1], lo, hi, cw, ch);
  if (score < MIN_COVERAGE) return [circle, -1, 0];
  const kind = hits(e, [a1, b1], r + 2, sign > 0);
  const near: number[] = [];
  for (let i = 0; i < e.n; i++) if (kind.sel[i] && Math.abs(kind.dist[i] - r) <= 2) near.push(i);
  if (near.length < 20) return [circle, -1, 0];
  return [fitCircleAlgebraic(e.x, e.y, near), sign, r1];
}

/** A9: the median texture over the scene [start, r1] over the surround's (0: no surround seen). */
function textureRatio(t: Float64Array, start: number, r1: number): number {
  const gap = gapPx(r1);
  const inside: number[] = [];
  const out: number[] = [];
  t.forEach((v, r) => {
    if (Number.isNaN(v)) return;
    if (r >= start && r <= r1) inside.push(v);
    if (r >= r1 + 3 && r <= r1 + 3 + gap) out.push(v);
  });
  if (!inside.length || !out.length) return 0;
  return median(inside) / Math.max(TEXTURE_FLOOR, median(out));
}

/** Stage A: the ring in coarse pixels, or null without a ring. */
function coarseRing(cv: RingCv, grey: CvMat): Coarse | null {
  const h = grey.rows;
  const w = grey.cols;
  const f = Math.min(1, COARSE_MAX / Math.max(w, h));
  const cw = Math.floor(w * f + 0.5);
  const ch = Math.floor(h * f + 0.5);
  // the coarse image stays until A8 is done: a dim scene's inner edge is looked for again there
  const small = f < 1 ? new cv.Mat() : null;
  try {
    if (small) cv.resize(grey, small, new cv.Size(cw, ch), 0, 0, cv.INTER_AREA);
    return coarseStages(cv, small ?? grey, w, h, cw, ch);
  } finally {
    small?.delete();
  }
}

function coarseStages(cv: RingCv, img: CvMat, w: number, h: number, cw: number, ch: number): Coarse | null {
  const e = coarseEdges(cv, img);
  if (e.n < 20) return null;
  const rmin = Math.floor(0.15 * Math.min(cw, ch) + 0.5);
  const rmax = Math.floor(0.6 * Math.max(cw, ch) + 0.5);
  // A5: votes along each gradient towards the brighter side, in float32 as the engine casts them
  const acc = new Int32Array(cw * ch);
  for (let i = 0; i < e.n; i += VOTE_EVERY) {
    const vx = f32(e.x[i]);
    const vy = f32(e.y[i]);
    const vux = f32(e.ux[i]);
    const vuy = f32(e.uy[i]);
    for (let k = rmin; k <= rmax; k += VOTE_STEP) {
      const a = Math.floor(f32(f32(vx + f32(k * vux)) + 0.5));
      const b = Math.floor(f32(f32(vy + f32(k * vuy)) + 0.5));
      // a ray that has left the image never comes back (it starts inside, and the image is convex)
      if (a < 0 || a >= cw || b < 0 || b >= ch) break;
      acc[b * cw + a]++;
    }
  }
  // A6: the VOTE_BOX x VOTE_BOX box sum's first maximum (separable: rows, then columns; cells off
  // the image count 0)
  const h2 = VOTE_BOX >> 1;
  const box = boxSum(boxSum(acc, cw, ch, 1, cw, h2), ch, cw, cw, 1, h2);
  let best = -1;
  let at = 0;
  for (let p = 0; p < cw * ch; p++) if (box[p] > best) [best, at] = [box[p], p];
  if (best < MIN_VOTES) return null;
  // A7: the outer circle, first tolerant of the votes' error, then around the better centre
  const circle = outerCircle(e, [at % cw, Math.floor(at / cw)], rmin, rmax, cw, ch);
  if (!circle) return null;
  // A9: is that circle the scene's edge, or a housing's outside it?
  let t = texture(e, [circle[0], circle[1]], Math.floor(circle[2] + 3 + gapPx(circle[2])));
  const [[a1, b1, r1], outerSign, housing] = sceneOuter(e, circle, smooth(t), cw, ch);
  if (housing > 0) t = texture(e, [a1, b1], Math.floor(r1 + 3 + gapPx(r1)));
  // A8: the inner radius (a dark centre) just inside where the scene starts
  const run = sceneRun(smooth(t), Math.floor(r1));
  const lo = Math.floor(0.1 * r1 + 0.5);
  const hi = Math.floor(0.9 * r1 + 0.5);
  let inner: Circle | null = null;
  if (hi > lo + 2 && lo >= 1) {
    const where = { c: [a1, b1] as [number, number], lo, hi, cw, ch, start: run ? run[0] : null, gap: gapPx(r1) };
    inner = innerCircle(e, where);
    // a dim scene's faint inner edge: again with the edge points of a fainter Canny
    if (!inner) inner = innerCircle(coarseEdges(cv, img, CANNY_FAINT), where);
  }
  // A9: the texture ratio, over the scene from its inner edge (or from where its texture starts)
  const r2 = inner ? inner[2] : 0;
  const start = r2 || (run ? run[0] : 0);
  return {
    center: [a1, b1],
    rInner: r2,
    innerCenter: inner ? [inner[0], inner[1]] : null,
    rOuter: r1,
    scale: [cw / w, ch / h],
    outerSign,
    housing,
    textureRatio: textureRatio(t, start, r1),
  };
}

interface InnerSearch {
  c: [number, number];
  lo: number;
  hi: number;
  cw: number;
  ch: number;
  /** A9's scene run's start (null: no run). */
  start: number | null;
  gap: number;
}

/** A8: is the blurred picture brighter just outside radius r than just inside, all round? */
function darkInside(e: Edges, c: [number, number], r: number): boolean {
  const { blur, cols, rows } = e;
  const qo = r + INNER_WINDOW + 2;
  const qi = Math.max(0, r - INNER_WINDOW - 2);
  let n = 0;
  let brighter = 0;
  for (let k = 0; k < N_BINS; k++) {
    const uo = Math.floor(c[0] + qo * BIN_COS[k] + 0.5);
    const vo = Math.floor(c[1] + qo * BIN_SIN[k] + 0.5);
    const ui = Math.floor(c[0] + qi * BIN_COS[k] + 0.5);
    const vi = Math.floor(c[1] + qi * BIN_SIN[k] + 0.5);
    if (uo < 0 || uo >= cols || vo < 0 || vo >= rows || ui < 0 || ui >= cols || vi < 0 || vi >= rows) continue;
    n++;
    if (blur[vo * cols + uo] - blur[vi * cols + ui] > INNER_STEP) brighter++;
  }
  return n >= 36 && brighter / n >= INNER_DARK;
}

/** A8: the dark centre's circle of outward edges (found around c, fitted with its own centre), or null. */
function innerCircle(e: Edges, w: InnerSearch): Circle | null {
  const win = INNER_WINDOW;
  const out = hits(e, w.c, w.hi + win, true);
  const r0 = Math.max(w.lo, win + 1);
  const radii = range(Math.max(0, w.hi + 1 - r0)).map((i) => i + r0);
  if (!radii.length) return null;
  const sc = coverage(out.table, w.c, radii, w.cw, w.ch, win).map(
    (v, i) => v / Math.min(1, (2 * Math.PI * radii[i]) / N_BINS),
  );
  const cand: number[] = [];
  for (let i = 0; i < sc.length; i++) {
    const prev = i > 0 ? sc[i - 1] : -1;
    const next = i < sc.length - 1 ? sc[i + 1] : -1;
    if (sc[i] >= MIN_COVERAGE && sc[i] >= prev && sc[i] >= next && darkInside(e, w.c, radii[i])) cand.push(radii[i]);
  }
  if (!cand.length) return null;
  const start = w.start;
  const inside = start === null ? cand : cand.filter((r) => r <= start + w.gap);
  // the largest inside where the scene starts; else (a dim scene's texture starts further out) the smallest
  const r = inside.length ? inside[inside.length - 1] : cand[0];
  const near: number[] = [];
  for (let i = 0; i < e.n; i++) if (out.sel[i] && Math.abs(out.dist[i] - r) <= win + 1) near.push(i);
  return near.length < 20 ? null : fitCircleAlgebraic(e.x, e.y, near);
}

/**
 * A7: the candidate outer circles around centre c with a radius window +-win, smallest radius first
 * (null for a candidate with too few points to fit; a bright rim further out is as complete a
 * circle, but never inside the ring); empty without a ring.
 */
function outerCircles(
  e: Edges,
  c: [number, number],
  rmin: number,
  rmax: number,
  cw: number,
  ch: number,
  win: number,
): (Circle | null)[] {
  const inward = hits(e, c, rmax + win, false);
  const r0 = Math.max(rmin, win + 1);
  const radii = range(Math.max(0, rmax + 1 - r0)).map((i) => i + r0);
  const score = coverage(inward.table, c, radii, cw, ch, win);
  let top = 0;
  for (const v of score) top = Math.max(top, v);
  if (top < MIN_COVERAGE) return [];
  const out: (Circle | null)[] = [];
  let last = -2;
  for (let i = 0; i < score.length; i++) {
    const prev = i > 0 ? score[i - 1] : -1;
    const next = i < score.length - 1 ? score[i + 1] : -1;
    if (!(score[i] >= OUTER_PICK * top && score[i] >= prev && score[i] >= next)) continue;
    const run = last === i - 1; // a plateau's radii are one candidate: its first
    last = i;
    if (run) continue;
    const near: number[] = [];
    for (let j = 0; j < e.n; j++) if (inward.sel[j] && Math.abs(inward.dist[j] - radii[i]) <= win + 1) near.push(j);
    out.push(near.length < 20 ? null : fitCircleAlgebraic(e.x, e.y, near));
  }
  return out;
}

/**
 * A7: the coarse outer circle around the votes' centre c, or null: the first run's candidates in
 * turn, each refined by the second run around its centre, until one gives a circle.
 */
function outerCircle(e: Edges, c: [number, number], rmin: number, rmax: number, cw: number, ch: number): Circle | null {
  const [wide, narrow] = OUTER_WINDOWS;
  for (const circle of outerCircles(e, c, rmin, rmax, cw, ch, wide)) {
    if (!circle) continue;
    const got = outerCircles(e, [circle[0], circle[1]], rmin, rmax, cw, ch, narrow);
    if (got.length && got[0]) return got[0];
  }
  return null;
}

/**
 * B1: the blurred frame, or the window of it around the ring (the rest of a frame is never read):
 * `data` holds a w x h frame's pixels ox .. ox + rw - 1, oy .. oy + rh - 1, of which those within
 * [x0, x1] x [y0, y1] are exactly the whole frame's blur. (The window is copied out first: opencv.js
 * blurs a window in place with other rounding, and as if its edges were the frame's, where the 5x5
 * kernel reaches 2 px across.)
 */
interface Fine {
  data: Uint8Array;
  w: number;
  h: number;
  ox: number;
  oy: number;
  rw: number;
  x0: number;
  y0: number;
  x1: number;
  y1: number;
}

/** A profile reached outside the blurred window: blur the whole frame instead. */
class OutsideWindow extends Error {}

/** B1 on the window of `grey` around a circle (`margin` px beyond it), or on all of it. */
function blurred(cv: RingCv, grey: RingMat, c: Circle | null, margin: number): Fine {
  const w = grey.cols;
  const h = grey.rows;
  let [x0, y0, x1, y1] = [0, 0, w - 1, h - 1];
  if (c) {
    x0 = Math.max(0, Math.floor(c[0] - c[2] - margin));
    y0 = Math.max(0, Math.floor(c[1] - c[2] - margin));
    x1 = Math.min(w - 1, Math.ceil(c[0] + c[2] + margin));
    y1 = Math.min(h - 1, Math.ceil(c[1] + c[2] + margin));
  }
  const K = 2; // the kernel's reach
  const ox = Math.max(0, x0 - K);
  const oy = Math.max(0, y0 - K);
  const rw = Math.min(w - 1, x1 + K) - ox + 1;
  const rh = Math.min(h - 1, y1 + K) - oy + 1;
  const whole = rw === w && rh === h;
  const view = whole ? null : grey.roi(new cv.Rect(ox, oy, rw, rh));
  const win = new cv.Mat();
  const out = new cv.Mat();
  try {
    view?.copyTo(win);
    cv.GaussianBlur(view ? win : grey, out, new cv.Size(5, 5), FINE_SIGMA, FINE_SIGMA, cv.BORDER_DEFAULT);
    return { data: out.data.slice(), w, h, ox, oy, rw, x0, y0, x1, y1 };
  } finally {
    for (const m of [view, win, out]) m?.delete();
  }
}

/**
 * B2: the sub-pixel edge on each radial profile across a circle; -> its points and the number of
 * profiles inside the image. sign -1: darker outwards (outer edge), +1: brighter outwards.
 */
function edgePoints(
  fine: Fine,
  center: [number, number],
  radius: number,
  sign: number,
  half: number,
): { xs: Float64Array; ys: Float64Array; nIn: number } {
  const { w, h, ox, oy, rw, data } = fine;
  const nS = Math.round((2 * half) / PROFILE_STEP) + 1;
  const prof = new Float64Array(nS);
  const e = new Float64Array(nS - 2);
  const xs: number[] = [];
  const ys: number[] = [];
  let nIn = 0;
  const [cos, sin] = unitCircle(N_PROFILES, false);
  for (let k = 0; k < N_PROFILES; k++) {
    const ct = cos[k];
    const st = sin[k];
    let inside = true;
    for (let j = 0; j < nS && inside; j++) {
      const x = center[0] + (radius + (-half + PROFILE_STEP * j)) * ct;
      const y = center[1] + (radius + (-half + PROFILE_STEP * j)) * st;
      if (!(x >= 0 && x <= w - 1 && y >= 0 && y <= h - 1)) inside = false;
      else {
        const x0 = Math.min(Math.max(Math.floor(x), 0), w - 2);
        const y0 = Math.min(Math.max(Math.floor(y), 0), h - 2);
        const fx = x - x0;
        const fy = y - y0;
        if (x0 < fine.x0 || y0 < fine.y0 || x0 + 1 > fine.x1 || y0 + 1 > fine.y1) throw new OutsideWindow();
        const p = (y0 - oy) * rw + (x0 - ox);
        prof[j] =
          (data[p] * (1 - fx) + data[p + 1] * fx) * (1 - fy) + (data[p + rw] * (1 - fx) + data[p + rw + 1] * fx) * fy;
      }
    }
    if (!inside) continue;
    nIn++;
    let jj = 0;
    for (let j = 0; j < nS - 2; j++) {
      e[j] = (sign * (prof[j + 2] - prof[j])) / (2 * PROFILE_STEP);
      if (e[j] > e[jj]) jj = j;
    }
    if (!(e[jj] >= MIN_EDGE && jj >= 1 && jj <= nS - 4)) continue;
    const [a, b, c] = [e[jj - 1], e[jj], e[jj + 1]];
    const den = a - 2 * b + c;
    const delta = Math.min(0.5, Math.max(-0.5, den < 0 ? (0.5 * (a - c)) / den : 0));
    const r = radius + (-half + PROFILE_STEP * (jj + 1)) + PROFILE_STEP * delta;
    xs.push(center[0] + r * ct);
    ys.push(center[1] + r * st);
  }
  return { xs: Float64Array.from(xs), ys: Float64Array.from(ys), nIn };
}

/** B2-B4 for the outer circle, or null. */
function refineOuter(fine: Fine, circle: Circle, sign: number): Circle | null {
  for (const half of [6, 3]) {
    const { xs, ys, nIn } = edgePoints(fine, [circle[0], circle[1]], circle[2], sign, half);
    if (nIn === 0 || xs.length < 20 || xs.length < MIN_SHARE * nIn) return null;
    const [c, keep] = fitRobust(xs, ys);
    if (keep.length < Math.max(20, MIN_SHARE * nIn)) return null;
    circle = c;
  }
  return circle;
}

/**
 * B5: the radius of the dark centre's own circle, from A8's circle `start`, or 0 without an inner
 * edge (or one further than INNER_OFFSET of its radius from the ring's `center`).
 */
function refineInner(fine: Fine, center: [number, number], start: Circle): number {
  let c: [number, number] = [start[0], start[1]];
  let r = start[2];
  for (const half of [6, 3]) {
    const { xs, ys, nIn } = edgePoints(fine, c, r, 1, half);
    if (nIn === 0 || xs.length < 20 || xs.length < MIN_SHARE * nIn) return 0;
    const [[cx, cy, rr], keep] = fitRobust(xs, ys);
    // (a NaN fit gives none)
    if (keep.length < Math.max(20, MIN_SHARE * nIn) || !(dist(cx - center[0], cy - center[1]) <= INNER_OFFSET * rr))
      return 0;
    [c, r] = [[cx, cy], rr];
  }
  return r;
}

/**
 * The ring in one frame (RGBA pixels, width x height), or null when it shows none (no lens, a
 * covered lens, an ordinary photo). Full-resolution pixels; ring.py's find_ring_frame.
 */
export function findRingFrame(
  cv: RingCv,
  rgba: Uint8Array | Uint8ClampedArray,
  width: number,
  height: number,
): Ring | null {
  if (Math.min(width, height) < MIN_SIDE) return null;
  const src = new cv.Mat(height, width, cv.CV_8UC4);
  const grey = new cv.Mat();
  try {
    src.data.set(rgba);
    cv.cvtColor(src, grey, cv.COLOR_RGBA2GRAY, 0);
    const coarse = coarseRing(cv, grey);
    if (!coarse) return null;
    const {
      center: [a, b],
      rInner: ri,
      rOuter: ro,
      scale: [sx, sy],
    } = coarse;
    const s = 0.5 * (sx + sy);
    const start: Circle = [(a + 0.5) / sx - 0.5, (b + 0.5) / sy - 0.5, ro / s];
    // B2-B5 read the frame near the coarse circle only: blur that window (a 1920x1080 frame's
    // blur is the slowest step), or the whole frame should a profile reach further
    const refine = (fine: Fine): [Circle | null, number] => {
      const outer = refineOuter(fine, start, coarse.outerSign);
      const ic = coarse.innerCenter;
      const inner: Circle | null = ic && ri > 0 ? [(ic[0] + 0.5) / sx - 0.5, (ic[1] + 0.5) / sy - 0.5, ri / s] : null;
      return [outer, outer && inner ? refineInner(fine, [outer[0], outer[1]], inner) : 0];
    };
    let got: [Circle | null, number];
    try {
      got = refine(blurred(cv, grey, start, WINDOW_MARGIN + 2 / s));
    } catch (e) {
      if (!(e instanceof OutsideWindow)) throw e;
      got = refine(blurred(cv, grey, null, 0));
    }
    const [outer, rInner] = got;
    if (!outer) return null;
    const [cx, cy] = outer;
    const rOut = outer[2] - EDGE_BIAS_PX;
    let rIn = rInner;
    if (rIn > 0) rIn += EDGE_BIAS_PX;
    return {
      image_size: [width, height],
      center: [cx, cy],
      r_inner: rIn,
      r_outer: rOut,
      visible: visibleShare([cx, cy], rOut, width, height),
      surround: coarse.outerSign > 0 ? 'brighter' : 'darker',
      housing: coarse.housing / s,
      texture_ratio: coarse.textureRatio,
    };
  } finally {
    for (const m of [src, grey]) m.delete();
  }
}

/**
 * C: the median ring over frames (r_inner over the frames that saw an inner edge, 0 when fewer than
 * half of them did); null when fewer than half of the frames show a ring.
 */
export function medianRing(rings: (Ring | null)[]): Ring | null {
  const found = rings.filter((r): r is Ring => r !== null);
  if (!found.length || found.length * 2 < rings.length) return null;
  // the majority by whether A9 took a circle for the housing: the two kinds see different circles
  const housed = found.filter((r) => (r.housing ?? 0) > 0);
  const major = found.filter((r) => (r.housing ?? 0) > 0 === 2 * housed.length > found.length);
  const center: [number, number] = [median(major.map((r) => r.center[0])), median(major.map((r) => r.center[1]))];
  const r_outer = median(major.map((r) => r.r_outer));
  const inner = major.map((r) => r.r_inner).filter((r) => r > 0);
  const [w, h] = found[0].image_size;
  return {
    image_size: [w, h],
    center,
    r_inner: 2 * inner.length >= major.length ? median(inner) : 0,
    r_outer,
    visible: visibleShare(center, r_outer, w, h),
    frames_used: found.length,
    frames_total: rings.length,
    surround: 2 * major.filter((r) => r.surround === 'brighter').length > major.length ? 'brighter' : 'darker',
    housing: 2 * housed.length > found.length ? median(housed.map((r) => r.housing!)) : 0,
    texture_ratio: median(major.map((r) => r.texture_ratio ?? 0)),
  };
}

/** What a ring says about a lens profile (lens_fit.py's `LensFit`). */
export type Verdict = 'same' | 'corrected' | 'too_far' | 'cut' | 'no_ring';
export interface LensFit {
  verdict: Verdict;
  /** The corrected profile when "corrected", else the profile unchanged. */
  lens: CatadioptricLens;
  dx: number;
  dy: number;
  scale: number;
  moved_px: number;
  /** The verdict in words, one line (ring.py's). */
  message: string;
}

// issue 12's decisions, as ring.py has them
export const STILL_PX: number = C.STILL_PX;
export const STILL_SCALE: number = C.STILL_SCALE;
export const TOO_FAR_SHARE: number = C.TOO_FAR_SHARE;
export const CUT_MARGIN: number = C.CUT_MARGIN;

/** "moved 6.2 px (right 5.0, down 3.7) and is 0.4 % larger" (lens_fit.py's _moved_words). */
function movedWords(dx: number, dy: number, s: number): string {
  const parts: string[] = [];
  if (Math.abs(dx) >= 0.05) parts.push(`${dx > 0 ? 'right' : 'left'} ${Math.abs(dx).toFixed(1)}`);
  if (Math.abs(dy) >= 0.05) parts.push(`${dy > 0 ? 'down' : 'up'} ${Math.abs(dy).toFixed(1)}`);
  const where = parts.length ? ` (${parts.join(', ')})` : '';
  const pct = (s - 1) * 100;
  const size =
    Math.abs(pct) < 0.05 ? 'the same size' : `${Math.abs(pct).toFixed(1)} % ${pct > 0 ? 'larger' : 'smaller'}`;
  return `moved ${Math.hypot(dx, dy).toFixed(1)} px${where} and is ${size}`;
}

/** The profile for a ring moved by d and s times larger: elevation(r) -> elevation(r / s), a sensor's unit scaled too. */
export function scaledLens(lens: CatadioptricLens, d: [number, number], s: number): CatadioptricLens {
  const out: CatadioptricLens = {
    ...lens,
    center: [lens.center[0] + d[0], lens.center[1] + d[1]],
    r_inner: lens.r_inner * s,
    r_outer: lens.r_outer * s,
    elevation_poly: lens.elevation_poly.map((c, k) => c / s ** k),
  };
  if (lens.ring)
    out.ring = {
      center: [lens.ring.center[0] + d[0], lens.ring.center[1] + d[1]],
      r_inner: lens.ring.r_inner * s,
      r_outer: lens.ring.r_outer * s,
    };
  if (lens.sensor) out.sensor = { ...lens.sensor, scale: lens.sensor.scale * s };
  return out;
}

/**
 * Does the profile fit the ring the frames show (lens_fit.py's fit_lens)? Compared with the ring the
 * profile was made with (`lens.ring`, else its centre and radii): d = centre moved, s = outer
 * radius now / then; cut, too far (10 %), the same (under 0.25 px and 0.2 %), else corrected.
 */
export function fitLens(lens: CatadioptricLens, ring: Ring | null): LensFit {
  const keep = (verdict: Verdict, dx: number, dy: number, scale: number, message: string): LensFit => ({
    verdict,
    lens,
    dx,
    dy,
    scale,
    moved_px: Math.hypot(dx, dy),
    message,
  });
  if (!ring) return keep('no_ring', 0, 0, 1, 'The panoramic lens does not seem to be attached');
  const [w, h] = lens.image_size;
  if (ring.image_size[0] !== w || ring.image_size[1] !== h)
    throw new Error(
      `the frames are ${ring.image_size[0]}x${ring.image_size[1]} but the lens profile is for ${w}x${h}: film at the profile's resolution`,
    );
  const ref = lens.ring ?? { center: lens.center, r_inner: lens.r_inner, r_outer: lens.r_outer };
  const dx = ring.center[0] - ref.center[0];
  const dy = ring.center[1] - ref.center[1];
  const s = ring.r_outer / ref.r_outer;
  const moved = Math.hypot(dx, dy);
  const words = movedWords(dx, dy, s);
  const visRef = visibleShare(lens.center, lens.r_outer, w, h);
  const visNow = visibleShare([lens.center[0] + dx, lens.center[1] + dy], lens.r_outer * s, w, h);
  if (visNow < visRef - CUT_MARGIN)
    return keep('cut', dx, dy, s, `The lens is not centred over the camera; clip it on again (ring ${words})`);
  if (moved > TOO_FAR_SHARE * ref.r_outer || Math.abs(s - 1) > TOO_FAR_SHARE)
    return keep(
      'too_far',
      dx,
      dy,
      s,
      `The lens ring ${words}: too far from the profile to correct; clip the lens on again or calibrate it (omninav calib lens)`,
    );
  if (moved < STILL_PX && Math.abs(s - 1) < STILL_SCALE)
    return keep('same', dx, dy, s, `The lens ring is where the profile expects it (${words})`);
  return {
    verdict: 'corrected',
    lens: scaledLens(lens, [dx, dy], s),
    dx,
    dy,
    scale: s,
    moved_px: moved,
    message: `The lens ring ${words}: corrected`,
  };
}

/**
 * The picture's look (protocol.ts `Look`) from RGBA pixels: the mean grey over a sparse grid, and
 * the mean step across the profile's outer ring edge at 90 angles (a few pixels either side).
 */
export function lookOf(rgba: Uint8Array | Uint8ClampedArray, w: number, h: number, lens: Lens): Look {
  const grey = (x: number, y: number) => {
    const p = 4 * (Math.round(y) * w + Math.round(x));
    return (77 * rgba[p] + 150 * rgba[p + 1] + 29 * rgba[p + 2]) / 256;
  };
  let sum = 0;
  let n = 0;
  const step = Math.max(1, Math.round(Math.sqrt((w * h) / 20000)));
  for (let y = step >> 1; y < h; y += step)
    for (let x = step >> 1; x < w; x += step) {
      sum += grey(x, y);
      n++;
    }
  if (lens.model !== 'catadioptric') return { mean: sum / n, edge: NaN };
  const ring = lens.ring ?? { center: lens.center, r_outer: lens.r_outer };
  const off = Math.max(3, 0.03 * ring.r_outer);
  let edge = 0;
  let m = 0;
  for (let i = 0; i < 90; i++) {
    const a = (2 * Math.PI * i) / 90;
    const [c, s] = [Math.cos(a), Math.sin(a)];
    const xi = ring.center[0] + (ring.r_outer - off) * c;
    const yi = ring.center[1] + (ring.r_outer - off) * s;
    const xo = ring.center[0] + (ring.r_outer + off) * c;
    const yo = ring.center[1] + (ring.r_outer + off) * s;
    if (Math.min(xi, yi, xo, yo) < 0 || Math.max(xi, xo) > w - 1 || Math.max(yi, yo) > h - 1) continue;
    edge += grey(xi, yi) - grey(xo, yo);
    m++;
  }
  return { mean: sum / n, edge: m ? edge / m : NaN };
}
