// The walk path editor's logic: corridor lines and snapping, suggestions in words, the one-click flow.
import { describe, expect, it } from 'vitest';
import type { Place } from '../src/shared/api-types';
import {
  acceptSuggestion,
  corridorLines,
  fromWalkPath,
  landmarkLine,
  nextUntagged,
  addAt,
  positionAt,
  putPoint,
  snapToLines,
  snapWords,
  suggestionLabel,
  suggestionText,
  toWalkPath,
  walkPathProblem,
  walkColumn,
  type Point,
} from '../src/admin/walk-path-edit';
import type { Suggestion } from '../src/admin/types';

// an L of two corridors (the quick demo's shape): one along x at y = 2, one along y at x = 20
const places: Place[] = [
  { id: 'a', floor: '1', name: 'Corridor 1', x: 11, y: 2, area: [0, 0.5, 21.5, 3.5] },
  { id: 'b', floor: '1', name: 'Corridor 2', x: 20, y: 8, area: [18.5, 0.5, 21.5, 14] },
  { id: 'c', floor: '1', name: 'the lifts', x: 20, y: 2 },
  { id: 'd', floor: '2', name: 'Upstairs', x: 5, y: 5, area: [0, 0, 10, 2] },
];
const s = (t: number, kind: Suggestion['kind'], turn_deg: number | null = null, duration_s: number | null = null) => ({
  t,
  kind,
  turn_deg,
  duration_s,
});

describe('corridor lines', () => {
  it('run along the long axis of each area, through its middle, on the floor asked for', () => {
    expect(corridorLines(places, '1')).toEqual([
      { place: 'Corridor 1', x0: 0, y0: 2, x1: 21.5, y1: 2 },
      { place: 'Corridor 2', x0: 20, y0: 0.5, x1: 20, y1: 14 },
    ]);
    expect(corridorLines(places, '2').map((l) => l.place)).toEqual(['Upstairs']);
  });
  it('a click near one line lands on it; far from all stays where it was', () => {
    const lines = corridorLines(places, '1');
    expect(snapToLines({ x: 8, y: 3.1 }, lines)).toEqual({ x: 8, y: 2, line: 'Corridor 1' });
    expect(snapToLines({ x: 19, y: 9 }, lines)).toEqual({ x: 20, y: 9, line: 'Corridor 2' });
    expect(snapToLines({ x: 8, y: 9 }, lines)).toEqual({ x: 8, y: 9, line: null });
  });
  it('a click near a corner lands on the crossing of the two lines', () => {
    const lines = corridorLines(places, '1');
    expect(snapToLines({ x: 19.2, y: 3 }, lines)).toEqual({ x: 20, y: 2, line: 'Corridor 2 × Corridor 1' }); // the nearer line first
  });
  it('past the end of an area, only across the line: a corner is not pulled back to the area end, and the words say how far', () => {
    const one = corridorLines([places[0]], '1'); // Corridor 1 alone: its line ends at x = 21.5
    const click = { x: 23.3, y: 2.4 };
    const got = snapToLines(click, one);
    expect(got.x).toBeCloseTo(23.3, 9);
    expect(got.y).toBeCloseTo(2, 9);
    expect(snapWords(click, got)).toBe(' (on Corridor 1, moved 0.4 m)');
    expect(snapWords(click, { ...click, line: null })).toBe('');
  });
  it('parallel corridors side by side: the nearer one', () => {
    const two: Place[] = [
      { id: 'a', floor: '1', name: 'A', x: 0, y: 0, area: [0, 0, 20, 2] },
      { id: 'b', floor: '1', name: 'B', x: 0, y: 0, area: [0, 3, 20, 5] },
    ];
    expect(snapToLines({ x: 5, y: 2.2 }, corridorLines(two, '1'))).toEqual({ x: 5, y: 1, line: 'A' });
  });
  it('within a custom distance only', () => {
    expect(snapToLines({ x: 8, y: 3.1 }, corridorLines(places, '1'), 1).line).toBeNull();
  });
});

describe('the landmarks beside the walk path', () => {
  it("the floor's named places in words, or where to add them", () => {
    const desk: Place = { id: 'l', floor: '1', name: 'the desk', x: 3, y: 2.04 };
    expect(landmarkLine([...places, desk, { ...desk, id: 'm', floor: '2' }], '1')).toBe(
      'Places on this floor: the lifts at (20.0, 2.0) m; the desk at (3.0, 2.0) m.',
    );
    expect(landmarkLine(places, '2')).toMatch(/^No named place on this floor/);
  });
});

