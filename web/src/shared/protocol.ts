/** Messages between the page and the feature worker (src/worker.ts). */
import type { Lens } from './lens';
import type { FeatureSettings } from './settings';
import type { Ring, Verdict } from '../worker/ring';
import type { LocalBlock } from './record';

/**
 * Two cheap numbers per frame that tell an abrupt change of the picture (the lens clipped off or
 * on, a hand over it): the mean grey level, and the step in grey levels across the profile's outer
 * ring edge (bright inside, dark outside: large while the lens sits where the profile says).
 */
export interface Look {
  mean: number;
  /** NaN for a 360 camera (no ring). */
  edge: number;
}

/** The lens check's outcome: ring.ts's LensFit without the profile, the ring, and the timing. */
export interface LensCheck {
  verdict: Verdict;
  dx: number;
  dy: number;
  scale: number;
  moved_px: number;
  message: string;
  /** The median ring over the frames, or null (none, or a 360 camera: nothing to find). */
  ring: Ring | null;
  /** The picture as it looks now, through the profile now in use: the baseline for changes. */
  look: Look;
  /** Ring finding per frame, ms. */
  ms: number[];
  /**
   * How far the check moved the profile the worker extracts with, in pixels (the ring's centre or
   * radii, whichever moved most; 0: unchanged): frames extracted before it (a clip filmed beside
   * the check) were extracted through the old one.
   */
  changed_px: number;
}

export type ToWorker =
  | { type: 'init'; id: number; lens: Lens; settings: FeatureSettings }
  /** One camera frame; `keep` returns the panorama and curves too (self-test only). */
  | { type: 'frame'; id: number; bitmap: ImageBitmap; keep?: boolean }
  /** A few camera frames: find the ring in each, compare with the profile, use the corrected one. */
  | { type: 'lens'; id: number; bitmaps: ImageBitmap[] }
  /** From now on keep frames for local features, `n` ORB keypoints (0: none), the detector made ready now. */
  | { type: 'prepare'; id: number; n: number }
  /** The local features of a frame extracted lately (`frame`: its 'frame' request's id; worker/local.ts). */
  | { type: 'local'; id: number; frame: number };

export type FromWorker =
  | { type: 'ready'; id: number; loadMs: number }
  | {
      type: 'features';
      id: number;
      mag: Uint16Array;
      phase: Int16Array;
      ms: number;
      look: Look;
      pano?: Uint8Array;
      curves?: Float32Array;
    }
  | { type: 'lens'; id: number; check: LensCheck }
  | ({ type: 'local'; id: number; ms: number } & LocalBlock)
  | { type: 'prepared'; id: number; ms: number }
  | { type: 'error'; id?: number; message: string };
