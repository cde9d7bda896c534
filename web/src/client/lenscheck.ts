/**
 * The phone keeps its clip-on lens calibrated by itself (issue 12): at the start of a session, and
 * again when the picture changes abruptly (the lens clipped off and on, a hand over it), the feature
 * worker finds the donut's ring in a few frames and compares it with the profile in use. A lens
 * clipped on a little off is corrected in the worker (said when it moved 2 px or more since the
 * phone last saw it, even in an earlier run of the app); no ring, a ring cut by the picture's edge
 * or one too far off stops "Where am I?" before anything is sent.
 * The frames stay in the worker: only the features of the clip that follows are ever sent.
 */
import type { ExtractorClient, FrameResult } from './bridge';
import type { LensCheck, Look } from '../shared/protocol';

/** Frames the ring is found in (their median), and how far apart they are taken. */
export const CHECK_FRAMES = 5;
export const CHECK_INTERVAL_MS = 80;

export const CORRECTED = 'Lens position corrected.';
export const NOT_ATTACHED =
  'The panoramic lens does not seem to be attached. Clip it on over the camera, then press Where am I? again.';
export const NOT_CENTRED = 'The lens is not centred over the camera; clip it on again.';
export const TOO_FAR =
  'The lens is far from where its profile expects it; clip it on again, or choose its lens profile in Settings.';

/**
 * A correction is said when the profile in use moves by at least this much (px). Not 1: the e2e
 * clips' lens sits 1 px off, and the same clip was "corrected" aloud in some runs and not in others
 * (the engine finds its ring 0.98 px off); 2 px is still under the smallest move of a lens clipped on
 * again (2.5-10 px, docs/benchlog.md "Finding the ring") and far above the finder's error
 * (0.02-0.3 px). Below it the worker still corrects, silently.
 */
export const SAY_PX = 2;
/** Where the correction in use is kept between runs of the app (localStorage): a lens that sits
 * where it sat yesterday is no news, and the user should not hear it each time the app opens. One
 * lens only: a phone that switches between two lens profiles hears the correction again after
 * each switch, as it did before anything was kept. */
export const HELD_KEY = 'omninav.lens-correction';

/** The phone's localStorage, or null where there is none or reading it throws (site data blocked:
 * a SecurityError on the very property, which `typeof` does not guard against). */
export function phoneStorage(): Storage | null {
  try {
    return globalThis.localStorage ?? null;
  } catch {
    return null;
  }
}

/** An abrupt change: the mean grey jumps by this many levels or this share, or the ring's edge fades. */
const MEAN_JUMP = 25;
const MEAN_SHARE = 0.35;
const EDGE_MIN = 10;
const EDGE_KEEP = 0.5;

interface Correction {
  dx: number;
  dy: number;
  scale: number;
}
const NONE: Correction = { dx: 0, dy: 0, scale: 1 };

/** What the phone keeps between runs: the lens (lensPart of the configuration) and its correction. */
interface Held extends Correction {
  lens: string | null;
}

/** The kept correction, or null when none is kept or it is not readable (then nothing is assumed). */
function readHeld(store: Pick<Storage, 'getItem'> | null): Held | null {
  try {
    const h = JSON.parse(store?.getItem(HELD_KEY) ?? 'null') as Partial<Held> | null;
    if (!h || typeof h.lens !== 'string') return null;
    const ok = [h.dx, h.dy, h.scale].every((v) => typeof v === 'number' && Number.isFinite(v));
    return ok ? { lens: h.lens, dx: h.dx!, dy: h.dy!, scale: h.scale! } : null;
  } catch {
    return null;
  }
}

/** What the user hears after a check, and whether "Where am I?" must stop there. */
export function lensWords(c: LensCheck): { text: string; stop: boolean } | null {
  if (c.verdict === 'no_ring') return { text: NOT_ATTACHED, stop: true };
  if (c.verdict === 'cut') return { text: NOT_CENTRED, stop: true };
  if (c.verdict === 'too_far') return { text: TOO_FAR, stop: true };
  return null;
}

/** The median look over a clip's frames (one odd frame does not count as a change). */
export function clipLook(frames: FrameResult[]): Look | null {
  const looks = frames.map((f) => f.look).filter((l): l is Look => !!l);
  if (!looks.length) return null;
  const med = (v: number[]) => v.sort((a, b) => a - b)[v.length >> 1];
  return { mean: med(looks.map((l) => l.mean)), edge: med(looks.map((l) => l.edge)) };
}

