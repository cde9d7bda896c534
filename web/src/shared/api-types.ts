/**
 * The public API's types, one interface per schema of backend/omninav/server/openapi.yaml (same
 * name, same properties, optional exactly where the schema does not require them, `| null` exactly
 * where it allows null). web/tests/api-types.test.ts compares them with the schemas.
 */
import type { Lens } from './lens';
import type { VenueFeatures } from './settings';

export interface Place {
  id: string;
  floor: string;
  name: string;
  x: number;
  y: number;
  /** A region one can be in, [x0, y0, x1, y1] in metres. */
  area?: [number, number, number, number];
  /** What it is (docs/formats.md); a lift or stairs of one name on two floors joins them. */
  kind?: 'room' | 'door' | 'lift' | 'stairs' | 'exit' | 'toilet' | 'desk' | 'other';
  /** A sentence to speak on arrival. */
  say?: string;
}

export interface Floor {
  id: string;
  name: string;
  plan_url: string | null;
  plan_size_px: [number, number] | null;
  px_per_m: number | null;
}

export interface Venue {
  id: string;
  name: string;
  revision: number;
  modelled: boolean;
  frames: number;
  floors: Floor[];
  places: Place[];
  lenses: Record<string, Lens>;
  features: VenueFeatures;
}

/** The nearest point place: how far, and its bearing clockwise from the heading, in (-180, 180]. */
export interface Nearest {
  name: string;
  distance_m: number;
  bearing_deg: number;
}

/** A localisation answer (docs/formats.md) with the words the server adds. */
export interface Answer {
  clip: string;
  x: number;
  y: number;
  heading_deg: number;
  confidence: number;
  floor: string;
  place: string | null;
  frame: number;
  area: string | null;
  nearest: Nearest | null;
  facing: string | null;
  /** The sentence in the default style, for API clients; the app makes its own (directions.ts). */
  sentence: string;
  low_confidence: boolean;
  accuracy_m: number | null;
  frames: number;
  sent: 'features' | 'frames';
  /** Only where the venue checked the clip by its keypoints: what that made of the answer. */
  verified?: 'moved' | 'confirmed' | 'unconfirmed';
  plan_png?: string | null;
  /** With ?session=: the filter's state (the pose fields above are then the filtered pose's). */
  tracking?: Tracking;
  /** With ?session=&to=: the next instruction towards the chosen place. */
  guidance?: Guidance;
}

/** The clip's own single-clip estimate, beside the filtered pose of a tracked answer. */
export interface TrackingSingle {
  x: number;
  y: number;
  heading_deg: number;
  confidence: number;
}

/**
 * A tracking session's state in a locate answer. `restarted`: the filter started over at this
 * request, `reason` says why ("new": an unknown session, "expired": idle too long or the clock `t`
 * jumped ahead more than the session's life, "venue changed": the venue was modelled again since,
 * "clock": `t` went backwards); null when the session continued.
 */
export interface Tracking {
  session: string;
  restarted: boolean;
  reason: 'new' | 'expired' | 'venue changed' | 'clock' | null;
  /** Updates the filter has had in this session, this request's included (a 2 s clip: two, a second each). */
  updates: number;
  single: TrackingSingle;
}

/** The place a guidance leads to. */
export interface GuidanceTarget {
  id: string;
  name: string;
  floor: string;
  /** The place's sentence to speak on arrival, when it has one. */
  say?: string;
}

/** A floor change on the route ahead: take the lift or the stairs to another floor. */
export interface FloorChange {
  via: 'lift' | 'stairs';
  to_floor: string;
  to_floor_name: string;
}

/** A route in numbers, said before starting: "Room 102: 45 metres, 2 turns, first turn after 12 metres." */
export interface RoutePreview {
  length_m: number;
  turns: number;
  first_turn_m: number | null;
  floors: string[];
}

/** The next instruction towards the place of `to` (docs/formats.md). */
export interface Guidance {
  to: GuidanceTarget;
  /**
   * `probably_arrived`: within ~2 m of the place but the pose is under 0.8 or the track has not
   * settled (more than a third of the last 30 s of answers low); said as "You are probably at
   * ...", and guidance goes on (only `arrived` ends it). `not_here`: more than half the answers of
   * a whole minute's guidance were low ("You may be outside the mapped area; ..."), said once until
   * the answers settle again.
   */
  kind:
    | 'start'
    | 'turn'
    | 'continue'
    | 'reassure'
    | 'off_route'
    | 'arrived'
    | 'probably_arrived'
    | 'back_on_route'
    | 'floor_change'
    | 'unsure'
    | 'not_here';
  /** Say it now (false: nothing new since the last spoken sentence). */
  speak: boolean;
  /** Cut in (off the route, arrived or probably arrived). */
  urgent: boolean;
  /** Where to face to walk the route (on arrival: where the place is), clockwise from the heading, (-180, 180]. */
  bearing_deg: number | null;
  walk_m: number | null;
  /** What is at the end of this walk: a place's name, "the end of the corridor", "the junction". */
  until: string | null;
  /**
   * Metres still to walk to the corner where the instruction's turn is, when it is said before the
   * corner ("In 3 metres, turn to 9 o'clock and walk 9 metres, to Room 1."); null at the corner, and
   * on kinds other than start, turn and continue.
   */
  in_m: number | null;
  next_turn_m: number | null;
  remaining_m: number | null;
  on_route: boolean;
  arrived: boolean;
  floor_change: FloorChange | null;
  /** On kind "start" only: the whole route in numbers. */
  preview?: RoutePreview;
  /** The route ahead on the user's floor, [x, y] plan metres. */
  route: [number, number][];
  /** The instruction in the default style (or ?style=); the app makes its own in the user's style. */
  sentence: string;
}

/** A place one can be guided to. */
export interface Destination {
  id: string;
  name: string;
  kind: 'room' | 'door' | 'lift' | 'stairs' | 'exit' | 'toilet' | 'desk' | 'other' | null;
  x: number;
  y: number;
}

export interface DestinationFloor {
  id: string;
  name: string;
  /** Sorted by name as a list files it: without case or a leading article, numbers by value. */
  places: Destination[];
}

/** GET /api/venues/{id}/destinations: the places that attach to the walk graph, by floor. */
export interface Destinations {
  venue: string;
  floors: DestinationFloor[];
}
