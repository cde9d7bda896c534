/**
 * The phone's own motion between two locate requests, for the tracker (issue 14): steps counted
 * from the accelerometer and the turn about the vertical from the gyroscope. Both detectors are
 * pure classes fed samples (time in ms, values as the browser reports them), so that Vitest can
 * drive them with synthetic walks; `MotionFeed` only wires them to the page's
 * `devicemotion`/`deviceorientation` events and hands out what happened since the motion last
 * reached the server (a reading counts as sent once its request was answered), or "unknown" where
 * the sensors did not report all through.
 *
 * Steps: the magnitude of `accelerationIncludingGravity` (so the way the phone is held does not
 * matter), minus its slow mean (gravity), smoothed; a step is a rise above STEP_HIGH after the
 * signal went back below its mean, at least MIN_STEP_MS after the previous step (a brisk walk is
 * ~2.5 steps/s). Turn: the gyroscope's rotation rate projected on the vertical ("up" in the
 * phone's axes, from the orientation's beta/gamma, else from gravity), integrated over time;
 * clockwise seen from above is positive, like the plan's headings. "Up" comes from the orientation
 * angles first: their convention is the same everywhere, while some browsers (older iOS Safari)
 * report gravity with the opposite sign, which would mirror the turn. Where a browser gives
 * orientation angles but no rotation rate, the change of `alpha` stands in.
 */
import { signed } from './directions';

/** A rise of the smoothed acceleration magnitude above its mean by this much (m/s²) is a step. */
export const STEP_HIGH = 0.9;
/** The shortest time between two steps (ms): ~4 steps/s, faster than anyone walks. */
export const MIN_STEP_MS = 250;
/** Smoothing of the magnitude (s): removes the hand's tremor, keeps the ~2 Hz of steps. */
const SMOOTH_S = 0.06;
/** Time constant of the running mean (s): gravity plus the phone's slow drifts. */
const MEAN_S = 1.5;
/** A gap longer than this (a page that slept) does not count as time turning. */
const MAX_DT_S = 0.25;

/** What the phone felt since the previous request; null where it could not tell (no sensor). */
export interface Motion {
  steps: number | null;
  turn_deg: number | null;
}

/** Rotation rate about the phone's axes in degrees per second: alpha about z, beta about x, gamma about y. */
export interface RotationRate {
  alpha: number | null;
  beta: number | null;
  gamma: number | null;
}

export type Vec3 = readonly [number, number, number];

/** Counts steps from the acceleration magnitude (m/s², gravity included) sampled over time. */
export class StepDetector {
  private t: number | null = null;
  private mean = 0;
  private smooth = 0;
  private armed = false;
  private lastStep = -Infinity;
  /** Steps counted since the start. */
  count = 0;
  /** Samples taken (a sensor that keeps sending). */
  samples = 0;

  /** One sample: time in ms, the acceleration including gravity (any axes, only its length is used). */
  add(tMs: number, a: Vec3): void {
    const m = Math.hypot(a[0], a[1], a[2]);
    if (!Number.isFinite(m)) return;
    this.samples++;
    if (this.t === null) {
      this.t = tMs;
      this.mean = m;
      return;
    }
    const dt = Math.min(Math.max((tMs - this.t) / 1000, 0), MAX_DT_S);
    this.t = tMs;
    if (dt === 0) return;
    this.mean += (1 - Math.exp(-dt / MEAN_S)) * (m - this.mean);
    this.smooth += (1 - Math.exp(-dt / SMOOTH_S)) * (m - this.mean - this.smooth);
    if (this.smooth < 0) this.armed = true;
    else if (this.armed && this.smooth > STEP_HIGH && tMs - this.lastStep >= MIN_STEP_MS) {
      this.armed = false;
      this.lastStep = tMs;
      this.count++;
    }
  }
}

/** Earth's "up" in the phone's axes from the orientation's beta and gamma (degrees), unit length. */
export function upFromOrientation(betaDeg: number, gammaDeg: number): Vec3 {
  const b = (betaDeg * Math.PI) / 180;
  const g = (gammaDeg * Math.PI) / 180;
  return [-Math.cos(b) * Math.sin(g), Math.sin(b), Math.cos(b) * Math.cos(g)];
}

