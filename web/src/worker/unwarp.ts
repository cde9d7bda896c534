/**
 * Unwarp tables (the paper's Eq. 1), as the engine's unwarp.py builds them: rows are elevations,
 * columns azimuths; cv.remap in the worker then reads the band panorama through them.
 */
import { directionToPixel, linspace, radiusTable, type Lens } from '../shared/lens';

/** Remap tables (float32, rows x cols), the rows' elevations, and which directions the lens sees. */
export interface UnwarpMap {
  rows: number;
  cols: number;
  mapX: Float32Array;
  mapY: Float32Array;
  elevations: Float64Array;
  valid: Uint8Array;
  /** OpenCV border mode: constant (black) outside the donut, wrap across a 360-camera's seam. */
  wrap: boolean;
}

/** Elevations of the panorama's rows, top (highest) first (unwarp.panorama_elevations). */
export function panoramaElevations(top: number, bottom: number, step: number): Float64Array {
  return linspace(top, bottom, Math.round((top - bottom) / step) + 1);
}

/** The remap tables for a panorama of `width` columns; column j looks at azimuth (j + 0.5) * 360 / width. */
export function buildMap(lens: Lens, elevations: Float64Array, width: number): UnwarpMap {
  const rows = elevations.length;
  const mapX = new Float32Array(rows * width);
  const mapY = new Float32Array(rows * width);
  const valid = new Uint8Array(rows * width);
  const radius = lens.model === 'catadioptric' ? radiusTable(lens) : null;
  for (let i = 0; i < rows; i++) {
    for (let j = 0; j < width; j++) {
      const az = ((j + 0.5) * 360) / width;
      const [x, y] = directionToPixel(lens, radius, az, elevations[i]);
      const ok = Number.isFinite(x) && Number.isFinite(y);
      const k = i * width + j;
      valid[k] = ok ? 1 : 0;
      // unseen directions read a pixel outside the image, which the constant border makes black
      mapX[k] = ok ? x : -10;
      mapY[k] = ok ? y : -10;
    }
  }
  return { rows, cols: width, mapX, mapY, elevations, valid, wrap: lens.model !== 'catadioptric' };
}

/** The remap a feature preset needs: the rows of all its bands, at `oversample` x the columns. */
export function bandMap(
  lens: Lens,
  s: { bands: [number, number][]; row_step_deg: number; pano_width: number; oversample: number },
): UnwarpMap {
  const lo = Math.min(...s.bands.map((b) => b[0]));
  const hi = Math.max(...s.bands.map((b) => b[1]));
  return buildMap(lens, panoramaElevations(hi, lo, s.row_step_deg), s.pano_width * s.oversample);
}
