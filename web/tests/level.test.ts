// Levelling's small parts (worker/level.ts); the whole of it is checked against the engine's
// golden frames in golden.test.ts (the donut-tilted case).
import { describe, expect, it } from 'vitest';
import { addLean, leanTilt, percentile, tiltRotation } from '../src/worker/level';

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