/** Has the picture changed abruptly since `base` (the look when the lens was last checked)? */
export function lookChanged(base: Look, now: Look): boolean {
  if (Math.abs(now.mean - base.mean) > Math.max(MEAN_JUMP, MEAN_SHARE * base.mean)) return true;
  // the ring's edge was clear and has faded (NaN now: the lens was taken off and nothing is there)
  return Number.isFinite(base.edge) && base.edge >= EDGE_MIN && !(now.edge >= EDGE_KEEP * base.edge);
}

/** Grab `n` frames `intervalMs` apart and have the worker check the lens on them. */
export async function checkLensOn(
  video: HTMLVideoElement,
  ext: ExtractorClient,
  n = CHECK_FRAMES,
  intervalMs = CHECK_INTERVAL_MS,
): Promise<LensCheck> {
  const bitmaps: ImageBitmap[] = [];
  for (let i = 0; i < n; i++) {
    if (i) await new Promise((r) => setTimeout(r, intervalMs));
    bitmaps.push(await createImageBitmap(video));
  }
  return ext.checkLens(bitmaps);
}

/** The lens of a worker configuration (bridge.ts's key: JSON of [lens, settings]); another key whole. */
export function lensPart(configured: string | null): string | null {
  try {
    const parsed: unknown = configured === null ? null : JSON.parse(configured);
    return Array.isArray(parsed) && parsed.length === 2 ? JSON.stringify(parsed[0]) : configured;
  } catch {
    return configured;
  }
}

/**
 * When the lens must be checked, and what the last check found: the worker's configuration it was
 * made for (a new lens or venue drops the worker's correction), the look then, and the correction
 * in use (so that the same correction found again is not said again).
 */
export class LensWatch {
  private checkedFor: string | null = null;
  private look: Look | null = null;
  /** The correction the worker holds, and the configuration it holds it for (kept across a new
   * camera stream: the same correction found again after the phone was unlocked is not said). */
  private held: Correction = NONE;
  private heldFor: string | null = null;

  /** `store`: where the correction is kept between runs of the app (the app passes localStorage;
   * null keeps it for this run only). */
  constructor(private readonly store: Pick<Storage, 'getItem' | 'setItem'> | null = null) {}

  /** A new camera stream: the lens may have been clipped on again meanwhile. */
  reset(): void {
    this.checkedFor = null;
  }

  /** A check is due: never made for this configuration, or the last one stopped "Where am I?". */
  due(configured: string | null): boolean {
    return this.checkedFor === null || this.checkedFor !== configured;
  }

  /** The clip's frames look unlike the picture at the last check. */
  changed(frames: FrameResult[]): boolean {
    const now = clipLook(frames);
    return !!(this.look && now && lookChanged(this.look, now));
  }

  /**
   * Record a check; -> what to say (null: nothing) and whether to stop. A correction is said when
   * it moves the profile in use by SAY_PX or more.
   */
  record(c: LensCheck, configured: string | null): { text: string; stop: boolean } | null {
    const words = lensWords(c);
    if (words) {
      this.checkedFor = null; // checked again on the next press
      return words;
    }
    // the same lens with the venue's new feature settings (modelled anew) is the same lens on the
    // phone: the worker dropped its correction, but finding it again is no news to the user; nor
    // is the correction this phone held for the lens when the app last ran
    const lens = lensPart(configured);
    const kept = this.heldFor === null ? readHeld(this.store) : null;
    const was = lensPart(this.heldFor) === lens ? this.held : kept && kept.lens === lens ? kept : NONE;
    const now: Correction = c.verdict === 'corrected' ? { dx: c.dx, dy: c.dy, scale: c.scale } : NONE;
    this.checkedFor = configured;
    this.heldFor = configured;
    this.look = c.look;
    this.held = now;
    try {
      this.store?.setItem(HELD_KEY, JSON.stringify({ lens, ...now }));
    } catch {
      // storage full or refused (a private window): the correction is kept for this run only
    }
    // how far the profile in use moved: its centre, plus its ring's edge for a change of scale
    const r = c.ring?.r_outer ?? 0;
    const moved = Math.hypot(now.dx - was.dx, now.dy - was.dy) + Math.abs(now.scale - was.scale) * r;
    return moved >= SAY_PX ? { text: CORRECTED, stop: false } : null;
  }
}
