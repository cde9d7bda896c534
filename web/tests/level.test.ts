// Levelling's small parts (worker/level.ts); the whole of it is checked against the engine's
// golden frames in golden.test.ts (the donut-tilted case).
import { describe, expect, it } from 'vitest';
import {
  ANCHOR_DEG,
  addLean,
  anchorStep,
  leanTilt,
  percentile,
  radiusAt,
  radiusTableOf,
  tiltedMap,
  tiltRotation,
} from '../src/worker/level';
import { bandMap } from '../src/worker/unwarp';
import { directionToPixel, radiusTable, type CatadioptricLens, type Lens } from '../src/shared/lens';

/** numpy.percentile (linear) by sorting, as a reference. */
function sorted(v: number[], q: number): number {
  const s = [...v].sort((a, b) => a - b);
  const pos = (s.length - 1) * (q / 100);
  const lo = Math.floor(pos);
  const hi = Math.min(lo + 1, s.length - 1);
  return s[lo] + (s[hi] - s[lo]) * (pos - lo);
}

describe('levelling', () => {
  it('finds the percentile by selection, as sorting would, ties and all', () => {
    let seed = 7;
    const rand = () => ((seed = (seed * 16807) % 2147483647) / 2147483647) * 100;
    for (const n of [1, 2, 3, 10, 11, 1000, 4097]) {
      const v = Array.from({ length: n }, () => Math.floor(rand() / 7)); // many ties
      for (const q of [0, 50, 90, 100]) expect(percentile(Float64Array.from(v), q)).toBeCloseTo(sorted(v, q), 12);
    }
  });

  it('turns the lens axis by the tilt towards its azimuth, and nothing else', () => {
    const r = tiltRotation(6, 90); // towards the right (camera azimuth 90)
    // orthonormal
    for (let i = 0; i < 3; i++)
      for (let j = 0; j < 3; j++) {
        const dot = r[i] * r[j] + r[3 + i] * r[3 + j] + r[6 + i] * r[6 + j];
        expect(dot).toBeCloseTo(i === j ? 1 : 0, 12);
      }
    // the up axis (0, 0, 1) leans 6 degrees, sideways (towards azimuth 90); forward is the axis turned about
    expect(Math.acos(r[8]) * (180 / Math.PI)).toBeCloseTo(6, 10);
    expect(Math.abs(r[5])).toBeCloseTo(Math.sin((6 * Math.PI) / 180), 12);
    [r[0], r[3], r[6]].forEach((v, i) => expect(v).toBeCloseTo(i === 0 ? 1 : 0, 12));
  });

  it('adds passes as vectors and caps the tilt', () => {
    const { tilt, toward } = leanTilt(Math.sin(0.1), 0);
    expect(tilt).toBeCloseTo((Math.sin(0.1) * 180) / Math.PI, 12);
    expect(toward).toBeCloseTo(0, 12);
    const v = addLean([3, 0], 0, -((3 * Math.PI) / 180)); // a pass leaning 3 degrees towards 90
    expect(v[0]).toBeCloseTo(3, 12);
    expect(v[1]).toBeCloseTo(3, 12);
    const big = addLean([0, 0], 1, 0); // 57 degrees: capped at 15
    expect(Math.hypot(...big)).toBeCloseTo(15, 12);
  });
});

describe('the radius lookup', () => {
  const donut = (poly: number[]): CatadioptricLens => ({
    model: 'catadioptric',
    image_size: [960, 720],
    center: [480, 360],
    r_inner: 100,
    r_outer: 340,
    elevation_poly: poly,
  });
  // the golden donut's, one far from linear, one falling with the radius
  for (const poly of [
    [-72.98732458125852, 0.24373019465821674, 0.0002172928927116338],
    [-90, 0.05, 0.0015, -1e-6],
    [40, -0.3],
  ])
    it(`finds numpy.interp's value of the radius table, bucketed (degree ${poly.length - 1})`, () => {
      const lens = donut(poly);
      const want = radiusTable(lens);
      const t = radiusTableOf(lens);
      expect(t.start).not.toBeNull();
      const n = t.r.length;
      const xs: number[] = [t.e[0] - 1, t.e[n - 1] + 1, NaN];
      for (let i = 0; i < n; i++) xs.push(t.e[i], (t.e[i] + (t.e[i + 1] ?? t.e[i])) / 2);
      let seed = 9;
      for (let i = 0; i < 20_000; i++)
        xs.push(t.e[0] + ((seed = (seed * 16807) % 2147483647) / 2147483647) * (t.e[n - 1] - t.e[0]));
      for (const x of xs)
        expect(Object.is(radiusAt(t, x), want(x)) || radiusAt(t, x) === want(x), `at ${x}`).toBe(true);
    });
});

describe('the tilted map', () => {
  // tiltInto takes a donut's pixel from the turned direction's horizontal components, without
  // atan2, cos and sin: the same tables as its azimuth and elevation give, through directionToPixel,
  // at every anchor column (ANCHOR_DEG apart); the columns between them within 0.08 px of it
  const lenses: Lens[] = [
    {
      model: 'catadioptric',
      image_size: [960, 720],
      center: [487, 352],
      r_inner: 105,
      r_outer: 340,
      elevation_poly: [-72.98732458125852, 0.24373019465821674, 0.0002172928927116338],
      forward_deg: 90,
      ccw: true,
    },
    { model: 'equirectangular', image_size: [1440, 720], forward_x: 360 },
  ];
  for (const lens of lenses)
    for (const oversample of [1, 2, 4])
      it(`is directionToPixel of the turned directions (${lens.model}, ${oversample} columns a degree)`, () => {
        const upright = bandMap(lens, { bands: [[-30, 30]], row_step_deg: 1, pano_width: 360, oversample });
        const step = anchorStep(upright.cols);
        expect(step).toBe(ANCHOR_DEG * oversample);
        const radius = lens.model === 'catadioptric' ? radiusTable(lens) : null;
        for (const [tilt, toward] of [
          [2, 10],
          [6, 135],
          [12, 260],
        ]) {
          const rot = tiltRotation(tilt, toward);
          const m = tiltedMap(lens, upright, rot);
          let worst = 0;
          let between = 0;
          for (let i = 0, k = 0; i < upright.rows; i++)
            for (let j = 0; j < upright.cols; j++, k++) {
              const el = (Math.fround(upright.elevations[i]) * Math.PI) / 180;
              const az = ((((j + 0.5) * 360) / upright.cols) * Math.PI) / 180;
              const w = [Math.cos(el) * Math.cos(az), Math.cos(el) * Math.sin(az), Math.sin(el)];
              const c = [0, 1, 2].map((q) => w[0] * rot[q] + w[1] * rot[3 + q] + w[2] * rot[6 + q]);
              const azc = ((Math.atan2(c[1], c[0]) * 180) / Math.PI + 360) % 360;
              const [x, y] = directionToPixel(lens, radius, azc, (Math.asin(c[2]) * 180) / Math.PI);
              const off = Math.max(Math.abs(m.mapX[k] - x), Math.abs(m.mapY[k] - y));
              if (!(Number.isFinite(x) && Number.isFinite(y)))
                expect([m.mapX[k], m.mapY[k]]).toEqual([upright.mapX[k], upright.mapY[k]]);
              else if (j % step === 0) worst = Math.max(worst, off);
              else between = Math.max(between, off);
            }
          expect(worst).toBeLessThan(1e-3);
          expect(between).toBeLessThan(0.08);
          // the ring's bend between anchors shows (a 360 camera's columns are nearly linear)
          if (lens.model === 'catadioptric') expect(between).toBeGreaterThan(5e-3);
        }
      });
});