describe('suggestions', () => {
  it('in words', () => {
    expect(suggestionLabel(s(12.4, 'turn', 88))).toBe('turn right 90°');
    expect(suggestionLabel(s(12.4, 'turn', -44))).toBe('turn left 45°');
    expect(suggestionLabel(s(12.4, 'turn', 178))).toBe('turn around');
    expect(suggestionLabel(s(30, 'stop', null, 4.2))).toBe('stop 4 s');
    expect(suggestionLabel(s(30, 'stop', null, 0.3))).toBe('stop 1 s');
    expect(suggestionLabel(s(0, 'start'))).toBe('start');
    expect(suggestionLabel(s(80, 'end'))).toBe('end');
    expect(suggestionText(s(62.46, 'turn', 90))).toBe('1:02.5, turn right 90°');
  });
  it('one click per corner: each accepted suggestion is tagged and the next untagged one comes up', () => {
    const sugg = [s(0, 'start'), s(10, 'turn', 90), s(15, 'stop', null, 4), s(30, 'end')];
    let pts: Point[] = [];
    const clicks = [
      { x: 1, y: 2 },
      { x: 20, y: 2 },
      { x: 20, y: 6 },
      { x: 20, y: 12 },
    ];
    let i = nextUntagged(sugg, pts);
    for (const at of clicks) {
      pts = acceptSuggestion(pts, sugg[i], at);
      i = nextUntagged(sugg, pts, i + 1);
    }
    expect(i).toBe(-1);
    // the stop holds still from 15 s to 19 s
    expect(pts).toEqual([
      { t: 0, x: 1, y: 2 },
      { t: 10, x: 20, y: 2 },
      { t: 15, x: 20, y: 6 },
      { t: 19, x: 20, y: 6 },
      { t: 30, x: 20, y: 12 },
    ]);
    expect(walkPathProblem(pts, 30)).toBeNull();
  });
  it('a suggestion already tagged (a waypoint within a quarter second) is skipped', () => {
    const sugg = [s(0, 'start'), s(10, 'turn', 90), s(30, 'end')];
    expect(nextUntagged(sugg, [{ t: 0.1, x: 0, y: 0 }])).toBe(1);
    expect(nextUntagged(sugg, [{ t: 9.8, x: 0, y: 0 }], 1)).toBe(2);
  });
});

describe('waypoints', () => {
  it('stay in time order; a second click at the same moment moves the waypoint', () => {
    let pts: Point[] = [];
    pts = putPoint(pts, { t: 5, x: 1, y: 1 });
    pts = putPoint(pts, { t: 1, x: 0, y: 0 });
    pts = putPoint(pts, { t: 5.01, x: 2, y: 2 });
    expect(pts).toEqual([
      { t: 1, x: 0, y: 0 },
      { t: 5.01, x: 2, y: 2 },
    ]);
  });
  it('say what keeps a walk path from being saved', () => {
    expect(walkPathProblem([{ t: 0, x: 0, y: 0 }], 10)).toMatch(/at least two/);
    expect(
      walkPathProblem(
        [
          { t: 2, x: 0, y: 0 },
          { t: 2, x: 1, y: 0 },
        ],
        10,
      ),
    ).toBe('Waypoint 2 (0:02.0) is not after waypoint 1 (0:02.0).');
    expect(
      walkPathProblem(
        [
          { t: 0, x: 0, y: 0 },
          { t: 12, x: 1, y: 0 },
        ],
        10,
      ),
    ).toMatch(/after the video ends/);
    expect(
      walkPathProblem(
        [
          { t: 0, x: NaN, y: 0 },
          { t: 1, x: 1, y: 0 },
        ],
        null,
      ),
    ).toMatch(/not a number/);
  });
  it("round-trip through walk_path.json: seconds (frames read at the walk path's fps), cm, the heading offset", () => {
    const pts = fromWalkPath({
      fps: 25,
      heading_offset_deg: 90,
      waypoints: [
        { t: 4.5, x: 3, y: 4 },
        { frame: 50, x: 1.234567, y: 2 },
      ],
    });
    expect(pts).toEqual([
      { t: 2, x: 1.234567, y: 2 },
      { t: 4.5, x: 3, y: 4 },
    ]);
    expect(toWalkPath(pts, 90)).toEqual({
      heading_offset_deg: 90,
      waypoints: [
        { t: 2, x: 1.23, y: 2 },
        { t: 4.5, x: 3, y: 4 },
      ],
    });
    expect(toWalkPath(pts).heading_offset_deg).toBeUndefined();
    expect(fromWalkPath(null)).toEqual([]);
  });
  it("the walker's position between waypoints, none outside them", () => {
    const pts = [
      { t: 0, x: 0, y: 0 },
      { t: 10, x: 10, y: 0 },
      { t: 20, x: 10, y: 5 },
    ];
    expect(positionAt(pts, 5)).toEqual({ x: 5, y: 0 });
    expect(positionAt(pts, 15)).toEqual({ x: 10, y: 2.5 });
    expect(positionAt(pts, 21)).toBeNull();
  });
  it('the walking direction on the panorama: the centre, shifted left by the heading offset', () => {
    expect(walkColumn(0)).toBe(0.5);
    expect(walkColumn(90)).toBe(0.25);
    expect(walkColumn(-90)).toBe(0.75);
    expect(walkColumn(270)).toBe(0.75);
  });
});

describe('a waypoint added at the current time', () => {
  const pts = [
    { t: 2, x: 0, y: 0 },
    { t: 6, x: 4, y: 0 },
  ];
  it('between two: on the line between them, and the words say so', () => {
    const a = addAt(pts, 3);
    expect(a.points).toEqual([pts[0], { t: 3, x: 1, y: 0 }, pts[1]]);
    expect(a.said).toMatch(/on the straight line between its neighbours/);
    expect(a.at).toBe(3);
  });
  it("after the last: at that waypoint's place, and the words ask for where the walker was", () => {
    const a = addAt(pts, 9);
    expect(a.points.at(-1)).toEqual({ t: 9, x: 4, y: 0 });
    expect(a.said).toMatch(/at the place of the waypoint at 0:06\.0: type where the walker was/);
  });
  it('again at the same moment: nothing changes, and it says where that waypoint is', () => {
    const once = addAt(pts, 3).points;
    const again = addAt(once, 3.02);
    expect(again.points).toEqual(once);
    expect(again.said).toBe('A waypoint is already at 0:03.0: its x and y are in the table.');
    expect(again.at).toBe(3);
  });
});
