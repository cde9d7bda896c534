import { describe, expect, it } from 'vitest';
import {
  HEADER_AT,
  HEADER_BYTES,
  encodeRecord,
  fromHalf,
  recordFrame,
  recordMismatch,
  unknownFeatureKeys,
  relativeError,
  toHalf,
} from '../src/shared/record';
import { harmonics, quantise } from '../src/worker/spectrum';
import { bandChannels, nCurves } from '../src/shared/settings';

/** The default preset's settings before per-band channels: six channels in two bands. */
const SIX = {
  pano_width: 360,
  oversample: 4,
  row_step_deg: 1,
  bands: [
    [-25, 0],
    [0, 25],
  ] as [number, number][],
  channels: ['I', 'O1', 'O2', 'dI', 'dO1', 'dO2'],
  gray_world: true,
  n_harmonics: 16,
};
import { linspace, interp, polyval, type CatadioptricLens } from '../src/shared/lens';
import { APP_OUTDATED, RecordMismatch } from '../src/client/problems';

describe('float16 as numpy rounds it', () => {
  it('every finite half value survives a round trip', () => {
    for (let h = 0; h < 0x10000; h++) {
      if (((h >> 10) & 0x1f) === 0x1f) continue; // Inf and NaN
      expect(toHalf(fromHalf(h))).toBe(h);
    }
  });
  it('ties go to even, overflow to infinity, tiny values to zero', () => {
    expect(toHalf(1 + 2 ** -11)).toBe(0x3c00); // halfway between 1 and the next half: even (1)
    expect(toHalf(1 + 3 * 2 ** -11)).toBe(0x3c02);
    expect(toHalf(65520)).toBe(0x7c00);
    expect(toHalf(2 ** -26)).toBe(0);
    expect(fromHalf(toHalf(0.1))).toBeCloseTo(0.0999755859375, 12);
  });
});

