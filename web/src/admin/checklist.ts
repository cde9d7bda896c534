/**
 * The venue's first-run checklist: what it still lacks for the phone to be useful, each step with
 * the screen that does it, from the venue document alone (so the header can show it at once).
 */
import type { Place, Venue } from '../shared/api-types';
import type { ScreenId } from './routes';

export interface Step {
  screen: ScreenId;
  /** What is missing, as the link says it. */
  text: string;
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

/** The steps still to do, in the order a new admin does them (none: the venue is ready). */
export function stepsLeft(v: Venue): Step[] {
  const steps: [boolean, Step][] = [
    [v.floors.every((f) => f.plan_url), { screen: 'floor', text: 'Upload the floor plan' }],
    [v.floors.every((f) => f.px_per_m), { screen: 'floor', text: 'Set the plan’s scale (two clicks and a distance)' }],
    [hasPoints(v.places), { screen: 'places', text: 'Add the places people go to (rooms, lifts, entrances)' }],
    [
      hasAreas(v.places),
      { screen: 'places', text: 'Draw the walked corridors as areas (the phone then says which one the user is in)' },
    ],
    [Object.keys(v.lenses).length > 0, { screen: 'lenses', text: 'Add the lens profile of the modelling camera' }],
    [v.modelled, { screen: 'videos', text: 'Upload a modelling walk, tag its track and model it' }],
  ];
  return steps.filter(([done]) => !done).map(([, s]) => s);
}
