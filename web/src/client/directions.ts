/**
 * The answer in words, in the user's chosen style: the words the user hears are made here, on the
 * phone, so that every style works offline too (Repeat, a changed style). Bearings come from the
 * server relative to the user's heading, clockwise, in (-180, 180]. The server's `sentence` is
 * the same sentence in the default style (backend/omninav/describe.py); one table of cases,
 * tests/data/sentences.json, holds both to the same words. Pure functions: the same words go to
 * speech and to the screen.
 */
import type { Answer, Guidance, RoutePreview } from '../shared/api-types';
import { SURE, isSure } from '../shared/sure';
// the thresholds and fixed sentences, read with the engine's describe.py from one file
import W from '../../../backend/omninav/words.json';

export { SURE, isSure };

export type { Answer };

export type Style = 'clock' | 'sides' | 'degrees';

export const DEFAULT_STYLE: Style = 'clock';
export const UNSURE: string = W.unsure;
/**
 * Once said as sure, the gist stays sure until the confidence falls under this, as AT_LEAVE_M does
 * for "at": a user standing still whose answers wobble about SURE is not told "probably" and
 * "sure" by turns.
 */
export const SURE_LEAVE = 0.7;
/** A place further than this (metres) is not "near". */
export const NEAR_M: number = W.near_m;
/**
 * Nor one nearer than this "near ... at 3 o'clock": the user is *at* it (under a metre the way to
 * it is noise, and said every few seconds to someone standing there it turned round the clock).
 */
export const AT_M: number = W.at_m;

/** Any angle -> (-180, 180], computed as Python's float % does, so both sides agree to the bit. */
export function signed(b: number): number {
  let m = (b + 180) % 360;
  if (m < 0) m += 360;
  const r = m - 180;
  return r === -180 ? 180 : r;
}

/** Half up, as Python's describe.py rounds. */
const round = (v: number): number => Math.floor(v + 0.5);

/**
 * A bearing -> 1..12, 12 straight ahead. A bearing on a boundary (15, 45, ...) takes the hour
 * nearer straight ahead, on either side, so left and right mirror each other.
 */
export function clockHour(bearing: number): number {
  const b = signed(bearing);
  const h = Math.ceil(Math.abs(b) / 30 - 0.5);
  return (b < 0 ? 12 - h : h) % 12 || 12;
}

/** The sides style's sector limits: straight ahead | ahead on a side | beside | behind on a side | behind. */
export const SECTOR_DEG = W.sector_deg as [number, number, number, number];

/**
 * The sides style's sector of a bearing: 0 straight ahead, 1 ahead on a side, 2 beside, 3 behind on
 * a side, 4 behind (both `direction` and `turnPhrase` word it). A bearing on a boundary belongs to
 * the sector nearer straight ahead, on either side.
 */
export function sector(bearing: number): number {
  const a = Math.abs(signed(bearing));
  const k = SECTOR_DEG.findIndex((limit) => a <= limit);
  return k < 0 ? SECTOR_DEG.length : k;
}

/** "at 3 o'clock" | "to your right" | "at 90 degrees to your right": a phrase that follows a place name. */
export function direction(bearing: number, style: Style): string {
  const b = signed(bearing);
  const side = b > 0 ? 'right' : 'left';
  const a = Math.abs(b);
  if (style === 'clock') return `at ${clockHour(b)} o'clock`;
  if (style === 'degrees') {
    const d = round(a);
    if (d === 0) return 'straight ahead';
    if (d === 180) return 'straight behind you';
    return `at ${d} ${d === 1 ? 'degree' : 'degrees'} to your ${side}`;
  }
  return ['straight ahead', `ahead on your ${side}`, `to your ${side}`, `behind you on your ${side}`, 'behind you'][
    sector(b)
  ];
}

/** "Corridor 1", "Hall B" and "the lifts" stay; "North corridor" becomes "the North corridor". */
export function withArticle(name: string): string {
  const words = name.trim().split(/\s+/);
  const last = words[words.length - 1] ?? '';
  if (/^the /i.test(name) || /^[0-9]/.test(last) || /^\p{Lu}$/u.test(last)) return name;
  return `the ${name}`;
}

function metres(d: number): string {
  const m = Math.max(1, round(d));
  return m === 1 ? '1 metre' : `${m} metres`;
}

/** The nearest place when it is near enough to name, else null. */
const nearOf = (a: Pick<Answer, 'nearest'>) => (a.nearest && a.nearest.distance_m <= NEAR_M ? a.nearest : null);

/** What the sentence is made from: the answer's words, and whether it is sure. */
export type Said = Pick<Answer, 'floor' | 'area' | 'nearest' | 'facing' | 'low_confidence' | 'confidence'>;