describe('spectrum and record', () => {
  it('harmonics 1..K of a pure cosine: all energy in its harmonic, phase 0', () => {
    const w = 16;
    const dft = new Float32Array(2 * w); // one curve: 3 cycles of a cosine -> bin 3 = w/2
    dft[2 * 3] = w / 2;
    dft[2 * (w - 3)] = w / 2;
    const { re, im } = harmonics(dft, 1, w, 4);
    expect(Array.from(re)).toEqual([0, 0, 1, 0]);
    expect(Array.from(im)).toEqual([0, 0, 0, 0]);
    expect(() => harmonics(dft, 1, w, 9)).toThrow(/n_harmonics/);
  });
  it('phases are int16 steps of pi/32768 and +pi wraps to -32768', () => {
    const q = quantise(Float64Array.from([-1, 0, 1]), Float64Array.from([0, 1, 0]));
    expect(Array.from(q.phase)).toEqual([-32768, 16384, 0]);
    expect(Array.from(q.mag).map(fromHalf)).toEqual([1, 1, 1]);
  });
  it('the binary record: header <3sBHHHII2x, then magnitudes, then phases', () => {
    const s = {
      pano_width: 360,
      oversample: 4,
      row_step_deg: 1,
      bands: [[-25, 0]] as [number, number][],
      channels: ['I'],
      gray_world: false,
      n_harmonics: 2,
    };
    const f = { mag: Uint16Array.from([0x3c00, 0x3800]), phase: Int16Array.from([1, -2]) };
    const rec = encodeRecord([f, f], s, 0xdeadbeef);
    const dv = new DataView(rec.buffer);
    expect(new TextDecoder().decode(rec.slice(0, 3))).toBe('ONV');
    expect([
      dv.getUint8(3),
      dv.getUint16(4, true),
      dv.getUint16(6, true),
      dv.getUint16(8, true),
      dv.getUint32(10, true),
      dv.getUint32(14, true),
    ]).toEqual([1, 1, 2, 360, 2, 0xdeadbeef]);
    expect(rec.length).toBe(20 + 2 * 2 * 4);
    expect(dv.getUint16(20, true)).toBe(0x3c00);
    expect(dv.getInt16(20 + 8 + 2, true)).toBe(-2);
    expect(() => encodeRecord([], s, 1)).toThrow(/at least one frame/);
  });
  it('the header layout is the engine struct <3sBHHHII2x: 20 bytes, these offsets', () => {
    // written out here, not derived: the test holds the layout to the wire format
    expect(HEADER_BYTES).toBe(20);
    expect(HEADER_AT).toEqual({
      magic: 0,
      version: 3,
      curves: 4,
      harmonics: 6,
      pano_width: 8,
      frames: 10,
      settings_id: 14,
      pad: 18,
    });
  });
  it("a venue document whose record sizes are not this app's is named as a mismatch", () => {
    const f = { n_curves: 12, n_harmonics: 16, record_header_bytes: 20, record_bytes_per_frame: 768 };
    const doc = (over: Partial<typeof f>) => ({ settings: SIX, settings_id: 1, ...f, ...over });
    expect(recordMismatch(doc({}))).toBeNull();
    expect(recordMismatch(doc({ record_header_bytes: 24 }))).toMatch(/24-byte record header, this app makes 20/);
    expect(recordMismatch(doc({ record_bytes_per_frame: 800 }))).toMatch(/800 bytes per frame, this app makes 768/);
    // curves counted otherwise than the server (settings read by an older app): named, not sent
    expect(recordMismatch(doc({ n_curves: 14, record_bytes_per_frame: 896 }))).toMatch(
      /needs 14 curves a frame, this app makes 12/,
    );
    // a setting this app cannot apply, though every size agrees: named, not sent
    expect(recordMismatch(doc({}))).toBeNull();
    expect(recordMismatch({ ...doc({}), feature_keys: ['bands', 'level_iters', 'n_harmonics'] })).toBeNull();
    const newer = { ...doc({}), feature_keys: ['bands', 'sky_mask', 'level_iters', 'row_mask'] };
    expect(recordMismatch(newer)).toBe("the venue's map needs settings this app does not know: sky_mask, row_mask");
    expect(unknownFeatureKeys(newer)).toEqual(['sky_mask', 'row_mask']);
    expect(unknownFeatureKeys(doc({}))).toEqual([]); // a server from before the list: sizes decide
    // the user hears that the app is too old, not the settings' names; a size mismatch says what differs
    expect(new RecordMismatch(recordMismatch(newer)!, true).message).toBe(APP_OUTDATED);
    expect(new RecordMismatch(recordMismatch(newer)!, true).why).toMatch(/sky_mask, row_mask/);
    expect(new RecordMismatch('the server expects 800 bytes per frame').message).toMatch(
      /cannot read \(the server expects 800 bytes per frame\)\. Close omninav/,
    );
  });
  it('per-band channels: each band its own list, counted in the record', () => {
    const plain = SIX;
    expect(bandChannels(plain)).toEqual([SIX.channels, SIX.channels]);
    expect(nCurves(plain)).toBe(12);
    expect(nCurves({ ...plain, band_channels: null })).toBe(12);
    const own = {
      ...plain,
      band_channels: [
        ['I', 'dI'],
        ['O1', 'O2', 'dO1'],
      ],
    };
    expect(bandChannels(own)).toEqual(own.band_channels);
    expect(nCurves(own)).toBe(5);
  });
});

describe('the checks the golden tests rely on', () => {
  it('recordFrame reads back what encodeRecord wrote, frame by frame', () => {
    const s = {
      pano_width: 8,
      oversample: 1,
      row_step_deg: 1,
      bands: [[0, 1]] as [number, number][],
      channels: ['I', 'dI'],
      gray_world: false,
      n_harmonics: 2,
    };
    const a = { mag: Uint16Array.from([1, 2, 3, 4]), phase: Int16Array.from([-5, 6, -7, 8]) };
    const b = { mag: Uint16Array.from([9, 10, 11, 12]), phase: Int16Array.from([13, -14, 15, -16]) };
    const rec = encodeRecord([a, b], s, 7);
    expect(recordFrame(rec, 0)).toEqual(a);
    expect(recordFrame(rec, 1)).toEqual(b);
  });
  it('relativeError is 0 for the same spectrum and the norm ratio otherwise', () => {
    const one = toHalf(1);
    const x = { mag: Uint16Array.from([one, 0]), phase: Int16Array.from([0, 0]) };
    expect(relativeError(x, x)).toBe(0);
    const turned = { mag: x.mag, phase: Int16Array.from([16384, 0]) }; // 1 -> i: |1 - i| / |1|
    expect(relativeError(turned, x)).toBeCloseTo(Math.SQRT2, 12);
    const small = { mag: Uint16Array.from([toHalf(1.001), 0]), phase: x.phase };
    expect(relativeError(small, x)).toBeCloseTo(fromHalf(toHalf(1.001)) - 1, 12);
  });
});

