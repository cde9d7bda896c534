/**
 * An evaluation walk's result in words and plan geometry, without Leaflet or the DOM (unit-tested
 * in Node): the summary sentence, one table row per clip and the arrow from truth to answer. The
 * result's format is omninav.evaluate.evaluate_walk's (types.ts, Evaluation).
 */
import type { Evaluation, EvaluationClip, Video } from './types';
import { at, clock, percent } from './quality-view';
import { isSure } from '../shared/sure';

/** Videos that can be evaluated: role 'evaluation' (tagged or not: the screen says which lack a walk path). */
export const evaluationVideos = (videos: Video[]): Video[] => videos.filter((v) => v.role === 'evaluation');

/** Why a video cannot be run yet, or null when it can. */
export function notReady(v: Video): string | null {
  if (v.error) return `the server refused it: ${v.error}`;
  if (v.status === 'uploading') return 'it is still uploading';
  if (!v.has_walk_path) return 'it has no walk path yet: tag its waypoints first';
  return null;
}

/** A median, or what to say when no clip was answered (the server sends null then). */
export const metres = (v: number | null): string => (v === null ? 'none' : `${v.toFixed(1)} m`);
export const degrees = (v: number | null): string => (v === null ? 'none' : `${Math.round(v)}°`);

/**
 * The answers said as "probably" and those said as sure but further than 2 m off: the summary's,
 * or, for a result stored before it had them, counted from its clips the same way.
 */
export function saidCounts(e: Evaluation): { probably: number; sure_over_2m: number } {
  const { probably, sure_over_2m } = e.summary;
  if (probably !== undefined && sure_over_2m !== undefined) return { probably, sure_over_2m };
  const answered = e.clips.filter((c) => c.answer !== null);
  return {
    probably: answered.filter((c) => !c.answer!.low_confidence && !isSure(c.answer!)).length,
    sure_over_2m: answered.filter((c) => isSure(c.answer!) && (c.error_m ?? 0) > 2).length,
  };
}

/** The summary, as shown and announced. */
export function summaryText(e: Evaluation): string {
  const s = { ...e.summary, ...saidCounts(e) };
  const answered = e.clips.filter((c) => c.answer !== null).length;
  return (
    `${s.clips} clips: ${percent(s.within_1m)} within 1 m, ${percent(s.within_2m)} within 2 m; ` +
    `median error ${metres(s.median_error_m)}, median heading error ${degrees(s.median_heading_error_deg)}; ` +
    `${s.not_sure} spoken as "not sure", ${s.probably} as "probably"; ` +
    `${s.sure_over_2m} said as sure and further than 2 m off` +
    (answered < s.clips ? `; ${s.clips - answered} without an answer` : '')
  );
}

/** A clip's verdict, as its arrow's colour and its table row say it. */
export function clipVerdict(c: EvaluationClip): 'within 1 m' | 'within 2 m' | 'off' | 'not sure' | 'no answer' {
  if (c.answer === null || c.error_m === null) return 'no answer';
  if (c.answer.low_confidence) return 'not sure';
  if (c.error_m <= 1) return 'within 1 m';
  if (c.error_m <= 2) return 'within 2 m';
  return 'off';
}

export const CLIP_COLOUR: Record<ReturnType<typeof clipVerdict>, string> = {
  'within 1 m': '#1b7a34',
  'within 2 m': '#2f6f9f',
  off: '#c5221f',
  'not sure': '#b35c00',
  'no answer': '#6b6b6b',
};

/** One table row: time, truth, answer, error, heading error, verdict. */
export function clipRow(c: EvaluationClip): string[] {
  const pose = (p: { x: number; y: number; heading_deg: number }) =>
    `${at(p.x, p.y)}, facing ${(((Math.round(p.heading_deg) % 360) + 360) % 360).toString()}°`;
  return [
    clock(c.t),
    pose(c.truth),
    c.answer ? pose(c.answer) : 'no answer',
    c.error_m === null ? '–' : `${c.error_m.toFixed(1)} m`,
    c.heading_error_deg === null ? '–' : `${Math.round(c.heading_error_deg)}°`,
    clipVerdict(c),
  ];
}

export const CLIP_COLUMNS = ['Time', 'Truth', 'Answer', 'Error', 'Heading error', 'Verdict'];

/**
 * An arrow from truth to answer, in plan metres: the shaft and the two barbs of its head (`head`
 * metres long, or a third of the shaft when that is shorter). Null without an answer.
 */
export function arrow(c: EvaluationClip, head = 0.5): { shaft: [number, number][]; barbs: [number, number][] } | null {
  if (!c.answer) return null;
  const { x: x0, y: y0 } = c.truth;
  const { x: x1, y: y1 } = c.answer;
  const len = Math.hypot(x1 - x0, y1 - y0);
  const shaft: [number, number][] = [
    [x0, y0],
    [x1, y1],
  ];
  if (len < 1e-6) return { shaft, barbs: [] };
  const h = Math.min(head, len / 3);
  const ux = (x1 - x0) / len;
  const uy = (y1 - y0) / len;
  const barb = (s: number): [number, number] => [
    x1 - h * (ux * Math.cos(0.5) - s * uy * Math.sin(0.5)),
    y1 - h * (uy * Math.cos(0.5) + s * ux * Math.sin(0.5)),
  ];
  return { shaft, barbs: [barb(1), [x1, y1], barb(-1)] };
}
