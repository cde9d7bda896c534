// The admin page's pure parts: metres <-> the map's CRS.Simple coordinates and plan pixels, the
// scale from two points, the scale bar's length, the place file's checks (the server's rules), the
// event-stream parser and the hash routes.
import { describe, expect, it } from 'vitest';
import { EventParser, venuePath, type StreamEvent } from '../src/admin/api';
import {
  areaOf,
  fromMap,
  metresLabel,
  metresToPx,
  planBounds,
  pxToMetres,
  scaleBar,
  scaleFromPoints,
  toMap,
} from '../src/admin/geometry';
import { placeGaps, stepsLeft } from '../src/admin/checklist';
import { checkPlace, exportPlaces, parsePlaces } from '../src/admin/places-io';
import { parseRoute } from '../src/admin/routes';

describe('metres and the map', () => {
  it('lat = -y, lng = x, and back', () => {
    expect(toMap(12.5, 3)).toEqual({ lat: -3, lng: 12.5 });
    expect(fromMap({ lat: -3, lng: 12.5 })).toEqual({ x: 12.5, y: 3 });
    for (const [x, y] of [
      [0, 0],
      [55.25, 27.5],
      [-1, 100],
    ])
      expect(fromMap(toMap(x, y))).toEqual({ x, y });
  });

  it('the plan spans [[-h/s, 0], [0, w/s]]; before a scale, metres are pixels', () => {
    expect(planBounds([1100, 600], 20)).toEqual([
      [-30, 0],
      [0, 55],
    ]);
    expect(planBounds([1100, 600], 1)).toEqual([
      [-600, 0],
      [0, 1100],
    ]);
  });

  it('plan pixels <-> metres', () => {
    expect(pxToMetres([400, 40], 20)).toEqual({ x: 20, y: 2 });
    expect(metresToPx({ x: 20, y: 2 }, 20)).toEqual([400, 40]);
  });

  it('a place keeps its metres when the plan is re-scaled: it moves on the picture, not in the building', () => {
    const place = { x: 11, y: 2 };
    expect(metresToPx(place, 20)).toEqual([220, 40]);
    expect(metresToPx(place, 40)).toEqual([440, 80]);
  });
});

describe('scale from two points', () => {
  it('pixels per metre is the pixel distance over the metres', () => {
    expect(scaleFromPoints([40, 40], [400, 40], 18)).toBe(20);
    expect(scaleFromPoints([0, 0], [30, 40], 5)).toBe(10);
  });

  it('refuses a zero distance and the same point twice', () => {
    expect(() => scaleFromPoints([0, 0], [10, 0], 0)).toThrow('more than 0 m');
    expect(() => scaleFromPoints([0, 0], [10, 0], Number.NaN)).toThrow('more than 0 m');
    expect(() => scaleFromPoints([5, 5], [5, 5], 3)).toThrow('same point');
  });
});

describe('scale bar', () => {
  it('the longest 1-2-5 length that fits', () => {
    expect(scaleBar(8, 120)).toEqual({ length: 10, px: 80 }); // 15 m fit: 10
    expect(scaleBar(2, 120)).toEqual({ length: 50, px: 100 }); // 60 m fit: 50
    expect(scaleBar(40, 120).length).toBe(2); // 3 m fit: 2
    expect(scaleBar(500, 120).length).toBe(0.2);
  });

  it('labels', () => {
    expect(metresLabel(50)).toBe('50 m');
    expect(metresLabel(0.5)).toBe('0.5 m');
    expect(metresLabel(2000)).toBe('2 km');
  });
});

it('an area from two corners in any order', () => {
  expect(areaOf({ x: 21, y: 3 }, { x: 1, y: 1 })).toEqual([1, 1, 21, 3]);
});