/**
 * The sentence to speak and show for an answer: "You are in the North corridor, near the lifts at
 * 3 o'clock, 4 metres, facing Room 102." The floor's name comes from the venue. Outside every area
 * with no place within NEAR_M: the floor, and how far the nearest place is and which way ("You are
 * on Floor 1, 25 metres from the lifts at 3 o'clock."), never the floor alone.
 */
export function describe(a: Said, style: Style, floorName?: string | null): string {
  if (a.low_confidence) return UNSURE;
  const near = nearOf(a);
  const parts: string[] = [];
  if (a.area) parts.push(`in ${withArticle(a.area)}`);
  if (near && near.distance_m < AT_M) parts.push(`at ${near.name}`);
  else if (near) parts.push(`near ${near.name} ${direction(near.bearing_deg, style)}, ${metres(near.distance_m)}`);
  // never the floor alone where the floor has a place: how far the nearest is, and where
  let far: Answer['nearest'] = null;
  if (parts.length === 0) {
    parts.push(`on ${floorName ?? `floor ${a.floor}`}`);
    if (a.nearest) {
      far = a.nearest;
      parts.push(`${metres(far.distance_m)} from ${far.name} ${direction(far.bearing_deg, style)}`);
    }
  }
  const named = near ?? far;
  if (a.facing && !(named && a.facing === named.name)) parts.push(`facing ${a.facing}`);
  return `You are ${isSure(a) ? '' : 'probably '}${parts.join(', ')}.`;
}

/**
 * Once "at" a place, the gist stays "at" it until the answer is this far from it: an estimate's
 * few decimetres of jitter about AT_M would otherwise flip "at the lifts" and "near the lifts at
 * 3 o'clock, 1 metre" at every answer of a user standing there.
 */
export const AT_LEAVE_M = AT_M + 0.5;

/**
 * What a continuous-mode answer is "about": it is spoken only when this changes, so walking down a
 * corridor does not repeat the same sentence every few seconds. `last`: the gist last said (with
 * no `last`, the gist of the sentence `describe` makes). Whether it is sure is part of it, with
 * SURE_LEAVE's margin at the same place only: "You are probably at the lifts" is followed by "You
 * are at the lifts" once the answer firms up, and another place is said as `describe` says it.
 */
export function gist(a: Said, last = ''): string {
  if (a.low_confidence) return 'unsure';
  const n = nearOf(a);
  const [lastSure, ...lastRest] = last.split('|');
  const [, , lastName, lastWay] = lastRest;
  const atM = n && lastWay === 'at' && lastName === n.name ? AT_LEAVE_M : AT_M;
  // what is news to a walker: another floor or area, another place near, a place reached. Which
  // way a place is, and what the phone faces, change at every step and every glance: said with
  // the news, never news themselves (a sentence every answer talked over the walk)
  const way = !n ? '' : n.distance_m < atM ? 'at' : 'near';
  // outside every area with nothing near, the nearest place however far is said (describe): a new
  // one is news, its distance and way at every step are not
  const far = !a.area && !n && a.nearest ? `far:${a.nearest.name}` : '';
  const rest = [a.floor, a.area, n?.name, way, far].join('|');
  const stay = lastSure === 'sure' && lastRest.join('|') === rest && a.confidence >= SURE_LEAVE;
  return [stay || isSure(a) ? 'sure' : 'probably', rest].join('|');
}

/**
 * What "Keep telling me" says when an answer is news (its gist changed) after `last`, the answer it
 * last said: the whole sentence (describe) for another floor or area, a first answer, or one that
 * is or was unsure; within the same area only the place that is new or reached, "Near the lifts at
 * 3 o'clock, 4 metres." / "At the lifts.", and what the phone faces if that changed. The area the
 * user is still in is not said again at every place passed.
 */
export function change(last: Said | null, a: Said, style: Style, floorName?: string | null): string {
  const near = nearOf(a);
  if (!last || last.low_confidence || a.low_confidence || a.floor !== last.floor || a.area !== last.area || !near)
    return describe(a, style, floorName);
  const parts = [
    near.distance_m < AT_M
      ? `at ${near.name}`
      : `near ${near.name} ${direction(near.bearing_deg, style)}, ${metres(near.distance_m)}`,
  ];
  if (a.facing && a.facing !== near.name && a.facing !== last.facing) parts.push(`facing ${a.facing}`);
  const said = `${isSure(a) ? '' : 'probably '}${parts.join(', ')}.`;
  return said[0].toUpperCase() + said.slice(1);
}

// --- route guidance: the words of backend/omninav/describe.py's guidance_sentence and
// preview_sentence, held to the same sentences by one table, tests/data/guidance.json.