/** Any angle in degrees -> (-180, 180]: the words' own wrap (directions.ts). */
export const wrap180 = signed;

/**
 * Integrates the turn about the vertical, clockwise seen from above positive (degrees). The phone
 * may be held any way: the rotation rate is projected on "up" in the phone's own axes.
 */
export class YawIntegrator {
  private t: number | null = null;
  private lastAlpha: number | null = null;
  private gyro = false;
  /** Degrees turned since the start. */
  total = 0;
  /** Samples taken into the turn. */
  samples = 0;

  /** One gyroscope sample: time in ms, the rotation rate (deg/s), and up in the phone's axes (any length). */
  rate(tMs: number, r: RotationRate, up: Vec3): void {
    if (r.alpha === null || r.beta === null || r.gamma === null) return;
    const n = Math.hypot(up[0], up[1], up[2]);
    if (!(n > 0)) return;
    this.gyro = true;
    this.samples++;
    if (this.t === null) {
      this.t = tMs;
      return;
    }
    const dt = Math.min(Math.max((tMs - this.t) / 1000, 0), MAX_DT_S);
    this.t = tMs;
    // right-handed axes: a positive rate turns counter-clockwise about its axis, so about "up"
    // a positive projection is a turn to the left
    const w = (r.beta * up[0] + r.gamma * up[1] + r.alpha * up[2]) / n;
    this.total -= w * dt;
  }

  /**
   * An orientation sample's alpha (degrees, growing counter-clockwise): used only where no
   * rotation rate ever came (a browser without a gyroscope event).
   */
  orientation(alphaDeg: number | null): void {
    if (this.gyro || alphaDeg === null || !Number.isFinite(alphaDeg)) return;
    this.samples++;
    if (this.lastAlpha !== null) this.total -= wrap180(alphaDeg - this.lastAlpha);
    this.lastAlpha = alphaDeg;
  }

  /** Whether any sample came (else the turn is unknown). */
  get seen(): boolean {
    return this.gyro || this.lastAlpha !== null;
  }
}

/** Where motion events come from: the window, or a fake in tests. */
export interface MotionSource {
  addEventListener(type: 'devicemotion' | 'deviceorientation', fn: (e: Event) => void): void;
  removeEventListener(type: 'devicemotion' | 'deviceorientation', fn: (e: Event) => void): void;
}

type MotionLike = Pick<DeviceMotionEvent, 'accelerationIncludingGravity' | 'rotationRate' | 'timeStamp'>;
type OrientationLike = Pick<DeviceOrientationEvent, 'alpha' | 'beta' | 'gamma' | 'timeStamp'>;

/**
 * Samples further apart than this (ms) mean the feed stopped meanwhile (a hidden page, a sensor
 * that paused): what happened then was not counted, so the interval's motion is unknown. Phones
 * send motion events 16-60 times a second.
 */
export const STALL_MS = 1000;

/** Whether one sensor's samples kept coming: how many, the last one's arrival, how often they stopped. */
class Liveness {
  n = 0;
  last = -Infinity;
  stalls = 0;

  beat(now: number): void {
    if (this.n > 0 && now - this.last > STALL_MS) this.stalls++;
    this.n++;
    this.last = now;
  }
}

/** Where the counts stood when motion was read: a later `commit` counts from here. */
export interface MotionMark {
  /** Which start() of the feed it belongs to: a mark from before a restart is ignored. */
  readonly run: number;
  readonly steps: number;
  readonly turn: number;
  readonly accel: { readonly n: number; readonly stalls: number };
  readonly yaw: { readonly n: number; readonly stalls: number };
}

/** The motion since the last commit, and the mark to commit once the request carrying it was answered. */
export interface MotionReading extends Motion {
  /** Null: the feed is not running, nothing to commit. */
  readonly mark: MotionMark | null;
}

