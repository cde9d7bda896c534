/**
 * The walk path being tagged, without the DOM (unit-tested in Node): waypoints kept in time order,
 * snapping to corridor lines, the words for a suggested waypoint, and the walk_path.json written from
 * them (docs/formats.md "Modelling walk path"). Times in seconds of the video, positions in metres.
 */
import type { Place } from '../shared/api-types';
import { formatDuration, formatTime } from './format';
import type { Suggestion, WalkPath, Waypoint } from './types';

/** A waypoint as the editor holds it: always a time (a `frame` is turned into seconds on load). */
export interface Point {
  t: number;
  x: number;
  y: number;
}

/** Two waypoints closer in time than this are one moment (one is replaced, not added). */
export const SAME_MOMENT_S = 0.05;

/** Waypoints of a walk_path.json as editor points, in time order (`t` wins over `frame`). */
export function fromWalkPath(walkPath: WalkPath | null, defaultFps = 30): Point[] {
  if (!walkPath) return [];
  const fps = walkPath.fps ?? defaultFps;
  return walkPath.waypoints
    .map((w: Waypoint) => ({ t: w.t ?? (w.frame ?? 0) / fps, x: w.x, y: w.y }))
    .sort((a, b) => a.t - b.t);
}

/** The walk_path.json of the editor's points: times in seconds (ms precision), positions to the cm. */
export function toWalkPath(points: readonly Point[], headingOffsetDeg = 0): WalkPath {
  const r = (v: number, k: number): number => Math.round(v * k) / k;
  const walkPath: WalkPath = { waypoints: points.map((p) => ({ t: r(p.t, 1000), x: r(p.x, 100), y: r(p.y, 100) })) };
  if (headingOffsetDeg) walkPath.heading_offset_deg = r(headingOffsetDeg, 10);
  return walkPath;
}

/** Add a waypoint (or move the one at the same moment); -> the new list, in time order. */
export function putPoint(points: readonly Point[], p: Point): Point[] {
  const rest = points.filter((q) => Math.abs(q.t - p.t) >= SAME_MOMENT_S);
  return [...rest, p].sort((a, b) => a.t - b.t);
}

/**
 * "Add a waypoint at the current time": -> the new points (the same where one is already at that
 * moment), what to say, and the moment of the waypoint whose x the focus goes to. Between two
 * waypoints the new one is where a steady walk between them puts it; before the first or after
 * the last it starts at that waypoint's place, and the words say so: its x and y are for the
 * admin to type (or a click on the plan puts it there).
 */
export function addAt(points: readonly Point[], t: number): { points: Point[]; said: string; at: number } {
  const there = points.find((q) => Math.abs(q.t - t) < SAME_MOMENT_S);
  if (there)
    return {
      points: [...points],
      said: `A waypoint is already at ${formatTime(there.t)}: its x and y are in the table.`,
      at: there.t,
    };
  const between = positionAt(points, t);
  if (between)
    return {
      points: putPoint(points, { t, ...between }),
      said: `Waypoint added at ${formatTime(t)}, on the straight line between its neighbours; correct its x and y in the table if the walk turned.`,
      at: t,
    };
  const near = points.length ? (t < points[0].t ? points[0] : points[points.length - 1]) : null;
  const from = near ? `at the place of the waypoint at ${formatTime(near.t)}` : 'at 0, 0';
  return {
    points: putPoint(points, { t, x: near?.x ?? 0, y: near?.y ?? 0 }),
    said: `Waypoint added at ${formatTime(t)} ${from}: type where the walker was (its x and y), or click the plan there.`,
    at: t,
  };
}

/** What is wrong with the points as a walk path, in words, or null when it can be saved. */
export function walkPathProblem(points: readonly Point[], duration: number | null): string | null {
  if (points.length < 2) return 'A walk path needs at least two waypoints: where the walk starts and where it ends.';
  for (let i = 0; i < points.length; i++) {
    const p = points[i];
    if (![p.t, p.x, p.y].every(Number.isFinite)) return `Waypoint ${i + 1} has a value that is not a number.`;
    if (p.t < 0) return `Waypoint ${i + 1} is before the video starts.`;
    if (duration !== null && p.t > duration + 0.5)
      return `Waypoint ${i + 1} (${formatTime(p.t)}) is after the video ends (${formatTime(duration)}).`;
    if (i > 0 && !(p.t > points[i - 1].t))
      return `Waypoint ${i + 1} (${formatTime(p.t)}) is not after waypoint ${i} (${formatTime(points[i - 1].t)}).`;
  }
  return null;
}

