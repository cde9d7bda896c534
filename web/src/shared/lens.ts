/**
 * Lens profiles (docs/formats.md `lens.json`): which camera pixel looks in which direction, computed
 * exactly as the engine's lens.py does (NumPy's linspace, interp and polyval included).
 */
import LIMITS from '../../../backend/omninav/sensor_limits.json';

export interface CatadioptricLens {
  model: 'catadioptric';
  image_size: [number, number];
  center: [number, number];
  r_inner: number;
  r_outer: number;
  elevation_poly: number[];
  forward_deg?: number;
  ccw?: boolean;
  /**
   * The ring's visible edges as `omninav calib` measured them when the profile was made; a
   * re-clipped lens is corrected by how far the ring moved from these. Absent: the ring is
   * `center`, `r_inner`, `r_outer` (hand-typed and rendered profiles).
   */
  ring?: { center: [number, number]; r_inner: number; r_outer: number };
  /**
   * A real mirror's departure from radial symmetry (lens.py `Sensor`): the symmetric offset o from
   * `center` is seen at center + matrix (o + scale t(o / scale)), t the decentring term.
   */
  sensor?: LensSensor;
}

export interface LensSensor {
  matrix: [[number, number], [number, number]];
  tangential: [number, number];
  scale: number;
}

export interface EquirectangularLens {
  model: 'equirectangular';
  image_size: [number, number];
  forward_x: number;
  ccw?: boolean;
}

export type Lens = CatadioptricLens | EquirectangularLens;

/** numpy.linspace: start + i * step, the last value exactly `stop`. */
export function linspace(start: number, stop: number, n: number): Float64Array {
  const out = new Float64Array(n);
  const step = n > 1 ? (stop - start) / (n - 1) : 0;
  for (let i = 0; i < n; i++) out[i] = start + i * step;
  if (n > 1) out[n - 1] = stop;
  return out;
}

/** Polynomial in ascending powers, by Horner's rule (numpy.polynomial.polynomial.polyval). */
export function polyval(x: number, c: readonly number[]): number {
  let v = c[c.length - 1];
  for (let i = c.length - 2; i >= 0; i--) v = c[i] + v * x;
  return v;
}

/** numpy.interp with left = right = NaN; `xp` ascending. */
export function interp(x: number, xp: Float64Array, fp: Float64Array): number {
  const n = xp.length;
  if (!(x >= xp[0] && x <= xp[n - 1])) return NaN;
  if (x === xp[n - 1]) return fp[n - 1];
  let lo = 0;
  let hi = n - 1;
  while (hi - lo > 1) {
    const mid = (lo + hi) >> 1;
    if (xp[mid] <= x) lo = mid;
    else hi = mid;
  }
  const slope = (fp[lo + 1] - fp[lo]) / (xp[lo + 1] - xp[lo]);
  return slope * (x - xp[lo]) + fp[lo];
}

/** 4097 radii across a donut's ring and the elevation each sees, elevations ascending (lens.py's table). */
export function elevationSamples(lens: CatadioptricLens): { r: Float64Array; e: Float64Array } {
  const n = 4097;
  let r = linspace(lens.r_inner, lens.r_outer, n);
  let e = r.map((v) => polyval(v, lens.elevation_poly));
  if (e[0] > e[n - 1]) {
    r = r.slice().reverse();
    e = e.slice().reverse();
  }
  return { r, e };
}

/** The radius (px) at which a donut lens sees each elevation; NaN outside its ring. */
export function radiusTable(lens: CatadioptricLens): (elevDeg: number) => number {
  const { r, e } = elevationSamples(lens);
  return (el) => interp(el, e, r);
}

/**
 * Offsets from the centre of the pixel that sees the symmetric offset (ox, oy): lens.py's
 * Sensor.to_pixel, the same operations in the same order (the panoramas match to the byte).
 */
export function sensorOffsets(sensor: LensSensor, ox: number, oy: number): [number, number] {
  const out = [0, 0];
  sensorInto(sensor, ox, oy, out, 0);
  return [out[0], out[1]];
}

/** sensorOffsets into out[at], out[at + 1], allocating nothing (levelling's turned maps). */
export function sensorInto(sensor: LensSensor, ox: number, oy: number, out: { [i: number]: number }, at: number): void {
  const [[m00, m01], [m10, m11]] = sensor.matrix;
  const [p1, p2] = sensor.tangential;
  const s = sensor.scale;
  const xn = ox / s;
  const yn = oy / s;
  const q = xn * xn + yn * yn;
  const ux = ox + s * (2.0 * p1 * xn * yn + p2 * (q + 2.0 * xn * xn));
  const uy = oy + s * (p1 * (q + 2.0 * yn * yn) + 2.0 * p2 * xn * yn);
  out[at] = m00 * ux + m01 * uy;
  out[at + 1] = m10 * ux + m11 * uy;
}

