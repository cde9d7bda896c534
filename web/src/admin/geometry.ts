/**
 * Plan geometry without Leaflet (so it is unit-tested in Node): metres <-> the map's CRS.Simple
 * coordinates, metres <-> plan pixels, the scale from two points, and a scale bar's length.
 * Everything the admin page stores is in plan metres (docs/formats.md): x to the right, y down.
 */

/** A map coordinate of L.CRS.Simple: lat = -y_m, lng = x_m (y grows down the plan, lat up). */
export interface MapPoint {
  lat: number;
  lng: number;
}

export interface Metres {
  x: number;
  y: number;
}

export const toMap = (x: number, y: number): MapPoint => ({ lat: -y, lng: x });

export const fromMap = (p: MapPoint): Metres => ({ x: p.lng, y: -p.lat });

/** Plan pixels -> metres at `pxPerM` (1 before a scale is set: metres are then pixels). */
export const pxToMetres = (px: readonly [number, number], pxPerM: number): Metres => ({
  x: px[0] / pxPerM,
  y: px[1] / pxPerM,
});

export const metresToPx = (m: Metres, pxPerM: number): [number, number] => [m.x * pxPerM, m.y * pxPerM];

/** The plan image's bounds on the map, [[south, west], [north, east]], for a w x h pixel plan. */
export function planBounds(sizePx: readonly [number, number], pxPerM: number): [[number, number], [number, number]] {
  return [
    [-sizePx[1] / pxPerM, 0],
    [0, sizePx[0] / pxPerM],
  ];
}

/** Pixels per metre from two plan points (in pixels) and the distance between them in metres. */
export function scaleFromPoints(a: readonly [number, number], b: readonly [number, number], distanceM: number): number {
  const d = Math.hypot(b[0] - a[0], b[1] - a[1]);
  if (!(distanceM > 0) || !Number.isFinite(distanceM)) throw new RangeError('the distance must be more than 0 m');
  if (!(d > 0)) throw new RangeError('the two points are the same point: pick two points apart');
  return d / distanceM;
}

/** Distance between two points, in their unit. */
export const distance = (a: Metres, b: Metres): number => Math.hypot(b.x - a.x, b.y - a.y);

/**
 * The longest "round" length (1, 2 or 5 times a power of ten) that fits in `maxPx` screen pixels
 * when one unit is `pxPerUnit` screen pixels: the scale bar's length, in units, and its width.
 */
export function scaleBar(pxPerUnit: number, maxPx = 120): { length: number; px: number } {
  const most = maxPx / pxPerUnit;
  const pow = 10 ** Math.floor(Math.log10(most));
  const length = [5, 2, 1].map((k) => k * pow).find((l) => l <= most) ?? pow;
  return { length, px: length * pxPerUnit };
}

/** "50 m", "2 m", "0.5 m" (a scale bar's or a distance's label). */
export function metresLabel(m: number): string {
  if (m >= 1000) return `${+(m / 1000).toPrecision(3)} km`;
  return `${+m.toPrecision(3)} m`;
}

/** A rectangle from two corners in any order, as [x0, y0, x1, y1] with x0 < x1 and y0 < y1. */
export function areaOf(a: Metres, b: Metres): [number, number, number, number] {
  return [Math.min(a.x, b.x), Math.min(a.y, b.y), Math.max(a.x, b.x), Math.max(a.y, b.y)];
}

/** Whether a point (metres) lies in an area [x0, y0, x1, y1] (its corners in any order), edges included. */
export function inArea(area: readonly [number, number, number, number], x: number, y: number): boolean {
  const [x0, y0, x1, y1] = area;
  return x >= Math.min(x0, x1) && x <= Math.max(x0, x1) && y >= Math.min(y0, y1) && y <= Math.max(y0, y1);
}

/** Round to centimetres for display and storage of typed-in or dragged values. */
export const cm = (v: number): number => Math.round(v * 100) / 100;