/** Where the walker was at `t` (linear between waypoints), or null outside the tagged span. */
export function positionAt(points: readonly Point[], t: number): { x: number; y: number } | null {
  if (points.length === 0 || t < points[0].t || t > points[points.length - 1].t) return null;
  for (let i = 1; i < points.length; i++) {
    const a = points[i - 1];
    const b = points[i];
    if (t <= b.t) {
      const k = b.t > a.t ? (t - a.t) / (b.t - a.t) : 0;
      return { x: a.x + k * (b.x - a.x), y: a.y + k * (b.y - a.y) };
    }
  }
  return { x: points[0].x, y: points[0].y };
}

// ---- corridor lines -------------------------------------------------------------------------------

/** A corridor's centre line: from (x0, y0) to (x1, y1) along the long axis of its area. */
export interface Line {
  place: string;
  x0: number;
  y0: number;
  x1: number;
  y1: number;
}

/** The centre lines of the floor's places that have an area, along each area's long axis. */
export function corridorLines(places: readonly Place[], floor: string): Line[] {
  return places
    .filter((p) => p.floor === floor && p.area)
    .map((p) => {
      const [x0, y0, x1, y1] = p.area as [number, number, number, number];
      const cx = (x0 + x1) / 2;
      const cy = (y0 + y1) / 2;
      return Math.abs(x1 - x0) >= Math.abs(y1 - y0)
        ? { place: p.name, x0, y0: cy, x1, y1: cy }
        : { place: p.name, x0: cx, y0, x1: cx, y1 };
    });
}

/** The point of segment `l` nearest to (x, y), and its distance (`clamp` false: of the infinite line through it). */
export function nearestOn(l: Line, x: number, y: number, clamp = true): { x: number; y: number; d: number } {
  const dx = l.x1 - l.x0;
  const dy = l.y1 - l.y0;
  const len2 = dx * dx + dy * dy;
  const along = len2 > 0 ? ((x - l.x0) * dx + (y - l.y0) * dy) / len2 : 0;
  const k = clamp ? Math.min(1, Math.max(0, along)) : along;
  const px = l.x0 + k * dx;
  const py = l.y0 + k * dy;
  return { x: px, y: py, d: Math.hypot(x - px, y - py) };
}

/** Where the (infinite) lines through two segments cross, or null when they are parallel. */
function crossing(a: Line, b: Line): { x: number; y: number } | null {
  const d1x = a.x1 - a.x0;
  const d1y = a.y1 - a.y0;
  const d2x = b.x1 - b.x0;
  const d2y = b.y1 - b.y0;
  const den = d1x * d2y - d1y * d2x;
  if (Math.abs(den) < 1e-9) return null;
  const k = ((b.x0 - a.x0) * d2y - (b.y0 - a.y0) * d2x) / den;
  return { x: a.x0 + k * d1x, y: a.y0 + k * d1y };
}

/**
 * A clicked point snapped to the corridor lines within `maxM` metres: to the crossing of two lines
 * when both are that close and so is their crossing (a corner, where a turn's waypoint belongs),
 * else onto the nearest line; unchanged when no line is that close. `line` names where it went.
 */
export function snapToLines(
  p: { x: number; y: number },
  lines: readonly Line[],
  maxM = 3,
): { x: number; y: number; line: string | null } {
  const near = lines
    .map((l) => ({ l, n: nearestOn(l, p.x, p.y) }))
    .filter((c) => c.n.d <= maxM)
    .sort((a, b) => a.n.d - b.n.d);
  if (!near.length) return { x: p.x, y: p.y, line: null };
  let best: { x: number; y: number; line: string; d: number } | null = null;
  for (let i = 0; i < near.length; i++) {
    for (let j = i + 1; j < near.length; j++) {
      const c = crossing(near[i].l, near[j].l);
      if (!c) continue;
      // the crossing must lie on (or within maxM of) both segments: two corridors that meet
      if (nearestOn(near[i].l, c.x, c.y).d > maxM || nearestOn(near[j].l, c.x, c.y).d > maxM) continue;
      const d = Math.hypot(c.x - p.x, c.y - p.y);
      if (d <= maxM && (!best || d < best.d)) best = { ...c, line: `${near[i].l.place} × ${near[j].l.place}`, d };
    }
  }
  if (best) return { x: best.x, y: best.y, line: best.line };
  // onto one line: only across it. Past the end of its area (a corner whose other corridor has no
  // area) the click keeps how far along it is: pulled to the line's end, a corner moved 2 m back
  const { l } = near[0];
  const across = nearestOn(l, p.x, p.y, false);
  return { x: across.x, y: across.y, line: l.place };
}

