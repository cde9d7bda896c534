/**
 * The answer in words, in the user's chosen style: the words the user hears are made here, on the
 * phone, so that every style works offline too (Repeat, a changed style). Bearings come from the
 * server relative to the user's heading, clockwise, in (-180, 180]. The server's `sentence` is
 * the same sentence in the default style (backend/omninav/server/describe.py); one table of cases,
 * tests/data/sentences.json, holds both to the same words. Pure functions: the same words go to
 * speech and to the screen.
 */
import type { Answer } from '../shared/api-types';

export type { Answer };

export type Style = 'clock' | 'sides' | 'degrees';

export const DEFAULT_STYLE: Style = 'clock';
export const UNSURE = 'Not sure where you are; turn slowly and try again.';
/** A place further than this (metres) is not "near". */
export const NEAR_M = 10;

/** Any angle -> (-180, 180], computed as Python's float % does, so both sides agree to the bit. */
function signed(b: number): number {
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

/** "at 3 o'clock" | "to your right" | "at 90 degrees right": a phrase that follows a place name. */
export function direction(bearing: number, style: Style): string {
  const b = signed(bearing);
  const side = b > 0 ? 'right' : 'left';
  const a = Math.abs(b);
  if (style === 'clock') return `at ${clockHour(b)} o'clock`;
  if (style === 'degrees') {
    const d = round(a);
    if (d === 0) return 'straight ahead';
    if (d === 180) return 'straight behind you';
    return `at ${d} ${d === 1 ? 'degree' : 'degrees'} ${side}`;
  }
  // sides: a bearing on a boundary belongs to the sector nearer straight ahead
  if (a <= 15) return 'straight ahead';
  if (a <= 60) return `ahead on your ${side}`;
  if (a <= 120) return `to your ${side}`;
  if (a <= 165) return `behind you on your ${side}`;
  return 'behind you';
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
export type Said = Pick<Answer, 'floor' | 'area' | 'nearest' | 'facing' | 'low_confidence'>;

/**
 * The sentence to speak and show for an answer: "You are in the North corridor, near the lifts at
 * 3 o'clock, 4 metres, facing Room 102." The floor's name comes from the venue.
 */
export function describe(a: Said, style: Style, floorName?: string | null): string {
  if (a.low_confidence) return UNSURE;
  const near = nearOf(a);
  const parts: string[] = [];
  if (a.area) parts.push(`in ${withArticle(a.area)}`);
  if (near) parts.push(`near ${near.name} ${direction(near.bearing_deg, style)}, ${metres(near.distance_m)}`);
  if (parts.length === 0) parts.push(`on ${floorName ?? `floor ${a.floor}`}`);
  if (a.facing && !(near && a.facing === near.name)) parts.push(`facing ${a.facing}`);
  return `You are ${parts.join(', ')}.`;
}

/**
 * What a continuous-mode answer is "about": it is spoken only when this changes, so walking down a
 * corridor does not repeat the same sentence every few seconds.
 */
export function gist(a: Said, style: Style): string {
  if (a.low_confidence) return 'unsure';
  const n = nearOf(a);
  return [a.floor, a.area, n?.name, n ? direction(n.bearing_deg, style) : '', a.facing].join('|');
}
