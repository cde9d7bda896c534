/**
 * The venue's first-run checklist: what it still lacks for the phone to be useful, each step with
 * the screen that does it, from the venue document and, once read, its videos and jobs.
 */
import type { Place, Venue } from '../shared/api-types';
import type { ScreenId } from './routes';
import { inArea } from './geometry';
import { fromWalkPath, positionAt } from './walk-path-edit';
import type { Job, Video } from './types';

export interface Step {
  screen: ScreenId;
  /** What is missing, as the link says it. */
  text: string;
  /** The screen's query (the walk path screen's video). */
  params?: Record<string, string>;
}

const hasPoints = (places: readonly Place[]): boolean => places.some((p) => !p.area);
const hasAreas = (places: readonly Place[]): boolean => places.some((p) => p.area);

/**
 * What a venue's places leave the phone unable to say, in words for the venue's header (null:
 * nothing): with no place at all an answer is the floor alone; with places but no area, the
 * nearest place and how far, never the corridor the user is in. (What to do about it: stepsLeft.)
 */
export function placeGaps(places: readonly Place[]): string | null {
  if (places.length === 0) return 'No places yet: the phone can only say the floor.';
  if (!hasAreas(places))
    return 'No place has an area: the phone names the nearest place and how far it is, never the corridor the user is in.';
  return null;
}

/** What the checklist knows beyond the venue document: its videos and jobs (null: not read yet). */
export interface Progress {
  videos: readonly Video[];
  jobs: readonly Job[];
}

/** Seconds of walk in no drawn area below which the areas step counts as done (a doorway's worth). */
export const UNZONED_S = 5;

/**
 * How many whole seconds of the tagged modelling walks lie in no area of their floor (each second
 * judged at its middle, on the walk path between its waypoints), of how many tagged seconds.
 */
export function walkOutsideAreas(videos: readonly Video[], places: readonly Place[]): { outside: number; all: number } {
  let outside = 0;
  let all = 0;
  for (const v of videos) {
    if (v.role !== 'model' || !v.walk_path) continue;
    const pts = fromWalkPath(v.walk_path, v.fps ?? 30);
    if (pts.length < 2) continue;
    const areas = places.filter((p) => p.floor === v.floor && p.area).map((p) => p.area!);
    for (let t = Math.ceil(pts[0].t); t + 1 <= pts[pts.length - 1].t; t++) {
      const at = positionAt(pts, t + 0.5);
      if (!at) continue;
      all++;
      if (!areas.some((a) => inArea(a, at.x, at.y))) outside++;
    }
  }
  return { outside, all };
}

/** A job of that kind done since the live modelling (`since`, Unix s; null: not known): one before it judged other frames. */
const done = (jobs: readonly Job[], kind: Job['kind'], since: number | null) =>
  jobs.some((j) => j.kind === kind && j.state === 'done' && (since === null || (j.finished ?? 0) >= since));

/**
 * The steps still to do, in the order a new admin does them (none: the venue is ready). With the
 * venue's videos and jobs it says which walk to tag, whether the walked corridors all have areas,
 * and whether the quality map and an evaluation walk were done; without them, what the venue
 * document alone shows.
 */
export function stepsLeft(v: Venue & { modelled_at?: number | null }, progress: Progress | null = null): Step[] {
  const since = v.modelled_at ?? null;
  const areas = (): [boolean, Step] => {
    if (!hasAreas(v.places) || !progress)
      return [
        hasAreas(v.places),
        { screen: 'places', text: 'Draw the walked corridors as areas (the phone then says which one the user is in)' },
      ];
    const { outside, all } = walkOutsideAreas(progress.videos, v.places);
    return [
      outside < UNZONED_S,
      {
        screen: 'places',
        text: `Draw areas along the rest of the walked corridors (${outside} of the walk's ${all} seconds are in none)`,
      },
    ];
  };
  const steps: [boolean, Step][] = [
    [v.floors.every((f) => f.plan_url), { screen: 'floor', text: 'Upload the floor plan' }],
    [v.floors.every((f) => f.px_per_m), { screen: 'floor', text: 'Set the plan’s scale (two clicks and a distance)' }],
    [hasPoints(v.places), { screen: 'places', text: 'Add the places people go to (rooms, lifts, entrances)' }],
    areas(),
    [Object.keys(v.lenses).length > 0, { screen: 'lenses', text: 'Add the lens profile of the modelling camera' }],
  ];
  if (!progress) {
    steps.push([v.modelled, { screen: 'videos', text: 'Upload a modelling walk, tag its walk path and model it' }]);
    return steps.filter(([ok]) => !ok).map(([, s]) => s);
  }
  const walks = progress.videos.filter((w) => w.role === 'model' && w.status !== 'uploading');
  const untagged = walks.find((w) => !w.has_walk_path);
  steps.push(
    [walks.length > 0, { screen: 'videos', text: 'Upload a modelling walk' }],
    // before any walk, its tagging is a step still to come, not one done
    [
      walks.length > 0 && !untagged,
      untagged
        ? { screen: 'walk-path', text: `Tag the walk path of ${untagged.name}`, params: { video: untagged.name } }
        : { screen: 'walk-path', text: 'Tag the walk path (where the walker was)' },
    ],
    [
      v.modelled && !walks.some((w) => w.has_walk_path && w.status === 'ready'),
      { screen: 'modelling', text: v.modelled ? 'Model the newly tagged walks' : 'Model the tagged walks' },
    ],
    [done(progress.jobs, 'quality', since), { screen: 'quality', text: 'Compute the quality map' }],
    [
      done(progress.jobs, 'evaluate', since),
      { screen: 'evaluation', text: 'Upload an evaluation walk, tag it and evaluate it' },
    ],
  );
  return steps.filter(([ok]) => !ok).map(([, s]) => s);
}
