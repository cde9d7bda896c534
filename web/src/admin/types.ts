/**
 * The admin API's types (backend/omninav/server/openapi.yaml, the /api/admin paths), as the admin
 * page reads them. The public types (Venue, Floor, Place, Lens) are in ../shared/api-types.ts.
 */
import type { Venue } from '../shared/api-types';

export interface AdminVenue extends Venue {
  /** The live generation of modelled frames (null before the first modelling). */
  generation: number | null;
  modelled_at: number | null;
  /** Whether the live generation's feature settings are the preset's now (null: never modelled). */
  settings_current: boolean | null;
  /** The settings id of the venue's preset now (what a modelling anew gives it). */
  preset_settings_id: number;
}

/** DELETE /api/admin/venues/{id}. */
export interface VenueDeleted {
  deleted: string;
  frames_removed: number;
  videos_removed: number;
}

/**
 * The body of a 412 (a write's If-Match named an older revision: another tab saved first). The
 * current revision is in both `revision` and `details.revision`; nothing was written.
 */
export interface StaleError {
  error: string;
  status: 412;
  revision: number;
  details: { revision: number };
}

export interface Waypoint {
  frame?: number;
  /** Seconds from the video's start; used instead of `frame` when both are given. */
  t?: number;
  x: number;
  y: number;
}

export interface WalkPath {
  fps?: number;
  heading_offset_deg?: number;
  waypoints: Waypoint[];
}

export interface Suggestion {
  t: number;
  kind: 'start' | 'turn' | 'stop' | 'end';
  /** Signed, + = clockwise (a right turn). */
  turn_deg: number | null;
  duration_s: number | null;
}

export interface Suggestions {
  duration_s: number;
  fps: number;
  frames: number;
  suggestions: Suggestion[];
  /** [t, cumulative relative heading in degrees], about two samples a second. */
  heading: [number, number][];
  /** Does the video fit its lens profile (on its first frames)? null: no ring to check, or older. */
  lens_check?: LensCheck | null;
}

export interface LensCheck {
  verdict: 'same' | 'corrected' | 'too_far' | 'cut' | 'no_ring';
  fits: boolean;
  message: string;
  moved_px: number;
  dx: number;
  dy: number;
  scale: number;
}

/** GET .../videos/{name}/frame?t=&view=&width= (image/jpeg). */
export type FrameView = 'raw' | 'panorama';

export interface Video {
  name: string;
  floor: string;
  lens: string;
  role: 'model' | 'evaluation';
  size: number;
  received: number;
  status: 'uploading' | 'ready' | 'modelled';
  frames: number;
  has_walk_path: boolean;
  walk_path: WalkPath | null;
  duration_s: number | null;
  fps: number | null;
  width: number | null;
  height: number | null;
  error: string | null;
  suggestions: Suggestions | null;
  upload_url: string;
}

export type JobKind = Job['kind'];

export interface Job {
  id: string;
  venue: string;
  kind: 'model' | 'suggest' | 'quality' | 'evaluate';
  target: string | null;
  /** A modelling anew: every modelling video, with the venue's preset as the server defines it now. */
  anew: boolean;
  videos: string[];
  state: 'queued' | 'running' | 'done' | 'failed' | 'cancelled';
  frames_done: number;
  frames_total: number;
  frames_per_s: number;
  eta_s: number | null;
  created: number;
  started: number | null;
  finished: number | null;
  attempts: number;
  max_attempts: number;
  retry_at: number | null;
  error: string | null;
  result_url: string | null;
}

export type Verdict = 'green' | 'amber' | 'red';

export interface QualitySegment {
  video: string;
  floor: string;
  t0: number;
  t1: number;
  points: [number, number][];
  verdict: Verdict;
  error_m: number | null;
  margin: number | null;
  query: { video: string; t: number };
  match: { video: string; t: number; x: number; y: number };
}

export interface QualityCorridor {
  place: string;
  floor: string;
  area: [number, number, number, number];
  covered: number;
  verdict: Verdict | 'grey';
  share_green: number | null;
  directions: { forward: boolean; backward: boolean };
}

export interface Quality {
  generation: number | null;
  frames: number;
  radius_m: number;
  segments: QualitySegment[];
  corridors: QualityCorridor[];
  summary: { share_green: number; ambiguous: number; wrong: number; uncovered: string[]; one_direction: string[] };
  sentence: string;
}

export interface Pose {
  x: number;
  y: number;
  heading_deg: number;
}

export interface EvaluationClip {
  t: number;
  truth: Pose;
  answer: (Pose & { confidence: number; low_confidence: boolean }) | null;
  error_m: number | null;
  heading_error_deg: number | null;
}

export interface Evaluation {
  clips: EvaluationClip[];
  summary: {
    clips: number;
    within_1m: number;
    within_2m: number;
    median_error_m: number | null;
    median_heading_error_deg: number | null;
    not_sure: number;
    /** Said as "You are probably ...": a place, under the sure line (0.8). Absent from results stored before it. */
    probably?: number;
    /** Said as sure (0.8 or more) and further than 2 m off: what would mislead a user. Absent before it too. */
    sure_over_2m?: number;
  };
}