/** The pixel (x, y) of a donut lens that sees the symmetric offset (ox, oy) from its centre. */
export function donutPixel(lens: CatadioptricLens, ox: number, oy: number): [number, number] {
  if (!lens.sensor) return [lens.center[0] + ox, lens.center[1] + oy];
  const [sx, sy] = sensorOffsets(lens.sensor, ox, oy);
  return [lens.center[0] + sx, lens.center[1] + sy];
}

/** Pixel (x, y) that sees (azimuth clockwise from forward, elevation), in degrees. */
export function directionToPixel(
  lens: Lens,
  radius: ((el: number) => number) | null,
  az: number,
  el: number,
): [number, number] {
  const sign = (lens.ccw ?? lens.model === 'catadioptric') ? -1 : 1; // donuts default to ccw
  if (lens.model === 'catadioptric') {
    const r = radius!(el);
    const phi = (((lens.forward_deg ?? 0) + sign * az) * Math.PI) / 180;
    return donutPixel(lens, r * Math.cos(phi), r * Math.sin(phi));
  }
  const [w, h] = lens.image_size;
  const a = lens.forward_x + (sign * az * w) / 360;
  const x = a - Math.floor(a / w) * w; // numpy.mod: the result takes the divisor's sign
  return [x, ((90 - el) * h) / 180 - 0.5];
}

const finite = (v: unknown): v is number => typeof v === 'number' && Number.isFinite(v);

/** lens.py's _sensor: a matrix near the identity and a small decentring (sensor_limits.json). */
function sensorOk(v: unknown): boolean {
  if (typeof v !== 'object' || v === null) return false;
  const { matrix: m, tangential: p, scale } = v as Record<string, unknown>;
  const pair = (r: unknown): r is [number, number] => Array.isArray(r) && r.length === 2 && r.every(finite);
  if (!(Array.isArray(m) && m.length === 2 && m.every(pair) && pair(p) && finite(scale))) return false;
  const [[a, b], [c, d]] = m as [number, number][];
  const det = a * d - b * c;
  const [lo, hi] = LIMITS.DETERMINANT;
  return (
    scale > 0 &&
    det > lo &&
    det < hi &&
    Math.max(Math.abs(b), Math.abs(c)) < LIMITS.MAX_SKEW &&
    Math.max(Math.abs(p[0]), Math.abs(p[1])) <= LIMITS.MAX_DECENTRING
  );
}

/** Why a lens profile cannot be used, or null when it can (the server validates it fully). */
export function lensProblem(lens: unknown): string | null {
  if (typeof lens !== 'object' || lens === null) return 'the lens profile is not an object';
  const l = lens as Record<string, unknown>;
  const size = l.image_size;
  if (!Array.isArray(size) || size.length !== 2 || !size.every((v) => Number.isInteger(v) && v > 0))
    return "the lens profile's image_size must be [width, height]";
  if (l.model === 'catadioptric') {
    if (!Array.isArray(l.center) || l.center.length !== 2 || !l.center.every(finite))
      return 'its center must be [x, y]';
    if (!Array.isArray(l.elevation_poly) || !l.elevation_poly.length || !l.elevation_poly.every(finite))
      return 'its elevation_poly must be a list of numbers';
    if (
      !finite(l.r_inner) ||
      !finite(l.r_outer) ||
      !((l.r_inner as number) >= 0 && (l.r_inner as number) < (l.r_outer as number))
    )
      return 'it needs 0 <= r_inner < r_outer';
    if (l.ring !== undefined) {
      const r = l.ring as Record<string, unknown> | null;
      const ok =
        r !== null &&
        typeof r === 'object' &&
        Array.isArray(r.center) &&
        r.center.length === 2 &&
        r.center.every(finite) &&
        finite(r.r_inner) &&
        finite(r.r_outer) &&
        (r.r_inner as number) >= 0 &&
        (r.r_inner as number) < (r.r_outer as number);
      if (!ok) return 'its ring must be {"center": [x, y], "r_inner": r, "r_outer": R} with 0 <= r < R';
    }
    if (l.sensor !== undefined && l.sensor !== null && !sensorOk(l.sensor))
      return `its sensor must be {"matrix": [[a, b], [c, d]], "tangential": [p1, p2], "scale": s} (near the identity, |p| <= ${LIMITS.MAX_DECENTRING})`;
    return null;
  }
  if (l.model === 'equirectangular')
    return typeof l.forward_x === 'number' ? null : 'the 360 lens profile lacks forward_x';
  return `unknown lens model ${String(l.model)}`;
}