/** A bearing within this of straight ahead is "straight ahead": no turn. */
export const STRAIGHT_DEG = SECTOR_DEG[0];
/** The sides style's turn beyond this is "Turn around", not "Turn sharp left" at 161 degrees. */
export const AROUND_DEG: number = W.around_deg;
export const GUIDE_UNSURE: string = W.guide_unsure;
/** The same, when a place was just chosen: the user has not been asked to walk yet. */
export const GUIDE_UNSURE_CHOSEN = 'Not sure where you are yet; press Start and walk slowly.';
export const GUIDE_NOT_HERE: string = W.guide_not_here;

/** What a guidance sentence is made from: the answer's `guidance` (its `to` may carry the place's `say`). */
export type Guided = Pick<Guidance, 'kind' | 'bearing_deg' | 'walk_m' | 'until' | 'floor_change'> &
  Partial<Pick<Guidance, 'in_m'>> & {
    to: { name: string; say?: string | null };
  };

/** "Turn to 2 o'clock" | "Turn right" | "Turn 60 degrees right"; null within STRAIGHT_DEG. */
export function turnPhrase(bearing: number, style: Style): string | null {
  const b = signed(bearing);
  const side = b > 0 ? 'right' : 'left';
  const k = sector(b);
  if (k === 0) return null;
  if (style === 'clock') return `Turn to ${clockHour(b)} o'clock`;
  if (style === 'degrees') {
    const d = round(Math.abs(b));
    return d >= 180 ? 'Turn around' : `Turn ${d} degrees ${side}`;
  }
  if (Math.abs(b) > AROUND_DEG) return 'Turn around'; // though a place there is "behind you on a side"
  return [`Bear ${side}`, `Turn ${side}`, `Turn sharp ${side}`, 'Turn around'][k - 1];
}

/**
 * "Turn to 2 o'clock and walk 12 metres, to the end of the corridor." (straight: "Walk straight
 * ahead 12 metres, ..."). With `inM`, the metres still to walk to the corner where the turn is:
 * "In 3 metres, turn to 2 o'clock and walk 12 metres, ..." (none when it rounds to 0).
 */
export function instruction(
  bearing: number,
  walkM: number,
  until: string | null,
  style: Style,
  inM: number | null = null,
): string {
  const tail = until ? `, to ${until}` : '';
  const turn = turnPhrase(bearing, style);
  const said =
    turn === null ? `Walk straight ahead ${metres(walkM)}${tail}.` : `${turn} and walk ${metres(walkM)}${tail}.`;
  if (inM === null || round(inM) < 1) return said;
  return `In ${metres(inM)}, ${said[0].toLowerCase()}${said.slice(1)}`;
}

/** The sentence for a guidance, in the user's style (the server's `sentence` is the default style's). */
export function guidanceSentence(g: Guided, style: Style): string {
  if (g.kind === 'unsure') return GUIDE_UNSURE;
  if (g.kind === 'not_here') return GUIDE_NOT_HERE;
  const b = g.bearing_deg ?? 0;
  const walk = g.walk_m ?? 0;
  if (g.kind === 'arrived' || g.kind === 'probably_arrived') {
    const at = g.kind === 'arrived' ? 'You have arrived at' : 'You are probably at';
    const said =
      walk < 0.5 ? `${at} ${g.to.name}.` : `${at} ${g.to.name}; it is ${direction(b, style)}, ${metres(walk)}.`;
    return g.to.say ? `${said} ${g.to.say}` : said;
  }
  if (g.kind === 'off_route') {
    const turn = turnPhrase(b, style);
    return `You are off the route; ${turn ? turn[0].toLowerCase() + turn.slice(1) : 'walk straight ahead'}.`;
  }
  if (g.floor_change) return `Take the ${g.floor_change.via} to ${g.floor_change.to_floor_name}.`;
  if (g.kind === 'reassure' || g.kind === 'back_on_route') {
    const on = `${metres(walk)}${g.until ? ` to ${g.until}` : ''}.`;
    return g.kind === 'back_on_route' ? `You are on the route again; keep going, ${on}` : `Keep going, ${on}`;
  }
  return instruction(b, walk, g.until, style, g.in_m ?? null);
}

/** A route before starting: "Room 102: 45 metres, 2 turns, first turn after 12 metres." */
export function previewSentence(p: RoutePreview, to: { name: string }): string {
  const name = to.name.slice(0, 1).toUpperCase() + to.name.slice(1);
  const n = p.turns;
  if (p.length_m < 1 && n === 0) return `${name}: you are there.`;
  const parts = [metres(p.length_m)];
  if (n === 0) parts.push('no turns');
  else if (n === 1) parts.push(`1 turn, after ${metres(p.first_turn_m ?? 0)}`);
  else parts.push(`${n} turns, first turn after ${metres(p.first_turn_m ?? 0)}`);
  const floors = new Set(p.floors).size;
  if (floors > 1) parts.push(`on ${floors} floors`);
  return `${name}: ${parts.join(', ')}.`;
}
