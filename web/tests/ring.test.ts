// The phone's ring finder (worker/ring.ts, opencv.js in Node as in the browser) against the engine's
// calib/ring.py on the same frames (e2e/fixtures.py `ring`: clip-ons with known shifts, a 1920x1080
// frame, a ring cut by the edge, a plain photo, a covered lens); then the lens decisions, the lens
// watch, and the session's flow (when the lens is checked, what is said, what is sent).
import { execFileSync } from 'node:child_process';
import { readFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { resolve } from 'node:path';
import { beforeAll, beforeEach, describe, expect, it, vi } from 'vitest';
import { readyCv } from '../src/worker/extract';
import {
  findRingFrame,
  fitLens,
  lookOf,
  medianRing,
  visibleShare,
  type LensFit,
  type Ring,
  type RingCv,
} from '../src/worker/ring';
import {
  CORRECTED,
  HELD_KEY,
  LensWatch,
  phoneStorage,
  NOT_ATTACHED,
  NOT_CENTRED,
  TOO_FAR,
  checkLensOn,
  lookChanged,
} from '../src/client/lenscheck';
import { lensProblem, type CatadioptricLens } from '../src/shared/lens';
import type { LensCheck } from '../src/shared/protocol';
import { ROOT } from './global-setup';
import { Session } from '../src/client/session';
import { DEFAULTS } from '../src/client/prefs';
import { captureClip, openCamera } from '../src/client/camera';
import { locate, venue, venues } from '../src/client/api';
import type { FrameResult } from '../src/client/bridge';

// the session's lens flow with the camera, the worker and the server stubbed (the browser runs
// the real ones in e2e/lens.spec.ts); the ring finder and the decisions above are not stubbed
vi.mock('../src/client/camera', async (real) => ({
  ...(await real<typeof import('../src/client/camera')>()),
  openCamera: vi.fn(),
  captureClip: vi.fn(),
}));
vi.mock('../src/client/api', async (real) => ({
  ...(await real<typeof import('../src/client/api')>()),
  locate: vi.fn(),
  venue: vi.fn(),
  venues: vi.fn(),
}));
vi.mock('../src/client/lenscheck', async (real) => ({
  ...(await real<typeof import('../src/client/lenscheck')>()),
  checkLensOn: vi.fn(),
}));
vi.mock('../src/client/bridge', () => ({
  ExtractorClient: class {
    configured: string | null = null;
    configure(lens: unknown, settings: unknown) {
      this.configured = JSON.stringify([lens, settings]);
      return Promise.resolve(1);
    }
  },
}));
vi.mock('../src/shared/record', async (real) => ({
  ...(await real<typeof import('../src/shared/record')>()),
  encodeRecord: () => new Uint8Array(16),
  recordMismatch: () => null,
}));

interface EngineRing {
  center: [number, number];
  r_inner: number;
  r_outer: number;
  visible: number;
  surround: 'darker' | 'brighter';
  housing: number;
  texture_ratio: number;
}
interface GoldenFrame {
  stem: string;
  size: [number, number];
  truth: [number, number, number, number] | null;
  engine: EngineRing | null;
  lens: CatadioptricLens;
  fit: Omit<LensFit, 'lens'> & { lens: CatadioptricLens };
}

// made once per run of this file (about 5 s the first time, then the frames are kept)
const DIR = resolve(ROOT, 'web/test-data/ring');
execFileSync(resolve(ROOT, '.venv/bin/python'), [resolve(ROOT, 'e2e/fixtures.py'), 'ring', DIR], { stdio: 'inherit' });
const frames: GoldenFrame[] = JSON.parse(readFileSync(resolve(DIR, 'ring.json'), 'utf8')).frames;

let cv: RingCv;
beforeAll(async () => {
  cv = (await readyCv(createRequire(import.meta.url)('@techstark/opencv-js'))) as RingCv;
});

const found = new Map<string, Ring | null>();
const ring = (f: GoldenFrame): Ring | null => {
  if (!found.has(f.stem))
    found.set(f.stem, findRingFrame(cv, new Uint8Array(readFileSync(resolve(DIR, `${f.stem}.rgba`))), ...f.size));
  return found.get(f.stem)!;
};

describe('the ring in a frame, as the engine finds it', () => {
  it('the golden set has what it should: clip-ons, 1920x1080, a cut ring, no ring', () => {
    expect(frames.map((f) => f.stem)).toEqual(
      expect.arrayContaining(['ring-hd', 'ring-cut', 'ring-dim', 'ring-plain', 'ring-housing', 'ring-small-centre']),
    );
    expect(frames.find((f) => f.stem === 'ring-hd')!.size).toEqual([1920, 1080]);
    expect(frames.filter((f) => f.engine === null).length).toBeGreaterThanOrEqual(2);
    // every branch of the decision is on a golden frame: a 5 % larger ring whose usable circle
    // leaves the picture is cut, and a profile with a measured ring is corrected from that ring
    const verdict = (stem: string) => frames.find((f) => f.stem === stem)!.fit.verdict;
    expect(verdict('ring-larger')).toBe('cut');
    expect(verdict('ring-measured')).toBe('corrected');
    expect(verdict('ring-donut-still')).toBe('same');
    expect(verdict('ring-plain')).toBe('no_ring');
  });

  for (const f of frames)
    it(`${f.stem}: within 0.5 px of calib/ring.py`, () => {
      const got = ring(f);
      if (f.engine === null) {
        expect(got).toBeNull();
        return;
      }
      expect(got).not.toBeNull();
      const r = got!;
      const e = f.engine;
      expect(r.image_size).toEqual(f.size);
      expect(Math.hypot(r.center[0] - e.center[0], r.center[1] - e.center[1]), 'centre').toBeLessThanOrEqual(0.5);
      expect(Math.abs(r.r_outer - e.r_outer), 'r_outer').toBeLessThanOrEqual(0.5);
      expect(Math.abs(r.r_inner - e.r_inner), 'r_inner').toBeLessThanOrEqual(0.5);
      expect(Math.abs(r.visible - e.visible), 'visible').toBeLessThanOrEqual(0.005);
      // A9 decided as the engine did: which surround, which circle was the housing
      expect(r.surround, 'surround').toBe(e.surround);
      expect(Math.abs(r.housing! - e.housing), 'housing').toBeLessThanOrEqual(0.5);
      expect(r.texture_ratio!, 'texture ratio').toBeCloseTo(e.texture_ratio, 2);
      // and both are where the lens really sat (the renderer's ring)
      if (f.truth) {
        const [cx, cy, ri, ro] = f.truth;
        expect(Math.hypot(r.center[0] - cx, r.center[1] - cy), 'centre vs truth').toBeLessThanOrEqual(0.5);
        expect(Math.abs(r.r_outer - ro), 'r_outer vs truth').toBeLessThanOrEqual(1);
        expect(Math.abs(r.r_inner - ri), 'r_inner vs truth').toBeLessThanOrEqual(1);
      }
    });

  // a real clip-on's photo (pyomniunwarp 0.2.5's, MIT, fetched by e2e/fixtures.py with pip): the
  // per-frame case above compares the phone's ring with the engine's on it; here, that it is there
  const real = frames.find((f) => f.stem === 'real-pyomniunwarp');
  it.skipIf(!real)('a real lens: its ring found by both, and the lens check says it is where it was calibrated', () => {
    const f = real!;
    expect(f.size).toEqual([1920, 1080]);
    expect(f.engine).not.toBeNull();
    const fit = fitLens(f.lens, ring(f));
    expect(['same', 'corrected']).toContain(fit.verdict);
    expect(Math.hypot(fit.dx, fit.dy)).toBeLessThan(0.025 * f.lens.r_outer);
  });

  // real frames that cannot live in the repository (their licences), written by
  // `python -m bench.real_rings IMAGE... -o DIR`: run with OMNINAV_REAL_RINGS=DIR
  const REAL = process.env.OMNINAV_REAL_RINGS;
  it.skipIf(!REAL)('real frames given by OMNINAV_REAL_RINGS: every ring within 0.5 px of the engine', () => {
    const given: Pick<GoldenFrame, 'stem' | 'size' | 'engine'>[] = JSON.parse(
      readFileSync(resolve(REAL!, 'ring.json'), 'utf8'),
    ).frames;
    expect(given.length).toBeGreaterThan(0);
    for (const f of given) {
      const got = findRingFrame(cv, new Uint8Array(readFileSync(resolve(REAL!, `${f.stem}.rgba`))), ...f.size);
      const e = f.engine;
      if (e === null) {
        expect(got, f.stem).toBeNull();
        continue;
      }
      expect(got, f.stem).not.toBeNull();
      const d = Math.max(
        Math.hypot(got!.center[0] - e.center[0], got!.center[1] - e.center[1]),
        Math.abs(got!.r_inner - e.r_inner),
        Math.abs(got!.r_outer - e.r_outer),
      );
      expect(d, f.stem).toBeLessThanOrEqual(0.5);
    }
  });

  it('a bright housing right against the mirror: the ring, not the housing, and a brighter surround', () => {
    const f = frames.find((g) => g.stem === 'ring-housing')!;
    const r = ring(f)!;
    const [, , ri, ro] = f.truth!;
    expect(r.surround).toBe('brighter');
    expect(r.housing!).toBeGreaterThan(ro + 30); // the housing's outer edge, a complete circle
    expect(Math.abs(r.r_outer - ro)).toBeLessThanOrEqual(1);
    expect(Math.abs(r.r_inner - ri)).toBeLessThanOrEqual(1); // not the mirror's edge taken for the inner one
  });

  it("the lens verdicts on the golden frames are the engine's", () => {
    for (const f of frames) {
      const fit = fitLens(f.lens, ring(f));
      expect(fit.verdict, f.stem).toBe(f.fit.verdict);
      expect(Math.hypot(fit.dx - f.fit.dx, fit.dy - f.fit.dy), f.stem).toBeLessThanOrEqual(0.5);
      if (fit.verdict === 'corrected') {
        expect(
          Math.hypot(fit.lens.center[0] - f.fit.lens.center[0], fit.lens.center[1] - f.fit.lens.center[1]),
        ).toBeLessThanOrEqual(0.5);
        expect(Math.abs(fit.lens.r_outer - f.fit.lens.r_outer)).toBeLessThanOrEqual(0.5);
      }
    }
  });
});

// the synthetic donut lens (omninav.synth.donut_lens(1.0))
const LENS: CatadioptricLens = {
  model: 'catadioptric',
  image_size: [960, 720],
  center: [487, 352],
  r_inner: 105,
  r_outer: 340,
  elevation_poly: [-90.0, 0.3, 0.0004],
  forward_deg: 90,
  ccw: true,
};
const at = (cx: number, cy: number, ri: number, ro: number): Ring => ({
  image_size: [960, 720],
  center: [cx, cy],
  r_inner: ri,
  r_outer: ro,
  visible: visibleShare([cx, cy], ro, 960, 720),
});

describe('fitLens: does the profile fit the ring the camera shows?', () => {
  it('the same ring (within 0.25 px and 0.2 %): the profile unchanged, the very object', () => {
    const fit = fitLens(LENS, at(487.2, 351.9, 105, 340.5));
    expect(fit.verdict).toBe('same');
    expect(fit.lens).toBe(LENS);
  });

  it('a lens clipped on 6 px off and 1 % larger: centre moved, radii scaled, elevation(r) -> elevation(r / s)', () => {
    const fit = fitLens(LENS, at(493, 348, 106, 343.4));
    expect(fit.verdict).toBe('corrected');
    expect(fit.dx).toBeCloseTo(6, 9);
    expect(fit.dy).toBeCloseTo(-4, 9);
    expect(fit.scale).toBeCloseTo(1.01, 9);
    expect(fit.moved_px).toBeCloseTo(Math.hypot(6, 4), 9);
    expect(fit.lens.center).toEqual([493, 348]);
    expect(fit.lens.r_outer).toBeCloseTo(343.4, 9);
    expect(fit.lens.r_inner).toBeCloseTo(106.05, 9);
    // the corrected profile sees at r * s what the profile saw at r
    const el = (p: number[], r: number) => p.reduce((s, c, k) => s + c * r ** k, 0);
    expect(el(fit.lens.elevation_poly, 200 * 1.01)).toBeCloseTo(el(LENS.elevation_poly, 200), 9);
    expect(fit.message).toBe('The lens ring moved 7.2 px (right 6.0, up 4.0) and is 1.0 % larger: corrected');
  });

  it('a measured ring in the profile is the reference, and moves with the correction', () => {
    const measured = { ...LENS, ring: { center: [488, 353] as [number, number], r_inner: 104, r_outer: 339 } };
    const fit = fitLens(measured, at(490, 353, 104, 339));
    expect(fit.verdict).toBe('corrected');
    expect([fit.dx, fit.dy]).toEqual([2, 0]);
    expect(fit.lens.center).toEqual([489, 352]);
    expect(fit.lens.ring).toEqual({ center: [490, 353], r_inner: 104, r_outer: 339 });
    expect(fitLens(measured, at(488, 353, 104, 339)).verdict).toBe('same');
  });

  it('more than 10 % of the outer radius off, or 10 % smaller: too far to correct', () => {
    expect(fitLens(LENS, at(487 + 35, 352, 105, 340)).verdict).toBe('too_far');
    expect(fitLens(LENS, at(487, 352, 93, 300)).verdict).toBe('too_far'); // 12 % smaller
    expect(fitLens(LENS, at(487 + 35, 352, 105, 340)).lens).toBe(LENS);
  });

  it('a ring that leaves the picture more than the profile`s does is cut (checked before too far)', () => {
    const fit = fitLens(LENS, at(490, 322, 105, 340));
    expect(fit.verdict).toBe('cut');
    expect(fit.message).toMatch(/^The lens is not centred over the camera; clip it on again/);
    // a lens whose ring is cut by design (pyomniunwarp's) is not "cut" where it sits
    const tall = { ...LENS, center: [487, 330] as [number, number], r_outer: 360 };
    expect(fitLens(tall, { ...at(487.1, 330, 105, 360) }).verdict).toBe('same');
  });

  it('a profile`s measured ring is checked when the user loads their own lens', () => {
    const ring = { center: [488, 353], r_inner: 104, r_outer: 339 };
    expect(lensProblem({ ...LENS, ring })).toBeNull();
    expect(lensProblem({ ...LENS, ring: { ...ring, r_inner: 400 } })).toMatch(/its ring must be/);
    expect(lensProblem({ ...LENS, ring: { center: [1] } })).toMatch(/its ring must be/);
  });

  it('no ring: the lens does not seem to be attached', () => {
    const fit = fitLens(LENS, null);
    expect(fit.verdict).toBe('no_ring');
    expect(fit.message).toBe('The panoramic lens does not seem to be attached');
  });

  it('the median over frames; none when fewer than half show a ring', () => {
    const m = medianRing([at(490, 350, 105, 340), null, at(492, 351, 106, 341), at(491, 349, 104, 342)]);
    expect(m).toMatchObject({ center: [491, 350], r_inner: 105, r_outer: 341, frames_used: 3, frames_total: 4 });
    expect(medianRing([at(490, 350, 105, 340), null, null])).toBeNull();
    // a frame whose inner edge was too faint says 0: not a radius, unless most frames say so
    expect(medianRing([at(490, 350, 0, 340), at(490, 350, 105, 340), at(490, 350, 107, 340)])!.r_inner).toBe(106);
    expect(medianRing([at(490, 350, 0, 340), at(490, 350, 0, 340), at(490, 350, 107, 340)])!.r_inner).toBe(0);
    expect(medianRing([])).toBeNull();
  });
});

describe('the lens watch: when to check, what to say', () => {
  const check = (verdict: LensCheck['verdict'], dx = 0, dy = 0, edge = 80): LensCheck => ({
    verdict,
    dx,
    dy,
    scale: 1,
    moved_px: Math.hypot(dx, dy),
    message: '',
    ring: null,
    look: { mean: 90, edge },
    ms: [20],
    changed_px: 0,
  });

  it('says a correction of 2 px or more once, a smaller one never; stops on no ring, a cut ring, too far', () => {
    const w = new LensWatch();
    expect(w.due('k')).toBe(true);
    expect(w.record(check('corrected', 0.6, 0.3), 'k')).toBeNull();
    expect(w.due('k')).toBe(false);
    expect(w.due('another lens')).toBe(true);
    expect(w.record(check('corrected', 6, -3), 'k')).toEqual({ text: CORRECTED, stop: false });
    expect(w.record(check('corrected', 6.2, -3.1), 'k')).toBeNull(); // the same correction again
    expect(w.record(check('no_ring'), 'k')).toEqual({ text: NOT_ATTACHED, stop: true });
    expect(w.due('k')).toBe(true); // and checked again on the next press
    expect(w.record(check('cut'), 'k')).toEqual({ text: NOT_CENTRED, stop: true });
    expect(w.record(check('too_far'), 'k')).toEqual({ text: TOO_FAR, stop: true });
    expect(NOT_ATTACHED).toMatch(/^The panoramic lens does not seem to be attached/);
    w.record(check('same'), 'k');
    w.reset(); // a new camera stream
    expect(w.due('k')).toBe(true);
  });

  it("a 1 px correction (the e2e clips' lens) is never said, 2.5 px is", () => {
    expect(new LensWatch().record(check('corrected', 0.95, -0.3), 'k')).toBeNull();
    expect(new LensWatch().record(check('corrected', 1.05, 0.3), 'k')).toBeNull();
    expect(new LensWatch().record(check('corrected', 2.5, 0), 'k')).toEqual({ text: CORRECTED, stop: false });
  });

  it('kept between runs of the app: the same correction next time says nothing, a new one is said', () => {
    const kept = new Map<string, string>();
    const store = {
      getItem: (k: string) => kept.get(k) ?? null,
      setItem: (k: string, v: string) => void kept.set(k, v),
    };
    const key = (lens: unknown) => JSON.stringify([lens, { settings_id: 1 }]);
    expect(new LensWatch(store).record(check('corrected', 6, -3), key(LENS))).toEqual({ text: CORRECTED, stop: false });
    // only the lens and the correction's numbers are kept
    expect(JSON.parse(kept.get(HELD_KEY)!)).toEqual({ lens: JSON.stringify(LENS), dx: 6, dy: -3, scale: 1 });
    // the app opened again (a new watch): the lens sits where it sat
    expect(new LensWatch(store).record(check('corrected', 6.1, -3), key(LENS))).toBeNull();
    // clipped on again elsewhere: said, and kept
    expect(new LensWatch(store).record(check('corrected', 1, 2), key(LENS))).toEqual({ text: CORRECTED, stop: false });
    expect(new LensWatch(store).record(check('corrected', 1.1, 2), key(LENS))).toBeNull();
    // another lens profile: the kept correction is not its own
    const other = { ...LENS, center: [LENS.center[0] + 1, LENS.center[1]] };
    expect(new LensWatch(store).record(check('corrected', 1.1, 2), key(other))).toEqual({
      text: CORRECTED,
      stop: false,
    });
    // the lens found where its profile says: kept as no correction, so the next move off is said
    new LensWatch(store).record(check('same'), key(LENS));
    expect(new LensWatch(store).record(check('corrected', 6, -3), key(LENS))).toEqual({ text: CORRECTED, stop: false });
    // a stop (no ring) keeps nothing
    const before = kept.get(HELD_KEY);
    new LensWatch(store).record(check('no_ring'), key(LENS));
    expect(kept.get(HELD_KEY)).toBe(before);
  });

  it('site data blocked (reading localStorage throws): no store, and the watch works for the run', () => {
    const had = Object.getOwnPropertyDescriptor(globalThis, 'localStorage');
    Object.defineProperty(globalThis, 'localStorage', {
      configurable: true,
      get: () => {
        throw new DOMException('The operation is insecure.', 'SecurityError');
      },
    });
    try {
      expect(phoneStorage()).toBeNull();
      const w = new LensWatch(phoneStorage());
      expect(w.record(check('corrected', 6, -3), 'k')).toEqual({ text: CORRECTED, stop: false });
      expect(w.record(check('corrected', 6.1, -3), 'k')).toBeNull();
    } finally {
      if (had) Object.defineProperty(globalThis, 'localStorage', had);
      else delete (globalThis as { localStorage?: unknown }).localStorage;
    }
    const kept = new Map<string, string>();
    const store = {
      getItem: (k: string) => kept.get(k) ?? null,
      setItem: (k: string, v: string) => void kept.set(k, v),
    };
    Object.defineProperty(globalThis, 'localStorage', { configurable: true, value: store });
    try {
      expect(phoneStorage()).toBe(store);
    } finally {
      if (had) Object.defineProperty(globalThis, 'localStorage', had);
      else delete (globalThis as { localStorage?: unknown }).localStorage;
    }
  });

  it('a kept correction that is not readable, or a store that refuses to keep one, changes nothing else', () => {
    const key = JSON.stringify([LENS, { settings_id: 1 }]);
    for (const raw of [
      'not json',
      '{"lens": 3}',
      JSON.stringify({ lens: JSON.stringify(LENS), dx: 'x', dy: 0, scale: 1 }),
    ]) {
      const store = { getItem: () => raw, setItem: () => undefined };
      expect(new LensWatch(store).record(check('corrected', 6, -3), key)).toEqual({ text: CORRECTED, stop: false });
    }
    const refusing = {
      getItem: () => null,
      setItem: () => {
        throw new Error('QuotaExceededError');
      },
    };
    const w = new LensWatch(refusing);
    expect(w.record(check('corrected', 6, -3), key)).toEqual({ text: CORRECTED, stop: false });
    expect(w.record(check('corrected', 6.1, -3), key)).toBeNull(); // still held for this run
  });

  it('a new camera stream that finds the same correction says nothing; a change of scale counts as a move', () => {
    const w = new LensWatch();
    expect(w.record(check('corrected', 6, -3), 'k')).toEqual({ text: CORRECTED, stop: false });
    w.reset(); // the phone was locked and unlocked: the worker still holds the correction
    expect(w.due('k')).toBe(true);
    expect(w.record(check('corrected', 6.1, -3), 'k')).toBeNull();
    // the centre stays, the ring grows 1 %: its edge (r 340 px) moves 3.4 px: said
    const grown = { ...check('corrected', 6.1, -3), scale: 1.01, ring: { r_outer: 343.4 } as LensCheck['ring'] };
    expect(w.record(grown, 'k')).toEqual({ text: CORRECTED, stop: false });
    // 0.1 % (0.34 px at the edge): silent
    expect(w.record({ ...grown, scale: 1.011 }, 'k')).toBeNull();
  });

  it('the venue modelled anew (new settings, same lens): the same correction found again says nothing', () => {
    const w = new LensWatch();
    const key = (lens: unknown, settingsId: number) => JSON.stringify([lens, { settings_id: settingsId }]);
    expect(w.record(check('corrected', 6, -3), key(LENS, 1))).toEqual({ text: CORRECTED, stop: false });
    expect(w.due(key(LENS, 2))).toBe(true); // the worker dropped the correction: look again
    expect(w.record(check('corrected', 6.1, -3), key(LENS, 2))).toBeNull();
    // another lens is another matter
    const other = { ...LENS, center: [LENS.center[0] + 1, LENS.center[1]] };
    expect(w.record(check('corrected', 6.1, -3), key(other, 2))).toEqual({ text: CORRECTED, stop: false });
  });

  it('an abrupt change: the brightness jumps, or the ring`s edge fades; not a little drift', () => {
    const base = { mean: 90, edge: 60 };
    expect(lookChanged(base, { mean: 95, edge: 55 })).toBe(false);
    expect(lookChanged(base, { mean: 150, edge: 60 })).toBe(true);
    expect(lookChanged(base, { mean: 88, edge: 12 })).toBe(true);
    expect(lookChanged(base, { mean: 88, edge: NaN })).toBe(true);
    expect(lookChanged({ mean: 90, edge: NaN }, { mean: 92, edge: NaN })).toBe(false); // a 360 camera
    const w = new LensWatch();
    w.record(check('same', 0, 0, 60), 'k');
    const frame = (mean: number, edge: number) => ({
      mag: new Uint16Array(),
      phase: new Int16Array(),
      ms: 1,
      look: { mean, edge },
    });
    expect(w.changed([frame(91, 58), frame(89, 61), frame(200, 0)])).toBe(false); // one odd frame
    expect(w.changed([frame(91, 5), frame(89, 4), frame(90, 6)])).toBe(true);
  });

  it('the look of a rendered frame: the ring`s edge is a clear step where the profile says, none off it', () => {
    const f = frames.find((x) => x.stem === 'donut-default-0')!;
    const px = new Uint8Array(readFileSync(resolve(DIR, `${f.stem}.rgba`)));
    const on = lookOf(px, ...f.size, f.lens);
    const off = lookOf(px, ...f.size, { ...f.lens, center: [f.lens.center[0] + 60, f.lens.center[1]] });
    expect(on.edge).toBeGreaterThan(20);
    expect(lookChanged(on, off)).toBe(true);
  });
});

describe("the session's lens check: when it runs, what is said, what is sent", () => {
  const donut: CatadioptricLens = { ...LENS };
  const VENUE = {
    id: 'demo',
    name: 'Demo',
    revision: 1,
    modelled: true,
    frames: 100,
    floors: [{ id: '1', name: 'Hall', plan_url: null, plan_size_px: null, px_per_m: null }],
    places: [],
    lenses: { donut },
    features: { settings: {}, settings_id: 1 },
  };
  const ANSWER = {
    clip: 'c',
    x: 1,
    y: 2,
    heading_deg: 30,
    confidence: 0.9,
    floor: '1',
    place: null,
    frame: 1,
    area: null,
    nearest: null,
    facing: null,
    sentence: '',
    low_confidence: false,
    accuracy_m: 1,
    frames: 10,
    sent: 'features',
  };
  const clip = (mean = 90, edge = 60) => ({
    frames: Array.from({ length: 10 }, (): FrameResult => ({
      mag: new Uint16Array(),
      phase: new Int16Array(),
      ms: 5,
      look: { mean, edge },
    })),
    fps: 10,
    startMs: 0,
    endMs: 900,
  });
  const checked = (verdict: LensCheck['verdict'], dx = 0, dy = 0): LensCheck => ({
    verdict,
    dx,
    dy,
    scale: 1,
    moved_px: Math.hypot(dx, dy),
    message: `the lens: ${verdict}`,
    ring: null,
    look: { mean: 90, edge: 60 },
    ms: [25, 26, 24],
    changed_px: verdict === 'corrected' ? Math.hypot(dx, dy) : 0,
  });

  function session(lenses: Record<string, unknown> = { donut }, [videoWidth, videoHeight] = [960, 720]) {
    vi.mocked(venues).mockResolvedValue([{ id: 'demo', name: 'Demo', modelled: true }]);
    vi.mocked(venue).mockResolvedValue({ ...VENUE, lenses } as never);
    vi.mocked(openCamera).mockResolvedValue({ getVideoTracks: () => [{ readyState: 'live' }] } as never);
    vi.mocked(captureClip).mockResolvedValue(clip());
    vi.mocked(locate).mockResolvedValue(ANSWER as never);
    const voice = { busy: false, say: vi.fn(), cue: vi.fn() };
    const s = new Session({
      prefs: { ...DEFAULTS },
      save: vi.fn(),
      voice,
      video: { videoWidth, videoHeight } as HTMLVideoElement,
      askedVenue: null,
    });
    const answers: unknown[] = [];
    s.on('answer', (a) => answers.push(a));
    return { s, voice, answers };
  }

  beforeEach(() => vi.clearAllMocks());

  it('no ring: "not attached" in the alert region, and no locate request, press after press', async () => {
    const { s, voice } = session();
    vi.mocked(checkLensOn).mockResolvedValue(checked('no_ring'));
    await s.whereAmI();
    // looked twice (a camera that has just started may still be finding its exposure), then said
    expect(checkLensOn).toHaveBeenCalledTimes(2);
    expect(voice.say).toHaveBeenCalledWith(NOT_ATTACHED, 'error', true);
    await s.whereAmI();
    expect(checkLensOn).toHaveBeenCalledTimes(3); // checked again: it may have been clipped on since
    // the second filmed beside each check was stopped when the check failed, and never sent
    expect(captureClip).toHaveBeenCalledTimes(2);
    for (const c of vi.mocked(captureClip).mock.calls) expect(c[4]?.()).toBe(true);
    expect(locate).not.toHaveBeenCalled();
  });

  it('a cut ring: "not centred", no request; once clipped on properly, it answers', async () => {
    const { s, voice } = session();
    vi.mocked(checkLensOn).mockResolvedValue(checked('cut', 2, -15));
    await s.whereAmI();
    expect(voice.say).toHaveBeenCalledWith(NOT_CENTRED, 'error', true);
    expect(locate).not.toHaveBeenCalled();
    vi.mocked(checkLensOn).mockResolvedValue(checked('same'));
    await s.whereAmI();
    expect(locate).toHaveBeenCalledTimes(1);
  });

  it('corrected by 6 px: said once, before the answer; checked again only when the picture jumps', async () => {
    const { s, voice, answers } = session();
    vi.mocked(checkLensOn).mockResolvedValue(checked('corrected', 5, -3.3));
    await s.whereAmI();
    expect(voice.say.mock.calls.map((c) => c[0])).toEqual([CORRECTED, expect.stringMatching(/^You are/)]);
    expect(locate).toHaveBeenCalledTimes(1);
    expect(answers[0]).toMatchObject({ lensCheck: { message: 'the lens: corrected', ms: 25 } });
    // the next press: no check, nothing about the lens
    await s.whereAmI();
    expect(checkLensOn).toHaveBeenCalledTimes(1);
    expect(voice.say.mock.calls.filter((c) => c[0] === CORRECTED)).toHaveLength(1);
    // the lens taken off and clipped on again between presses: the clip's ring edge has faded, so
    // the lens is checked again and the clip taken again through the new correction
    vi.mocked(captureClip).mockResolvedValueOnce(clip(88, 4));
    vi.mocked(checkLensOn).mockResolvedValue(checked('corrected', -4, 6));
    await s.whereAmI();
    expect(checkLensOn).toHaveBeenCalledTimes(2);
    // the first press filmed beside its check, and again through the corrected profile; the last
    // press's clip was taken again after its check; each press films on while it is answered
    expect(vi.mocked(captureClip).mock.calls.map((c) => c[2])).toEqual([10, 10, 20, 10, 20, 10, 10, 20]);
    expect(locate).toHaveBeenCalledTimes(3);
    expect(voice.say.mock.calls.filter((c) => c[0] === CORRECTED)).toHaveLength(2);
  });

  it('a check that moves the profile films the second anew at once, not after the one beside it', async () => {
    const { s } = session();
    vi.mocked(checkLensOn).mockResolvedValue(checked('corrected', 5, -3.3));
    // the filming beside the check never ends by itself: only its stop does, and it is not awaited
    vi.mocked(captureClip).mockReturnValueOnce(new Promise(() => undefined));
    await s.whereAmI();
    expect(vi.mocked(captureClip).mock.calls[0][4]?.()).toBe(true);
    expect(locate).toHaveBeenCalledTimes(1);
  });

  it('a fresh camera looked at twice: the second that passed is filmed anew, the one beside dropped', async () => {
    const { s } = session();
    vi.mocked(checkLensOn).mockResolvedValueOnce(checked('no_ring')).mockResolvedValue(checked('same'));
    await s.whereAmI();
    expect(checkLensOn).toHaveBeenCalledTimes(2);
    expect(vi.mocked(captureClip).mock.calls.map((c) => c[2])).toEqual([10, 10, 20]);
    expect(vi.mocked(captureClip).mock.calls[0][4]?.()).toBe(true);
    expect(locate).toHaveBeenCalledTimes(1);
  });

  it('under 1 px: corrected silently', async () => {
    const { s, voice } = session();
    vi.mocked(checkLensOn).mockResolvedValue(checked('corrected', 0.6, 0.4));
    await s.whereAmI();
    expect(voice.say.mock.calls.map((c) => c[0])).toEqual([expect.stringMatching(/^You are/)]);
  });

  it('a 360 camera: no ring, no check', async () => {
    const { s } = session({ theta: { model: 'equirectangular', image_size: [960, 480], forward_x: 480 } }, [960, 480]);
    await s.whereAmI();
    expect(checkLensOn).not.toHaveBeenCalled();
    expect(locate).toHaveBeenCalledTimes(1);
  });
});
