// The quality map and the evaluation walk in words and geometry (the admin page's text
// alternatives): what each stretch, corridor and clip says, and the arrow from truth to answer.
import { describe, expect, it } from 'vitest';
import {
  arrow,
  clipRow,
  clipVerdict,
  evaluationVideos,
  notReady,
  saidCounts,
  summaryText,
} from '../src/admin/evaluation-view';
import { progressPercent, progressText } from '../src/admin/jobprogress';
import {
  clock,
  corridorText,
  directionsText,
  mapLabel,
  outsideAreas,
  problemStretches,
  stretchReason,
  stretchTitle,
  verdictCounts,
} from '../src/admin/quality-view';
import type {
  Evaluation,
  EvaluationClip,
  Job,
  Quality,
  QualityCorridor,
  QualitySegment,
  Video,
} from '../src/admin/types';

const seg = (over: Partial<QualitySegment> = {}): QualitySegment => ({
  video: 'model.mp4',
  floor: '1',
  t0: 12,
  t1: 13,
  points: [
    [14, 2],
    [14.6, 2],
    [15.2, 2],
  ],
  verdict: 'green',
  error_m: 0.4,
  margin: 0.2,
  query: { video: 'model.mp4', t: 12.5 },
  match: { video: 'model.mp4', t: 12.4, x: 14.5, y: 2 },
  ...over,
});

const corridor = (over: Partial<QualityCorridor> = {}): QualityCorridor => ({
  place: 'Corridor 1',
  floor: '1',
  area: [0.8, 0.8, 21.2, 3.2],
  covered: 1,
  verdict: 'green',
  share_green: 0.95,
  directions: { forward: true, backward: false },
  ...over,
});

const quality = (segments: QualitySegment[], corridors: QualityCorridor[]): Quality => ({
  generation: 1,
  frames: 200,
  radius_m: 2,
  segments,
  corridors,
  summary: { share_green: 0.9, ambiguous: 1, wrong: 1, uncovered: ['the stairwell'], one_direction: ['Corridor 1'] },
  sentence: '90 % of the walked corridors answer within 2 m; 1 ambiguous stretch; the stairwell is not covered',
});

describe('quality map in words', () => {
  it('says times as seconds, then minutes', () => {
    expect([0, 12.34, 59.96, 65, 600.5].map(clock)).toEqual(['0.0 s', '12.3 s', '60.0 s', '1:05.0', '10:00.5']);
  });

  it('names a stretch by its video, times and middle point, and says why it is red or amber', () => {
    const red = seg({ verdict: 'red', error_m: 9.26, match: { video: 'model.mp4', t: 3, x: 5.5, y: 2 } });
    expect(stretchTitle(red)).toBe('red stretch: model.mp4 12.0 s to 13.0 s, near (14.6, 2.0) m');
    expect(stretchReason(red)).toBe('answered 9.3 m away: taken for model.mp4 at 3.0 s, (5.5, 2.0) m');
    expect(stretchReason(seg({ verdict: 'amber', margin: 0.013 }))).toMatch(/scored close \(margin 0\.01\)/);
    expect(stretchReason(seg())).toBe('answered within 0.4 m');
  });

  it('says grey corridors are not covered, and which walking directions were filmed', () => {
    expect(corridorText(corridor({ place: 'the stairwell', verdict: 'grey', covered: 0, share_green: null }))).toBe(
      'the stairwell: grey, no video covers it',
    );
    expect(corridorText(corridor())).toBe(
      'Corridor 1: green, 100 % covered, 95 % of it answers within 2 m, filmed one way only (forward); film the other way too',
    );
    expect(directionsText(corridor({ directions: { forward: true, backward: true } }))).toBe(
      'both walking directions filmed',
    );
  });

  it('lists red stretches before amber ones, in walk order, on the floor shown only', () => {
    const q = quality(
      [
        seg({ t0: 1, verdict: 'amber' }),
        seg({ t0: 2, verdict: 'red' }),
        seg({ t0: 0, verdict: 'amber' }),
        seg({ t0: 3 }),
        seg({ t0: 4, verdict: 'red', floor: '2' }),
      ],
      [corridor(), corridor({ place: 'the stairwell', verdict: 'grey', covered: 0, share_green: null })],
    );
    expect(problemStretches(q, '1').map((s) => [s.verdict, s.t0])).toEqual([
      ['red', 2],
      ['amber', 0],
      ['amber', 1],
    ]);
    expect(verdictCounts(q, '1')).toEqual({ green: 1, amber: 2, red: 1 });
    expect(mapLabel(q, '1')).toBe(
      'Quality map of floor 1: 1 of 4 seconds walked green; 2 amber and 1 red stretches; not covered: the stairwell. The lists below say the same.',
    );
  });
});