/** How far a snap moved a click, in words for the status: "", or " (on Corridor 1, moved 0.4 m)". */
export function snapWords(click: { x: number; y: number }, s: { x: number; y: number; line: string | null }): string {
  if (!s.line) return '';
  return ` (on ${s.line}, moved ${Math.hypot(s.x - click.x, s.y - click.y).toFixed(1)} m)`;
}

/** The floor's named places (not areas) in words, beside the walk path's plan: what to tag the walk by. */
export function landmarkLine(places: readonly Place[], floor: string): string {
  const named = places.filter((p) => p.floor === floor && !p.area);
  if (!named.length) return 'No named place on this floor to tag the walk by: add them on the Places screen.';
  return `Places on this floor: ${named.map((p) => `${p.name} at (${p.x.toFixed(1)}, ${p.y.toFixed(1)}) m`).join('; ')}.`;
}

// ---- suggestions ----------------------------------------------------------------------------------

/** "turn right 90°", "turn left 45°", "turn around", "stop 4 s", "start", "end". */
export function suggestionLabel(s: Suggestion): string {
  switch (s.kind) {
    case 'start':
      return 'start';
    case 'end':
      return 'end';
    case 'stop':
      return s.duration_s !== null ? `stop ${formatDuration(Math.max(1, s.duration_s))}` : 'stop';
    case 'turn': {
      const d = s.turn_deg ?? 0;
      const deg = Math.round(Math.abs(d) / 5) * 5;
      if (deg >= 160) return 'turn around';
      return `turn ${d >= 0 ? 'right' : 'left'} ${deg}°`;
    }
  }
}

/** "0:12.4, turn right 90°": a suggestion as a list item or a button names it. */
export const suggestionText = (s: Suggestion): string => `${formatTime(s.t)}, ${suggestionLabel(s)}`;

/** The times a suggestion wants tagged: a stop has two (it starts and it ends; the walker stays put). */
export function suggestionTimes(s: Suggestion): number[] {
  if (s.kind === 'stop' && s.duration_s !== null && s.duration_s > SAME_MOMENT_S) return [s.t, s.t + s.duration_s];
  return [s.t];
}

/** Whether the points already have a waypoint at the suggestion's (first) time. */
export function isTagged(s: Suggestion, points: readonly Point[], tolerance = 0.25): boolean {
  return points.some((p) => Math.abs(p.t - s.t) <= tolerance);
}

/** Index of the first suggestion at or after `from` in `suggestions` that has no waypoint yet, or -1. */
export function nextUntagged(suggestions: readonly Suggestion[], points: readonly Point[], from = 0): number {
  for (let i = Math.max(0, from); i < suggestions.length; i++) if (!isTagged(suggestions[i], points)) return i;
  return -1;
}

/**
 * Accept a suggestion at a plan position: a waypoint at its time (and one at the end of a stop, at
 * the same place); -> the new points.
 */
export function acceptSuggestion(points: readonly Point[], s: Suggestion, at: { x: number; y: number }): Point[] {
  let out = [...points];
  for (const t of suggestionTimes(s)) out = putPoint(out, { t, x: at.x, y: at.y });
  return out;
}

/** Panorama column (0..1 of its width) of the walking direction: forward is the centre, and the
 * lens looks `headingOffsetDeg` clockwise of where the walker goes, so the walk is that far left. */
export function walkColumn(headingOffsetDeg: number): number {
  const f = 0.5 - headingOffsetDeg / 360;
  return f - Math.floor(f);
}
