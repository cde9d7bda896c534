/**
 * The last second, ready at the press. While the camera is open and nothing else films, and the
 * app allows it (the locate or Go to screen shown, the page visible, the phone not lying flat, the
 * user has not turned it off in Settings), the feature worker extracts a frame every 100 ms and the
 * features of the last `size` frames are kept: a ring of about 9 KB of numbers, never a picture.
 * "Where am I?" sends them at once instead of filming a second first; "Keep telling me" and
 * guidance take them as the first second of their clips.
 *
 * A frame is taken once: `take` empties the ring, and so does any pause (a press filming, the
 * screen changed), so that a clip never holds a frame sent before or one older than the pause.
 * Frames extracted through another lens profile than the worker's now are never taken.
 *
 * What it costs is measured as it runs: `duty()` is the share of the time the worker spent
 * extracting while standing by (the battery's and the heat's measure; the details panel shows it).
 */
import type { FrameResult } from './bridge';
import { clipFps, type Clip } from './camera';

/** A kept frame: its features, when it was grabbed (performance.now()), the worker configuration then. */
export interface Kept {
  frame: FrameResult;
  t: number;
  key: string | null;
}

/** A frame counts as fresh within this many intervals of the press. */
const FRESH_INTERVALS = 2.5;
/** Frames further apart than this many intervals are not one clip (a stall, a slow phone's backlog). */
const GAP_INTERVALS = 3;
/** How often a paused standby looks again whether it may run. */
const PAUSED_POLL_MS = 250;
/** Frames in the worker at once: a slow phone falls behind by skipping frames, never by queueing them. */
const IN_FLIGHT = 2;

/**
 * The last `n` kept frames as a clip, or null when they do not make one: fewer than `n`, the newest
 * older than FRESH_INTERVALS at `now`, a gap over GAP_INTERVALS, or a frame of another
 * configuration than `key`.
 */
export function clipOf(
  ring: readonly Kept[],
  n: number,
  now: number,
  intervalMs: number,
  key: string | null,
): Clip | null {
  if (ring.length < n || n < 1) return null;
  const last = ring.slice(-n);
  if (now - last[last.length - 1].t > FRESH_INTERVALS * intervalMs) return null;
  for (let i = 0; i < last.length; i++) {
    if (last[i].key !== key) return null;
    if (i && last[i].t - last[i - 1].t > GAP_INTERVALS * intervalMs) return null;
  }
  const [startMs, endMs] = [last[0].t, last[last.length - 1].t];
  return { frames: last.map((k) => k.frame), fps: clipFps(n, startMs, endMs), startMs, endMs };
}

export interface StandbyOptions {
  /** Frames kept: one clip's worth. */
  size: number;
  intervalMs: number;
  /** Grab and extract a frame now, or null when there is nothing to grab now (a press films, no camera). */
  grab: () => Promise<FrameResult> | null;
  /** Standing by is allowed now (checked before each frame). */
  allowed: () => boolean;
  /** The worker's configuration now (bridge.ts's `configured`). */
  key: () => string | null;
  /** There is nothing to stand by for any more (the camera ended): it stops until started again. */
  gone?: () => boolean;
  now?: () => number;
}

export class Standby {
  private ring: Kept[] = [];
  private timer: ReturnType<typeof setTimeout> | null = null;
  /** Bumped by every clear: a frame grabbed before it is not kept. */
  private generation = 0;
  private inFlight = 0;
  private nextDue = 0;
  /** The worker's time on standby frames and the time standing by, since the last pause. */
  private busyMs = 0;
  private spanMs = 0;
  private readonly now: () => number;

  constructor(private readonly o: StandbyOptions) {
    this.now = o.now ?? (() => performance.now());
  }

  /** Stand by from now on (again: nothing changes). */
  start(): void {
    if (this.timer === null) this.schedule(0);
  }

  /** Stand by no more; the ring is emptied. */
  stop(): void {
    if (this.timer !== null) clearTimeout(this.timer);
    this.timer = null;
    this.clear();
  }

  /** Frames kept now. */
  get kept(): number {
    return this.ring.length;
  }

  /** The last second as a clip (see clipOf), taken out of the ring; null when it does not make one. */
  take(): Clip | null {
    const clip = clipOf(this.ring, this.o.size, this.now(), this.o.intervalMs, this.o.key());
    this.clear();
    return clip;
  }

  /** The share of the time (0-1) the worker spent extracting while standing by; null before a second of it. */
  duty(): number | null {
    return this.spanMs >= 1000 ? this.busyMs / this.spanMs : null;
  }

  private clear(): void {
    this.ring = [];
    this.generation++;
  }

  private schedule(ms: number): void {
    this.timer = setTimeout(() => this.tick(), Math.max(0, ms));
  }

  private tick(): void {
    if (this.o.gone?.()) {
      this.stop();
      return;
    }
    const now = this.now();
    if (!this.o.allowed()) {
      if (this.ring.length) this.clear();
      [this.spanMs, this.busyMs] = [0, 0];
      this.schedule(PAUSED_POLL_MS);
      return;
    }
    // a full worker skips this frame (its time still counts); nothing to grab (a press films) does not count
    const job = this.inFlight < IN_FLIGHT ? this.o.grab() : undefined;
    if (job !== null) this.spanMs += this.o.intervalMs;
    if (job) {
      const [generation, key] = [this.generation, this.o.key()];
      this.inFlight++;
      job
        .then((frame) => {
          this.busyMs += frame.ms;
          if (generation !== this.generation) return;
          this.ring.push({ frame, t: now, key });
          if (this.ring.length > this.o.size) this.ring.splice(0, this.ring.length - this.o.size);
        })
        .catch(() => this.clear()) // a frame lost: the ring would have a gap
        .finally(() => this.inFlight--);
    }
    // frames `intervalMs` apart on the clock, however long a tick took (late: from now)
    this.nextDue += this.o.intervalMs;
    if (this.nextDue <= now) this.nextDue = now + this.o.intervalMs;
    this.schedule(this.nextDue - this.now());
  }
}

/** Within this many degrees of level, a phone lies flat (on a table, face up or down). */
export const FLAT_DEG = 20;

/** The phone lies flat by its orientation's beta and gamma (degrees): its camera sees ceiling or table. */
export function lyingFlat(betaDeg: number, gammaDeg: number): boolean {
  const b = Math.abs(betaDeg);
  return Math.abs(gammaDeg) < FLAT_DEG && (b < FLAT_DEG || b > 180 - FLAT_DEG);
}

/**
 * The phone's posture from `deviceorientation`: flat or not, by the last reading. Without readings
 * (no sensor, or iOS before the user allowed motion) it is never flat.
 */
export class Posture {
  flat = false;

  constructor(target: Pick<Window, 'addEventListener'> = window) {
    target.addEventListener('deviceorientation', (e: DeviceOrientationEvent) => {
      if (e.beta !== null && e.gamma !== null) this.flat = lyingFlat(e.beta, e.gamma);
    });
  }
}
