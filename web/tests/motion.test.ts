// The phone's motion for the tracker: steps counted on synthetic walking accelerations (any
// holding of the phone, noise, a limp's uneven steps), none while standing; the turn about the
// vertical integrated from the gyroscope however the phone is tilted; the feed's counts per request.
import { describe, expect, it } from 'vitest';
import {
  MotionFeed,
  STALL_MS,
  StepDetector,
  YawIntegrator,
  upFromOrientation,
  wrap180,
  type MotionSource,
  type Vec3,
} from '../src/client/motion';

/** A seeded generator (mulberry32) and Gaussian noise from it. */
function rng(seed: number): () => number {
  let a = seed >>> 0;
  return () => {
    a = (a + 0x6d2b79f5) >>> 0;
    let t = a;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}
function gauss(r: () => number): number {
  return Math.sqrt(-2 * Math.log(r() || 1e-12)) * Math.cos(2 * Math.PI * r());
}

/**
 * A walk's accelerometer at `hz` samples/s for `seconds`: gravity along `down` plus, per step, a
 * bounce of `amp` m/s² (its second harmonic too, as a heel strike has), and noise of `noise` m/s².
 */
function walk(o: {
  stepsPerS: number;
  seconds: number;
  amp: number;
  noise: number;
  hz?: number;
  seed?: number;
  up?: Vec3;
}) {
  const hz = o.hz ?? 60;
  const r = rng(o.seed ?? 1);
  const up = o.up ?? [0, 0, 1];
  const n = Math.hypot(...up);
  const samples: [number, Vec3][] = [];
  for (let i = 0; i < o.seconds * hz; i++) {
    const t = i / hz;
    const ph = 2 * Math.PI * o.stepsPerS * t;
    const bounce = o.stepsPerS ? o.amp * Math.sin(ph) + 0.3 * o.amp * Math.sin(2 * ph + 0.7) : 0;
    const g = 9.81 + bounce;
    samples.push([
      t * 1000,
      [
        (g * up[0]) / n + o.noise * gauss(r),
        (g * up[1]) / n + o.noise * gauss(r),
        (g * up[2]) / n + o.noise * gauss(r),
      ],
    ]);
  }
  return samples;
}

function countSteps(samples: [number, Vec3][]): number {
  const d = new StepDetector();
  for (const [t, a] of samples) d.add(t, a);
  return d.count;
}

describe('StepDetector', () => {
  it.each([
    ['a brisk walk, phone flat', { stepsPerS: 2, seconds: 10, amp: 2, noise: 0.3 }, 20],
    ['a slow walk, phone upright', { stepsPerS: 1.2, seconds: 10, amp: 1.4, noise: 0.3, up: [0, 1, 0] as Vec3 }, 12],
    [
      'a walk, phone tilted, 50 Hz',
      { stepsPerS: 1.8, seconds: 20, amp: 1.8, noise: 0.4, hz: 50, up: [0.3, 0.8, 0.5] as Vec3 },
      36,
    ],
    ['another seed', { stepsPerS: 1.7, seconds: 30, amp: 1.6, noise: 0.5, seed: 7 }, 51],
  ])('%s: counts the steps within one', (_, o, steps) => {
    expect(Math.abs(countSteps(walk(o)) - steps)).toBeLessThanOrEqual(1);
  });

  it('counts no step while the user stands still with a shaky hand', () => {
    expect(countSteps(walk({ stepsPerS: 0, seconds: 30, amp: 0, noise: 0.4, seed: 3 }))).toBe(0);
  });

  it('counts a walk after standing, and nothing more once stopped', () => {
    const still = walk({ stepsPerS: 0, seconds: 5, amp: 0, noise: 0.3, seed: 4 });
    const moving = walk({ stepsPerS: 2, seconds: 5, amp: 2, noise: 0.3, seed: 5 }).map(
      ([t, a]) => [t + 5000, a] as [number, Vec3],
    );
    const after = walk({ stepsPerS: 0, seconds: 5, amp: 0, noise: 0.3, seed: 6 }).map(
      ([t, a]) => [t + 10000, a] as [number, Vec3],
    );
    const d = new StepDetector();
    for (const [t, a] of still) d.add(t, a);
    expect(d.count).toBe(0);
    for (const [t, a] of moving) d.add(t, a);
    const walked = d.count;
    expect(Math.abs(walked - 10)).toBeLessThanOrEqual(1);
    for (const [t, a] of after) d.add(t, a);
    expect(d.count).toBe(walked);
  });
});

/**
 * A pure turn about `up` at `degPerS` clockwise, as the gyroscope reports it, for `seconds` after
 * `t0` (ms; the previous sample's time).
 */
function turn(y: YawIntegrator, up: Vec3, degPerS: number, seconds: number, t0 = 0, hz = 60): number {
  const n = Math.hypot(...up);
  const u = up.map((v) => v / n);
  // clockwise about up is a negative rate about up; rotation rate: alpha about z, beta about x, gamma about y
  const w = u.map((v) => -degPerS * v);
  let t = t0;
  if (t0 === 0) y.rate(0, { alpha: 0, beta: 0, gamma: 0 }, up);
  for (let i = 1; i <= seconds * hz; i++) {
    t = t0 + (i * 1000) / hz;
    y.rate(t, { alpha: w[2], beta: w[0], gamma: w[1] }, up);
  }
  return t;
}

describe('YawIntegrator', () => {
  it.each([
    ['flat, screen up', [0, 0, 9.81] as Vec3],
    ['upright, portrait', [0, 9.81, 0] as Vec3],
    ['tilted 60 degrees, rolled a little', upFromOrientation(60, 20)],
  ])('%s: a right turn of 90 degrees is +90, a left turn back is -90', (_, up) => {
    const y = new YawIntegrator();
    const t = turn(y, up, 45, 2);
    expect(y.total).toBeCloseTo(90, 5);
    turn(y, up, -90, 1, t);
    expect(y.total).toBeCloseTo(0, 1);
  });

  it('ignores a pitch of the phone (rotation about a level axis)', () => {
    const y = new YawIntegrator();
    const up: Vec3 = [0, 0, 1];
    for (let i = 0; i <= 60; i++) y.rate((i * 1000) / 60, { alpha: 0, beta: 40, gamma: -25 }, up);
    expect(y.total).toBeCloseTo(0, 9);
  });

  it('does not count a sleeping page as time turning', () => {
    const y = new YawIntegrator();
    y.rate(0, { alpha: -90, beta: 0, gamma: 0 }, [0, 0, 1]);
    y.rate(10_000, { alpha: -90, beta: 0, gamma: 0 }, [0, 0, 1]); // 10 s gap: at most 0.25 s counted
    expect(y.total).toBeLessThanOrEqual(90 * 0.25 + 1e-9);
  });

  it('falls back to the orientation alpha (counter-clockwise) only without a gyroscope', () => {
    const y = new YawIntegrator();
    expect(y.seen).toBe(false);
    y.orientation(350);
    y.orientation(10); // 20 degrees counter-clockwise across north
    y.orientation(340); // 30 degrees clockwise back
    expect(y.total).toBeCloseTo(10, 9);
    const g = new YawIntegrator();
    g.rate(0, { alpha: 0, beta: 0, gamma: 0 }, [0, 0, 1]);
    g.orientation(0);
    g.orientation(90);
    expect(g.total).toBe(0);
  });

  it('up from the orientation angles: flat, upright, rolled', () => {
    const close = (a: Vec3, b: Vec3) => a.forEach((v, i) => expect(v).toBeCloseTo(b[i], 9));
    close(upFromOrientation(0, 0), [0, 0, 1]);
    close(upFromOrientation(90, 0), [0, 1, 0]);
    close(upFromOrientation(0, 90), [-1, 0, 0]);
    expect(wrap180(190)).toBe(-170);
    expect(wrap180(-180)).toBe(180);
  });
});

class FakeWindow implements MotionSource {
  fns = new Map<string, (e: Event) => void>();
  addEventListener(type: string, fn: (e: Event) => void): void {
    this.fns.set(type, fn);
  }
  removeEventListener(type: string): void {
    this.fns.delete(type);
  }
  fire(type: string, e: object): void {
    this.fns.get(type)?.(e as Event);
  }
}

describe('MotionFeed', () => {
  /** A window with a clock: each sample arrives at its own time stamp. */
  function rigFeed() {
    const w = new FakeWindow();
    let now = 0;
    const feed = new MotionFeed(w, () => now);
    const at = (t: number) => (now = t);
    /** `seconds` of walking from `from` ms, turning 18 degrees a second clockwise, phone flat. */
    const walkFor = (from: number, seconds: number, seed = 9) => {
      for (const [t, a] of walk({ stepsPerS: 2, seconds, amp: 2, noise: 0.2, seed })) {
        at(from + t);
        w.fire('devicemotion', {
          timeStamp: from + t,
          accelerationIncludingGravity: { x: a[0], y: a[1], z: a[2] },
          rotationRate: { alpha: -18, beta: 0, gamma: 0 },
        });
      }
    };
    /** Standing still, `seconds` of samples from `from` ms. */
    const standFor = (from: number, seconds: number) => {
      for (let t = 0; t <= seconds * 1000; t += 20) {
        at(from + t);
        w.fire('devicemotion', {
          timeStamp: from + t,
          accelerationIncludingGravity: { x: 0, y: 0, z: 9.81 },
          rotationRate: { alpha: 0, beta: 0, gamma: 0 },
        });
      }
    };
    return { w, feed, at, walkFor, standFor };
  }

  it('hands out the steps and the turn since the last committed reading, unknown without sensors', () => {
    const { w, feed, walkFor, standFor } = rigFeed();
    feed.start();
    // the first reading after start: the interval began before the sensors ran
    const first = feed.peek();
    expect(first).toMatchObject({ steps: null, turn_deg: null });
    feed.commit(first);
    expect(feed.peek()).toMatchObject({ steps: null, turn_deg: null }); // no sensor at all
    w.fire('deviceorientation', { alpha: 0, beta: 0, gamma: 0, timeStamp: 0 });
    standFor(0, 1);
    feed.commit(feed.peek());
    walkFor(1000, 5);
    const walked = feed.peek();
    expect(Math.abs(walked.steps! - 10)).toBeLessThanOrEqual(1);
    expect(walked.turn_deg!).toBeCloseTo(90, 0);
    feed.commit(walked);
    standFor(6100, 1);
    expect(feed.peek()).toMatchObject({ steps: 0, turn_deg: 0 });
    feed.stop();
    expect(w.fns.size).toBe(0);
    expect(feed.peek()).toEqual({ steps: null, turn_deg: null, mark: null });
  });

  it('a reading not committed (its request failed) is counted again with the next', () => {
    const { feed, walkFor, standFor } = rigFeed();
    feed.start();
    standFor(0, 1);
    feed.commit(feed.peek());
    walkFor(1000, 5, 1);
    const lost = feed.peek(); // sent, never answered
    walkFor(6000, 5, 2);
    const next = feed.peek();
    expect(next.steps!).toBeGreaterThanOrEqual(lost.steps! + 9);
    expect(next.turn_deg!).toBeCloseTo(180, 0);
    feed.commit(next);
    standFor(11100, 0.5);
    expect(feed.peek()).toMatchObject({ steps: 0, turn_deg: 0 });
  });

  it('unknown once the samples stopped: none since the last reading, a gap, or none lately', () => {
    const { feed, at, walkFor, standFor } = rigFeed();
    feed.start();
    standFor(0, 1);
    feed.commit(feed.peek());
    standFor(1000, 1);
    const still = feed.peek();
    expect(still).toMatchObject({ steps: 0, turn_deg: 0 });
    feed.commit(still);
    // the feed stops (a hidden page): no sample since the last reading, not "stood still"
    at(10_000);
    expect(feed.peek()).toMatchObject({ steps: null, turn_deg: null });
    // samples again, after a gap that counted nothing: still unknown for this interval
    walkFor(10_000, 2);
    const gap = feed.peek();
    expect(gap).toMatchObject({ steps: null, turn_deg: null });
    feed.commit(gap);
    walkFor(12_000, 2);
    expect(feed.peek().steps).toBeGreaterThan(0);
    // samples that stopped a while ago, read now: unknown
    at(15_000 + STALL_MS);
    expect(feed.peek()).toMatchObject({ steps: null, turn_deg: null });
  });

  it('start() again begins a new count: the first reading is unknown and an old mark is ignored', () => {
    const { feed, standFor, walkFor } = rigFeed();
    feed.start();
    standFor(0, 1);
    feed.commit(feed.peek());
    walkFor(1000, 3);
    const old = feed.peek();
    feed.stop();
    feed.start();
    feed.commit(old); // from before the restart: ignored
    standFor(5000, 1);
    expect(feed.peek()).toMatchObject({ steps: null, turn_deg: null });
  });
});