describe('place files', () => {
  const floors = ['1'];

  it('takes the docs/formats.md list and the API answer', () => {
    const list = [
      { name: ' North corridor ', floor: '1', x: 30, y: 4, area: [5, 2, 55, 6] },
      { name: 'the lifts', x: 27, y: 3, say: 'The lifts are on your left.', kind: 'lift' },
    ];
    const parsed = parsePlaces(JSON.stringify(list), floors);
    expect(parsed).toEqual([
      { name: 'North corridor', floor: '1', x: 30, y: 4, area: [5, 2, 55, 6] },
      { name: 'the lifts', floor: '1', x: 27, y: 3, say: 'The lifts are on your left.', kind: 'lift' },
    ]);
    expect(parsePlaces(JSON.stringify({ places: list }), floors)).toEqual(parsed);
  });

  it('names the place a problem is about', () => {
    const cases: [unknown, string][] = [
      [{ x: 1, y: 1 }, 'place 1: "name"'],
      [{ name: 'a', x: '1', y: 1 }, 'place 1 (a): "x" and "y"'],
      [{ name: 'a', x: 1, y: 1, floor: '2' }, 'no floor "2"'],
      [{ name: 'a', x: 1, y: 1, area: [0, 0, 1] }, '"area" must be'],
      [{ name: 'a', x: 1, y: 1, area: [5, 0, 1, 1] }, 'x0 < x1'],
      [{ name: 'a', x: 1, y: 1, say: 'x'.repeat(501) }, '"say"'],
      [{ name: 'a', x: 1, y: 1, kind: 'lobby' }, '"kind" must be one of room, door, lift'],
      [[1], 'is not an object'],
    ];
    for (const [p, msg] of cases) expect(() => checkPlace(p, 0, floors), msg).toThrow(msg);
    expect(() => parsePlaces('[{"name": "ok", "x": 1, "y": 1}, {"name": "b"}]', floors)).toThrow('place 2 (b)');
    expect(() => parsePlaces('{"name": "x"}', floors)).toThrow('JSON list');
    expect(() => parsePlaces('not json', floors)).toThrow('not JSON');
  });

  it('without a floor, the only floor, or "1" among several', () => {
    expect(checkPlace({ name: 'a', x: 0, y: 0 }, 0, ['G']).floor).toBe('G');
    expect(checkPlace({ name: 'a', x: 0, y: 0 }, 0, ['1', '2']).floor).toBe('1');
  });

  it('the export reads back as it was', () => {
    const places = [
      { id: 'a1', floor: '1', name: 'Room 1', x: 11, y: 2 },
      { id: 'b2', floor: '1', name: 'Corridor', x: 10, y: 2, area: [1, 1, 21, 3] as [number, number, number, number] },
    ];
    const text = exportPlaces(places);
    expect(text).not.toContain('a1');
    expect(parsePlaces(text, floors)).toEqual(places.map(({ id: _id, ...p }) => p));
  });
});

describe('event stream', () => {
  it('events in arbitrary pieces, comments skipped, CRLF and data lines joined', () => {
    const got: StreamEvent[] = [];
    const p = new EventParser((e) => got.push(e));
    const text =
      'event: progress\ndata: {"a":1}\n\n: still running\n\nevent: done\r\ndata: x\r\ndata: y\r\n\r\ndata: z\n\n';
    for (let i = 0; i < text.length; i += 3) p.push(text.slice(i, i + 3));
    expect(got).toEqual([
      { event: 'progress', data: '{"a":1}' },
      { event: 'done', data: 'x\ny' },
      { event: 'message', data: 'z' },
    ]);
  });
});

describe('routes', () => {
  it('#/venues, #/v/<id>/<screen>?query, and anything else', () => {
    expect(parseRoute('#/venues')).toEqual({ kind: 'venues' });
    expect(parseRoute('')).toEqual({ kind: 'venues' });
    const r = parseRoute('#/v/lab%201/walk-path?video=walk&floor=2');
    expect(r.kind).toBe('venue');
    if (r.kind !== 'venue') return;
    expect([r.id, r.screen, r.params.get('video'), r.params.get('floor')]).toEqual(['lab 1', 'walk-path', 'walk', '2']);
    expect(parseRoute('#/v/lab/nonsense')).toMatchObject({ kind: 'venue', screen: 'floor' });
  });

  it('opens a renamed screen by its old name (a bookmark of the last release)', () => {
    const r = parseRoute('#/v/lab/track?video=walk.mp4');
    if (r.kind !== 'venue') throw new Error('not a venue route');
    expect([r.screen, r.params.get('video')]).toEqual(['walk-path', 'walk.mp4']);
  });

  it('venue paths are escaped', () => {
    expect(venuePath('a b', '/places')).toBe('/api/admin/venues/a%20b/places');
  });
});

describe("what a venue's places leave the phone unable to say", () => {
  it('no place: only the floor; places without an area: never the corridor; an area: nothing to say', () => {
    expect(placeGaps([])).toMatch(/^No places yet: the phone can only say the floor/);
    const lifts = { id: 'p1', name: 'the lifts', floor: '1', x: 1, y: 1 };
    expect(placeGaps([lifts])).toMatch(/^No place has an area: .*never the corridor/);
    expect(placeGaps([lifts, { ...lifts, id: 'p2', name: 'Corridor 1', area: [0, 0, 10, 2] }])).toBeNull();
  });
});