describe('seconds in no drawn area', () => {
  it('are counted, on the floor shown, by their middle point', () => {
    const q = quality(
      [
        seg(),
        seg({ t0: 13, points: [[40, 9]] }),
        seg({ t0: 14, points: [[41, 9]] }),
        seg({ floor: '2', points: [[40, 9]] }),
      ],
      [corridor()],
    );
    expect(outsideAreas(q, '1')).toEqual({ outside: 2, all: 3 });
  });
});

describe('stretches to check', () => {
  it('a run of red or amber seconds of one video is one stretch, as the summary counts them', () => {
    const walk = [
      seg({ t0: 0, t1: 1, verdict: 'amber', margin: 0.05 }),
      seg({ t0: 1, t1: 2, verdict: 'amber', margin: 0.01, match: { video: 'model.mp4', t: 30, x: 40, y: 2 } }),
      seg({ t0: 2, t1: 3, verdict: 'amber', margin: 0.03 }),
      seg({ t0: 3, t1: 4 }),
      seg({ t0: 4, t1: 5, verdict: 'red', error_m: 6 }),
      seg({ t0: 5, t1: 6, verdict: 'red', error_m: 12 }),
      seg({ t0: 6, t1: 7, verdict: 'amber' }),
      seg({ video: 'other.mp4', t0: 7, t1: 8, verdict: 'amber' }),
    ];
    const got = problemStretches(quality(walk, [corridor()]), '1');
    expect(got.map((s) => [s.video, s.verdict, s.t0, s.t1])).toEqual([
      ['model.mp4', 'red', 4, 6],
      ['model.mp4', 'amber', 0, 3],
      ['model.mp4', 'amber', 6, 7],
      ['other.mp4', 'amber', 7, 8],
    ]);
    // explained by its worst second: the closest look-alike, the furthest wrong answer
    expect(got[1].margin).toBe(0.01);
    expect(got[1].match.t).toBe(30);
    expect(got[1].points).toHaveLength(9);
    expect(got[0].error_m).toBe(12);
    // the plan's text alternative counts them as the list does
    expect(mapLabel(quality(walk, [corridor()]), '1')).toMatch(
      /: 1 of 8 seconds walked green; 3 amber and 1 red stretches/,
    );
  });
});

const clip = (over: Partial<EvaluationClip> = {}): EvaluationClip => ({
  t: 3,
  truth: { x: 10, y: 2, heading_deg: 90 },
  answer: { x: 11.5, y: 2, heading_deg: 95, confidence: 0.8, low_confidence: false },
  error_m: 1.5,
  heading_error_deg: 5,
  ...over,
});

