/**
 * The quality map in words and colours, without Leaflet or the DOM (so it is unit-tested in Node):
 * what each verdict looks like on the plan and how each stretch and corridor is said in the text
 * alternative. The result's format is omninav.quality.quality_map's (types.ts, Quality).
 */
import { inArea } from './geometry';
import type { Quality, QualityCorridor, QualitySegment, Verdict } from './types';

export type CorridorVerdict = Verdict | 'grey';

/** Plan colours, dark enough on the white plan for the 3:1 that WCAG asks of graphics. */
export const VERDICT_COLOUR: Record<CorridorVerdict, string> = {
  green: '#1b7a34',
  amber: '#b35c00',
  red: '#c5221f',
  grey: '#6b6b6b',
};

/** What a verdict means, as the legend and the text alternative say it. */
export const VERDICT_MEANING: Record<CorridorVerdict, string> = {
  green: 'answers within 2 m',
  amber: 'right, but a look-alike place scored close',
  red: 'answers the wrong place',
  grey: 'no video covers it',
};

/** "12.0 s" below a minute, "1:05.0" above (the time in a walk video). */
export function clock(t: number): string {
  if (t < 60) return `${t.toFixed(1)} s`;
  const m = Math.floor(t / 60);
  const s = t - 60 * m;
  return `${m}:${s.toFixed(1).padStart(4, '0')}`;
}

/** "(14.0, 2.3) m" */
export const at = (x: number, y: number): string => `(${x.toFixed(1)}, ${y.toFixed(1)}) m`;

/** "92 %" (a 0..1 share). */
export const percent = (share: number): string => `${Math.round(share * 100)} %`;

/** The middle point of a stretch's polyline (where it is said to be). */
export function middle(seg: QualitySegment): [number, number] {
  const p = seg.points;
  if (p.length === 0) return [seg.match.x, seg.match.y];
  return p[Math.floor((p.length - 1) / 2)];
}

/** "red stretch: model.mp4 12.0 s to 13.0 s, near (14.0, 2.0) m" */
export function stretchTitle(seg: QualitySegment): string {
  const [x, y] = middle(seg);
  return `${seg.verdict} stretch: ${seg.video} ${clock(seg.t0)} to ${clock(seg.t1)}, near ${at(x, y)}`;
}

/** Why a stretch has its verdict: how far the answer was and which look-alike it was taken for. */
export function stretchReason(seg: QualitySegment): string {
  const m = seg.match;
  const where = `${m.video} at ${clock(m.t)}, ${at(m.x, m.y)}`;
  const off = seg.error_m === null ? 'an unknown distance' : `${seg.error_m.toFixed(1)} m`;
  if (seg.verdict === 'green') return `answered within ${off}`;
  if (seg.verdict === 'amber')
    return `answered ${off} away, but ${where} scored close${seg.margin === null ? '' : ` (margin ${seg.margin.toFixed(2)})`}`;
  return `answered ${off} away: taken for ${where}`;
}

/** "both walking directions filmed" / "only one walking direction filmed" / "not filmed" */
export function directionsText(c: QualityCorridor): string {
  const { forward, backward } = c.directions;
  if (forward && backward) return 'both walking directions filmed';
  if (forward || backward) return `filmed one way only (${forward ? 'forward' : 'backward'}); film the other way too`;
  return 'not filmed in either direction';
}

/** One corridor in the text alternative. */
export function corridorText(c: QualityCorridor): string {
  if (c.verdict === 'grey') return `${c.place}: grey, ${VERDICT_MEANING.grey}`;
  const parts = [`${c.place}: ${c.verdict}`, `${percent(c.covered)} covered`];
  if (c.share_green !== null) parts.push(`${percent(c.share_green)} of it answers within 2 m`);
  parts.push(directionsText(c));
  return parts.join(', ');
}

/** The stretches an admin should look at (red first, then amber, each in walk order) on a floor. */
export function problemStretches(q: Quality, floor: string): QualitySegment[] {
  const rank = (s: QualitySegment) => (s.verdict === 'red' ? 0 : 1);
  return stretches(q.segments)
    .filter((s) => s.floor === floor && s.verdict !== 'green')
    .sort((a, b) => rank(a) - rank(b) || a.video.localeCompare(b.video) || a.t0 - b.t0);
}

/**
 * The segments (a second of walk each) as stretches: each run of consecutive red or amber segments
 * of one video is one stretch, as the summary counts them (quality.py `_runs`), from its first
 * segment's start to its last's end, named and explained by its worst second (the furthest wrong
 * answer, or the closest look-alike).
 */
export function stretches(segments: readonly QualitySegment[]): QualitySegment[] {
  const out: QualitySegment[] = [];
  let run: QualitySegment | null = null;
  for (const s of segments) {
    if (s.verdict !== 'green' && run && s.video === run.video && s.floor === run.floor && s.verdict === run.verdict) {
      const worse: boolean =
        s.verdict === 'red' ? (s.error_m ?? 0) > (run.error_m ?? 0) : (s.margin ?? 1) < (run.margin ?? 1);
      run = { ...(worse ? s : run), t0: run.t0, t1: s.t1, points: [...run.points, ...s.points] };
      out[out.length - 1] = run;
      continue;
    }
    run = s.verdict === 'green' ? null : s;
    out.push(s);
  }
  return out;
}

/**
 * How many of a floor's seconds of walk lie in no drawn area (their middle point): they are judged
 * second by second, but no corridor verdict counts them, and the page says so.
 */
export function outsideAreas(q: Quality, floor: string): { outside: number; all: number } {
  const areas = q.corridors.filter((c) => c.floor === floor).map((c) => c.area);
  const segs = q.segments.filter((s) => s.floor === floor);
  const inside = ([x, y]: [number, number]) => areas.some((a) => inArea(a, x, y));
  return { outside: segs.filter((s) => !inside(middle(s))).length, all: segs.length };
}

/** How many stretches of each verdict are on a floor. */
export function verdictCounts(q: Quality, floor: string): Record<Verdict, number> {
  const n: Record<Verdict, number> = { green: 0, amber: 0, red: 0 };
  for (const s of q.segments) if (s.floor === floor) n[s.verdict]++;
  return n;
}

/** The plan's accessible name: the summary and the counts, then where the full lists are. */
export function mapLabel(q: Quality, floor: string): string {
  const n = verdictCounts(q, floor);
  const all = n.green + n.amber + n.red;
  // red and amber as the list below counts them (runs of seconds), green as seconds walked
  const runs = stretches(q.segments).filter((s) => s.floor === floor);
  const amber = runs.filter((s) => s.verdict === 'amber').length;
  const red = runs.filter((s) => s.verdict === 'red').length;
  const corridors = q.corridors.filter((c) => c.floor === floor);
  const grey = corridors.filter((c) => c.verdict === 'grey').map((c) => c.place);
  return (
    `Quality map of floor ${floor}: ${n.green} of ${all} seconds walked green; ${amber} amber and ${red} red stretches` +
    (grey.length ? `; not covered: ${grey.join(', ')}` : '') +
    '. The lists below say the same.'
  );
}