/**
 * The page's motion events -> steps and turn since the motion last counted as sent. A request
 * reads (`peek`) when its clip is filmed and commits that reading only once the server answered
 * it, so the motion of a request that failed goes with the next one. Nothing is kept but counts.
 * The motion is unknown (null), never "still", where the feed cannot tell: no sensor (or no
 * permission), the first reading after `start()` (the interval began before the sensors ran),
 * and an interval in which the sensor's samples stopped (none came, or a gap of over STALL_MS).
 */
export class MotionFeed {
  private steps = new StepDetector();
  private yaw = new YawIntegrator();
  private up: Vec3 | null = null;
  private gravity: [number, number, number] | null = null;
  private accel = new Liveness();
  private turns = new Liveness();
  /** The last committed mark of this run; null until the first commit after start(). */
  private base: MotionMark | null = null;
  private run = 0;
  private on = false;

  /** `now`: the clock samples arrive by (ms). */
  constructor(
    private readonly source: MotionSource = globalThis as unknown as MotionSource,
    private readonly now: () => number = () => performance.now(),
  ) {}

  private readonly onMotion = (ev: Event): void => {
    const e = ev as unknown as MotionLike;
    const a = e.accelerationIncludingGravity;
    if (a && a.x !== null && a.y !== null && a.z !== null) {
      const before = this.steps.samples;
      this.steps.add(e.timeStamp, [a.x, a.y, a.z]);
      if (this.steps.samples !== before) this.accel.beat(this.now());
      // gravity's direction, slowly averaged, where the orientation angles are missing
      const g = (this.gravity ??= [a.x, a.y, a.z]);
      for (const [i, v] of [a.x, a.y, a.z].entries()) g[i] += 0.1 * (v - g[i]);
    }
    const r = e.rotationRate;
    const up = this.up ?? this.gravity;
    if (r && up) this.turned(() => this.yaw.rate(e.timeStamp, r, up));
  };

  private readonly onOrientation = (ev: Event): void => {
    const e = ev as unknown as OrientationLike;
    if (e.beta !== null && e.gamma !== null) this.up = upFromOrientation(e.beta, e.gamma);
    this.turned(() => this.yaw.orientation(e.alpha));
  };

  /** A sample for the turn: counts as one only where the integrator took it. */
  private turned(feed: () => void): void {
    const before = this.yaw.samples;
    feed();
    if (this.yaw.samples !== before) this.turns.beat(this.now());
  }

  start(): void {
    if (this.on) return;
    this.on = true;
    this.run++;
    this.steps = new StepDetector();
    this.yaw = new YawIntegrator();
    this.accel = new Liveness();
    this.turns = new Liveness();
    this.base = null;
    this.source.addEventListener('devicemotion', this.onMotion);
    this.source.addEventListener('deviceorientation', this.onOrientation);
  }

  stop(): void {
    if (!this.on) return;
    this.on = false;
    this.source.removeEventListener('devicemotion', this.onMotion);
    this.source.removeEventListener('deviceorientation', this.onOrientation);
  }

  /** Whether a sensor's samples came all through the interval since `from`, and still come. */
  private live(s: Liveness, from: { n: number; stalls: number }): boolean {
    // samples before the interval's start, during it, none stopping, and the last one recent
    return from.n > 0 && s.n > from.n && s.stalls === from.stalls && this.now() - s.last <= STALL_MS;
  }

  /** Steps and turn (degrees, clockwise +) since the last commit, nothing counted as sent yet. */
  peek(): MotionReading {
    if (!this.on) return { steps: null, turn_deg: null, mark: null };
    const mark: MotionMark = {
      run: this.run,
      steps: this.steps.count,
      turn: this.yaw.total,
      accel: { n: this.accel.n, stalls: this.accel.stalls },
      yaw: { n: this.turns.n, stalls: this.turns.stalls },
    };
    const b = this.base;
    return {
      steps: b && this.live(this.accel, b.accel) ? mark.steps - b.steps : null,
      turn_deg: b && this.live(this.turns, b.yaw) ? Math.round((mark.turn - b.turn) * 10) / 10 : null,
      mark,
    };
  }

  /** The request that carried `r` was answered: the next reading counts from r. */
  commit(r: MotionReading): void {
    if (this.on && r.mark && r.mark.run === this.run) this.base = r.mark;
  }
}