describe("a venue's first-run checklist", () => {
  it('lists what is left, in order, each with its screen; nothing once the venue has it all', () => {
    const floor = { id: '1', name: 'Ground', plan_url: null, plan_size_px: null, px_per_m: null };
    const bare = {
      id: 'v',
      name: 'V',
      revision: 1,
      modelled: false,
      frames: 0,
      floors: [floor],
      places: [],
      lenses: {},
    };
    const v = bare as unknown as Parameters<typeof stepsLeft>[0];
    expect(stepsLeft(v).map((s) => s.screen)).toEqual(['floor', 'floor', 'places', 'places', 'lenses', 'videos']);
    const point = { id: 'p', name: 'the lifts', floor: '1', x: 1, y: 1 };
    const ready = {
      ...bare,
      modelled: true,
      floors: [{ ...floor, plan_url: '/plan.png', px_per_m: 10 }],
      places: [point],
      lenses: { donut: {} },
    } as unknown as Parameters<typeof stepsLeft>[0];
    // walked, but no corridor drawn as an area: the one step left
    expect(stepsLeft(ready)).toEqual([
      { screen: 'places', text: 'Draw the walked corridors as areas (the phone then says which one the user is in)' },
    ]);
    const all = { ...ready, places: [point, { ...point, id: 'c', name: 'Corridor 1', area: [0, 0, 9, 2] }] };
    expect(stepsLeft(all as typeof ready)).toEqual([]);

    // with the videos and jobs: every walked second in an area, each walk tagged and modelled,
    // a quality map and an evaluation; each missing piece is a step with its screen
    type Progress = NonNullable<Parameters<typeof stepsLeft>[1]>;
    const walk = (name: string, role: string, walkPath: unknown, status = 'modelled') =>
      ({
        name,
        role,
        floor: '1',
        status,
        has_walk_path: !!walkPath,
        walk_path: walkPath,
        fps: 30,
      }) as unknown as Progress['videos'][number];
    // 20 s east along y = 1 (in Corridor 1 up to x = 9), then 10 s south along x = 20 (in no area)
    const walkPath = {
      waypoints: [
        { t: 0, x: 0, y: 1 },
        { t: 20, x: 20, y: 1 },
        { t: 30, x: 20, y: 11 },
      ],
    };
    const job = (kind: string, state = 'done') => ({ kind, state }) as unknown as Progress['jobs'][number];
    const full: Progress = { videos: [walk('walk.mp4', 'model', walkPath)], jobs: [job('quality'), job('evaluate')] };
    const areas = stepsLeft(all as typeof ready, full);
    // 9 of the 20 s along y = 1 are in Corridor 1 (their middles at 0.5 .. 8.5 m), none of the next 10
    expect(areas).toEqual([
      {
        screen: 'places',
        text: "Draw areas along the rest of the walked corridors (21 of the walk's 30 seconds are in none)",
      },
    ]);
    const zoned = {
      ...all,
      places: [
        ...all.places,
        { ...point, id: 'd', name: 'Corridor 2', area: [8, 0, 21, 2] },
        { ...point, id: 'e', name: 'Corridor 3', area: [19, 0, 21, 12] },
      ],
    } as typeof ready;
    expect(stepsLeft(zoned, full)).toEqual([]);
    // a walk uploaded but not tagged, nothing modelled, no quality map, no evaluation
    const early: Progress = { videos: [walk('walk.mp4', 'model', null, 'ready')], jobs: [job('quality', 'failed')] };
    expect(stepsLeft({ ...zoned, modelled: false }, early)).toEqual([
      { screen: 'walk-path', text: 'Tag the walk path of walk.mp4', params: { video: 'walk.mp4' } },
      { screen: 'modelling', text: 'Model the tagged walks' },
      { screen: 'quality', text: 'Compute the quality map' },
      { screen: 'evaluation', text: 'Upload an evaluation walk, tag it and evaluate it' },
    ]);
    // tagged, not modelled again; no walk at all; an evaluation walk is not a modelling walk
    const tagged: Progress = { ...full, videos: [walk('walk.mp4', 'model', walkPath, 'ready')] };
    expect(stepsLeft(zoned, tagged).map((st) => st.text)).toEqual(['Model the newly tagged walks']);
    // a quality map and an evaluation from before the live modelling judged other frames: asked again
    const old = (kind: string) => ({ kind, state: 'done', finished: 100 }) as unknown as Progress['jobs'][number];
    const remodelled = { ...zoned, modelled_at: 200 };
    expect(stepsLeft(remodelled, { ...full, jobs: [old('quality'), old('evaluate')] }).map((st) => st.screen)).toEqual([
      'quality',
      'evaluation',
    ]);
    const fresh = (kind: string) => ({ kind, state: 'done', finished: 300 }) as unknown as Progress['jobs'][number];
    expect(stepsLeft(remodelled, { ...full, jobs: [fresh('quality'), fresh('evaluate')] })).toEqual([]);
    const none: Progress = { ...full, videos: [walk('eval.mp4', 'evaluation', walkPath)] };
    expect(stepsLeft(zoned, none).map((st) => st.text)).toEqual([
      'Upload a modelling walk',
      'Tag the walk path (where the walker was)',
    ]);
  });
});