describe('numpy helpers the unwarp tables need', () => {
  it('linspace ends exactly at stop; interp is NaN outside; polyval is ascending', () => {
    const l = linspace(25, -25, 51);
    expect([l[0], l[25], l[50]]).toEqual([25, 0, -25]);
    const xp = Float64Array.from([0, 1, 2]);
    const fp = Float64Array.from([10, 20, 40]);
    expect([interp(0.5, xp, fp), interp(2, xp, fp), interp(-0.1, xp, fp), interp(2.1, xp, fp)]).toEqual([
      15,
      40,
      NaN,
      NaN,
    ]);
    expect(polyval(2, [1, 2, 3])).toBe(1 + 4 + 12);
  });
});

// a donut profile, and a real mirror's sensor (`calib lens` on OpenCV's real catadioptric corners)
const DONUT: CatadioptricLens = {
  model: 'catadioptric',
  image_size: [960, 720],
  center: [487, 352],
  r_inner: 105,
  r_outer: 340,
  elevation_poly: [-90, 0.5],
};
const SENSOR: NonNullable<CatadioptricLens['sensor']> = {
  matrix: [
    [1, -0.0256],
    [0.0242, 1.004],
  ],
  tangential: [0.0296, -0.0046],
  scale: 340,
};

describe('lens profiles the user loads', async () => {
  const { lensProblem } = await import('../src/shared/lens');
  const donut = DONUT;
  it('accepts both models and names what is wrong', () => {
    expect(lensProblem(donut)).toBeNull();
    expect(lensProblem({ model: 'equirectangular', image_size: [1920, 960], forward_x: 960 })).toBeNull();
    expect(lensProblem({ ...donut, r_inner: 400 })).toMatch(/r_inner < r_outer/);
    expect(lensProblem({ ...donut, image_size: [960] })).toMatch(/image_size/);
    expect(lensProblem({ ...donut, model: 'fisheye' })).toMatch(/unknown lens model fisheye/);
    expect(lensProblem([1, 2])).toMatch(/image_size/);
    expect(lensProblem(null)).toMatch(/not an object/);
  });
  it("holds a sensor to lens.py's bounds: near the identity, a small decentring", () => {
    const sensor = SENSOR;
    expect(lensProblem({ ...donut, sensor })).toBeNull();
    expect(lensProblem({ ...donut, sensor: null })).toBeNull(); // as absent, as lens.py reads it
    for (const bad of [
      { ...sensor, tangential: [0.1, 0] },
      {
        ...sensor,
        matrix: [
          [1, 0.9],
          [0, 1],
        ],
      },
      {
        ...sensor,
        matrix: [
          [0.3, 0],
          [0, 1],
        ],
      },
      { ...sensor, scale: 0 },
      { ...sensor, matrix: [1, 0, 0, 1] },
      'flat',
    ])
      expect(lensProblem({ ...donut, sensor: bad }), JSON.stringify(bad)).toMatch(/sensor must be/);
  });
});

describe("the admin page's drawing of a real mirror's profile", async () => {
  const { sensorOutline } = await import('../src/admin/lens-view');
  const { directionToPixel, radiusTable } = await import('../src/shared/lens');
  const donut: CatadioptricLens = { ...DONUT, forward_deg: 90 };
  it('draws a profile without a sensor as circles, one with a sensor where the unwarp reads', () => {
    expect(sensorOutline(donut, 340)).toBeNull();
    const real: CatadioptricLens = { ...donut, sensor: SENSOR };
    const o = sensorOutline(real, 340, 8)!;
    expect(o.points).toHaveLength(8);
    // the forward point is the pixel the profile reads for straight ahead at the outer edge
    const el = polyval(340, donut.elevation_poly);
    const [fx, fy] = directionToPixel(real, radiusTable(real), 0, el);
    expect(Math.hypot(o.forward[0] - fx, o.forward[1] - fy)).toBeLessThan(1e-6);
    // and it is pixels away from the circle's (a real mirror's departure, not rounding)
    expect(Math.hypot(o.forward[0] - 487, o.forward[1] - (352 + 340))).toBeGreaterThan(3);
  });
});