describe('evaluation walk in words', () => {
  it('sorts each clip into within 1 m, within 2 m, off, not sure, no answer', () => {
    expect(
      [
        clip({ error_m: 0.5 }),
        clip(),
        clip({ error_m: 4 }),
        clip({ answer: { x: 0, y: 0, heading_deg: 0, confidence: 0.1, low_confidence: true }, error_m: 12 }),
        clip({ answer: null, error_m: null, heading_error_deg: null }),
      ].map(clipVerdict),
    ).toEqual(['within 1 m', 'within 2 m', 'off', 'not sure', 'no answer']);
    expect(clipRow(clip())).toEqual([
      '3.0 s',
      '(10.0, 2.0) m, facing 90°',
      '(11.5, 2.0) m, facing 95°',
      '1.5 m',
      '5°',
      'within 2 m',
    ]);
    const north = clip({ answer: { x: 10, y: 2, heading_deg: 359.7, confidence: 0.9, low_confidence: false } });
    expect(clipRow(north)[2]).toBe('(10.0, 2.0) m, facing 0°');
    expect(clipRow(clip({ answer: null, error_m: null, heading_error_deg: null })).slice(2)).toEqual([
      'no answer',
      '–',
      '–',
      'no answer',
    ]);
  });

  it('summarises the shares, the errors and the "not sure" answers', () => {
    const e: Evaluation = {
      clips: [clip(), clip({ answer: null, error_m: null, heading_error_deg: null })],
      summary: {
        clips: 2,
        within_1m: 0,
        within_2m: 0.5,
        median_error_m: 1.5,
        median_heading_error_deg: 5.4,
        not_sure: 0,
        probably: 1,
        sure_over_2m: 0,
      },
    };
    expect(summaryText(e)).toBe(
      '2 clips: 0 % within 1 m, 50 % within 2 m; median error 1.5 m, median heading error 5°; ' +
        '0 spoken as "not sure", 1 as "probably"; 0 said as sure and further than 2 m off; 1 without an answer',
    );
  });

  it('counts "probably" and sure-but-off from the clips of a result stored before the summary had them', () => {
    const c = (confidence: number, low_confidence: boolean, error_m: number) =>
      clip({ answer: { x: 0, y: 0, heading_deg: 0, confidence, low_confidence }, error_m });
    const e: Evaluation = {
      clips: [c(0.9, false, 0.4), c(0.95, false, 3.1), c(0.7, false, 2.5), c(0.3, true, 9), clip({ answer: null })],
      summary: {
        clips: 5,
        within_1m: 0.2,
        within_2m: 0.2,
        median_error_m: 2.8,
        median_heading_error_deg: 1,
        not_sure: 1,
      },
    };
    expect(saidCounts(e)).toEqual({ probably: 1, sure_over_2m: 1 });
    expect(summaryText(e)).toContain(
      '1 spoken as "not sure", 1 as "probably"; 1 said as sure and further than 2 m off',
    );
    // a summary that has them is taken as it is
    expect(saidCounts({ ...e, summary: { ...e.summary, probably: 4, sure_over_2m: 0 } })).toEqual({
      probably: 4,
      sure_over_2m: 0,
    });
  });

  it('draws an arrow from truth to answer with its head at the answer', () => {
    const a = arrow(clip())!;
    expect(a.shaft).toEqual([
      [10, 2],
      [11.5, 2],
    ]);
    expect(a.barbs[1]).toEqual([11.5, 2]);
    for (const b of [a.barbs[0], a.barbs[2]]) {
      expect(b[0]).toBeLessThan(11.5); // behind the tip
      expect(Math.hypot(b[0] - 11.5, b[1] - 2)).toBeCloseTo(0.5, 6); // a third of 1.5 m
    }
    expect(a.barbs[0][1]).toBeCloseTo(4 - a.barbs[2][1], 6); // symmetric about the shaft
    expect(arrow(clip({ answer: null }))).toBeNull();
  });

  it('offers only evaluation videos, and says why one cannot run yet', () => {
    const v = (over: Partial<Video>): Video =>
      ({ name: 'eval.mp4', role: 'evaluation', status: 'ready', has_walk_path: true, error: null, ...over }) as Video;
    expect(evaluationVideos([v({}), v({ name: 'model.mp4', role: 'model' })]).map((x) => x.name)).toEqual(['eval.mp4']);
    expect(notReady(v({}))).toBeNull();
    expect(notReady(v({ has_walk_path: false }))).toMatch(/no walk path/);
    expect(notReady(v({ status: 'uploading' }))).toMatch(/uploading/);
    expect(notReady(v({ error: 'it does not decode' }))).toMatch(/refused it: it does not decode/);
  });
});

describe('job progress', () => {
  const job = (over: Partial<Job>): Job =>
    ({
      state: 'running',
      frames_done: 120,
      frames_total: 240,
      frames_per_s: 41.3,
      eta_s: 2.9,
      error: null,
      ...over,
    }) as Job;
  it('says frames, rate and time left, and the end', () => {
    expect(progressText(job({}))).toBe('120 of 240 frames, 41 frames/s, about 3 s left');
    expect(progressPercent(job({}))).toBe(50);
    expect(progressText(job({ state: 'queued' }))).toBe('waiting to start');
    expect(progressText(job({ state: 'failed', error: 'no live generation' }))).toBe('failed: no live generation');
    expect(progressPercent(job({ state: 'done' }))).toBe(100);
  });
});
