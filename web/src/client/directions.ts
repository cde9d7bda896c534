/**
 * The answer in words, in the user's chosen style. Bearings come from the server relative to the
 * user's heading, clockwise, in (-180, 180]; the phone turns them into a clock face, left/right or
 * degrees. Pure functions: unit-tested, and the same words go to speech and to the screen.
 */

export type Style = 'clock' | 'sides' | 'degrees';

export interface Answer {
  x: number;
  y: number;
  heading_deg: number;
  confidence: number;
  floor: string;
  place: string | null;
  area: string | null;
  nearest: { name: string; distance_m: number; bearing_deg: number } | null;
  facing: string | null;
  sentence: string;
  low_confidence: boolean;
  accuracy_m: number | null;
  frames: number;
  sent: string;
}

export const UNSURE = 'Not sure where you are; turn slowly and try again.';
const NEAR_M = 10;

/** 0..360 or -180..180 clockwise -> "3 o'clock" (12 is straight ahead). */
export function clockHour(bearing: number): number {
  const h = Math.round((((bearing % 360) + 360) % 360) / 30) % 12;
  return h === 0 ? 12 : h;
}

/** "at 3 o'clock" | "to your right" | "90 degrees right": a phrase that follows a place name. */
export function direction(bearing: number, style: Style): string {
  const b = ((((bearing + 180) % 360) + 360) % 360) - 180; // (-180, 180]
  const side = b > 0 ? 'right' : 'left';
  const a = Math.abs(b);
  if (style === 'clock') return `at ${clockHour(b)} o'clock`;
  if (style === 'degrees') {
    const d = Math.round(a);
    if (d === 0) return 'straight ahead';
    if (d === 180) return 'straight behind you';
    return `${d} degrees ${side}`;
  }
  if (a <= 15) return 'straight ahead';
  if (a <= 60) return `ahead on your ${side}`;
  if (a <= 120) return `to your ${side}`;
  if (a < 165) return `behind you on your ${side}`;
  return 'behind you';
}

/** "Corridor 1" and "the lifts" stay; "North corridor" becomes "the North corridor". */
export function withArticle(name: string): string {
  const words = name.trim().split(/\s+/);
  const last = words[words.length - 1] ?? '';
  if (/^the /i.test(name) || /^\d/.test(last) || (last.length === 1 && last === last.toUpperCase())) return name;
  return `the ${name}`;
}

function metres(d: number): string {
  const m = Math.max(1, Math.round(d));
  return m === 1 ? '1 metre' : `${m} metres`;
}

const cap = (s: string) => s.charAt(0).toUpperCase() + s.slice(1);

/** The sentence to speak and show for an answer. */
export function describe(a: Answer, style: Style, floorName?: string): string {
  if (a.low_confidence) return UNSURE;
  const parts: string[] = [];
  parts.push(a.area ? `You are in ${withArticle(a.area)}.` : `You are on ${floorName ?? `floor ${a.floor}`}.`);
  const n = a.nearest;
  if (n && n.distance_m <= NEAR_M)
    parts.push(`${cap(n.name)} ${direction(n.bearing_deg, style)}, ${metres(n.distance_m)}.`);
  if (a.facing && !(n && n.distance_m <= NEAR_M && a.facing === n.name)) parts.push(`Facing ${a.facing}.`);
  return parts.join(' ');
}

/**
 * What a continuous-mode answer is "about": it is spoken only when this changes, so walking down a
 * corridor does not repeat the same sentence every few seconds.
 */
export function gist(a: Answer, style: Style): string {
  if (a.low_confidence) return 'unsure';
  const n = a.nearest && a.nearest.distance_m <= NEAR_M ? a.nearest : null;
  return [a.floor, a.area, n?.name, n ? direction(n.bearing_deg, style) : '', a.facing].join('|');
}
