// The pieces of the answer in words. The whole sentences, in every style, are pinned by the table
// that the engine's describe.py is held to as well (sentences.test.ts, tests/data/sentences.json).
import { describe as group, expect, it } from 'vitest';
import {
  SURE,
  SURE_LEAVE,
  change,
  clockHour,
  describe,
  direction,
  gist,
  withArticle,
  type Answer,
} from '../src/client/directions';
import { planLabel, planWay } from '../src/client/views/plan';

const answer = (over: Partial<Answer> = {}): Answer => ({
  clip: 'clip',
  x: 14,
  y: 2.3,
  heading_deg: 250,
  confidence: 0.95,
  floor: '1',
  place: 'Room 1',
  frame: 120,
  area: 'Corridor 1',
  nearest: { name: 'Room 1', distance_m: 3.2, bearing_deg: 88 },
  facing: 'the entrance',
  sentence: '',
  low_confidence: false,
  accuracy_m: 2,
  frames: 10,
  sent: 'features',
  ...over,
});

group('directions', () => {
  it('clock faces: 12 ahead, 3 right, 6 behind, 9 left; a boundary takes the hour nearer ahead', () => {
    expect([0, 14, 15, 16, 90, 180, -180, -90, -100, 345, -15, 45, -45].map(clockHour)).toEqual([
      12, 12, 12, 1, 3, 6, 6, 9, 9, 12, 12, 1, 11,
    ]);
  });
  it('left and right in six sectors', () => {
    expect(direction(0, 'sides')).toBe('straight ahead');
    expect(direction(40, 'sides')).toBe('ahead on your right');
    expect(direction(-90, 'sides')).toBe('to your left');
    expect(direction(140, 'sides')).toBe('behind you on your right');
    expect(direction(179, 'sides')).toBe('behind you');
    expect(direction(-170, 'sides')).toBe('behind you');
  });
  it('degrees, rounded, with a side', () => {
    expect(direction(88.4, 'degrees')).toBe('at 88 degrees to your right');
    expect(direction(-30.6, 'degrees')).toBe('at 31 degrees to your left');
    expect(direction(0.2, 'degrees')).toBe('straight ahead');
    expect(direction(270, 'degrees')).toBe('at 90 degrees to your left');
    expect(direction(1, 'degrees')).toBe('at 1 degree to your right');
  });
  it('articles as the server uses them', () => {
    expect(withArticle('Corridor 1')).toBe('Corridor 1');
    expect(withArticle('North corridor')).toBe('the North corridor');
    expect(withArticle('the lifts')).toBe('the lifts');
    expect(withArticle('Hall B')).toBe('Hall B');
  });
  it('the floor stands in for a missing area, by its number when the venue gives no name', () => {
    expect(describe(answer({ area: null, nearest: null, facing: null }), 'clock')).toBe('You are on floor 1.');
  });
});

group('what Keep telling me says when there is news', () => {
  const corridor = answer({
    area: 'Corridor 1',
    facing: null,
    nearest: { name: 'Room 1', distance_m: 3.0, bearing_deg: 86 },
  });
  it('in the same area: only the place near or reached, not the area again', () => {
    const next = answer({
      area: 'Corridor 1',
      facing: null,
      nearest: { name: 'Room 2', distance_m: 2.2, bearing_deg: -90 },
    });
    expect(change(corridor, next, 'clock')).toBe("Near Room 2 at 9 o'clock, 2 metres.");
    const at = answer({
      area: 'Corridor 1',
      facing: null,
      nearest: { name: 'Room 2', distance_m: 0.4, bearing_deg: 0 },
    });
    expect(change(next, at, 'sides')).toBe('At Room 2.');
    expect(change(next, { ...at, confidence: 0.7 }, 'clock')).toBe('Probably at Room 2.');
    // what the phone faces, when that changed too
    expect(change(corridor, { ...next, facing: 'the lifts' }, 'clock')).toBe(
      "Near Room 2 at 9 o'clock, 2 metres, facing the lifts.",
    );
  });
  it('another area or floor, a first answer, an unsure one, nothing near: the whole sentence', () => {
    const other = answer({
      area: 'Corridor 2',
      facing: null,
      nearest: { name: 'Room 5', distance_m: 2, bearing_deg: 0 },
    });
    expect(change(corridor, other, 'clock')).toBe(describe(other, 'clock'));
    expect(change(null, corridor, 'clock')).toBe(describe(corridor, 'clock'));
    expect(change(answer({ low_confidence: true }), corridor, 'clock')).toBe(describe(corridor, 'clock'));
    const open = answer({ area: 'Corridor 1', facing: null, nearest: null });
    expect(change(corridor, open, 'clock')).toBe('You are in Corridor 1.');
  });
});

group('the gist', () => {
  it('changes with the news (another area, another place near, a place reached), not with each step or glance', () => {
    const a = gist(answer());
    expect(
      gist(answer({ x: 14.4, heading_deg: 252, nearest: { name: 'Room 1', distance_m: 3.0, bearing_deg: 86 } })),
    ).toBe(a);
    // walked past it (now behind), or turned to face something else: not news
    expect(gist(answer({ nearest: { name: 'Room 1', distance_m: 3.0, bearing_deg: 170 } }))).toBe(a);
    expect(gist(answer({ facing: 'the lifts' }))).toBe(a);
    expect(gist(answer({ nearest: { name: 'Room 2', distance_m: 3.0, bearing_deg: 86 } }))).not.toBe(a);
    expect(gist(answer({ area: 'Corridor 2' }))).not.toBe(a);
    expect(gist(answer({ low_confidence: true }))).toBe('unsure');
  });

  it('outside every area with nothing near: a new nearest place is news, its distance and way are not', () => {
    const far = (name: string, distance_m: number, bearing_deg: number) =>
      gist(answer({ area: null, facing: null, nearest: { name, distance_m, bearing_deg } }));
    const a = far('the lifts', 31, 90);
    expect([far('the lifts', 24, 150), far('the lifts', 18.5, -20)]).toEqual([a, a]);
    expect(far('Room 102', 22, 90)).not.toBe(a);
    expect(far('the lifts', 9, 90)).not.toBe(a); // near now: said with its way
  });

  it('standing at a place (under a metre): the same gist whichever way the noise points, until the user leaves it', () => {
    const at = (distance_m: number, bearing_deg: number) =>
      gist(answer({ nearest: { name: 'the entrance', distance_m, bearing_deg } }));
    const here = at(0.3, 90);
    expect([at(0.6, 0), at(0.1, 180), at(0.9, -90)]).toEqual([here, here, here]);
    expect(at(1.4, 90)).not.toBe(here);
  });

  it('once at a place, stays at it until half a metre past the metre: no flip-flop about 1 m', () => {
    const g = (distance_m: number, last = '') =>
      gist(answer({ nearest: { name: 'the lifts', distance_m, bearing_deg: 90 } }), last);
    const at = g(0.8);
    const near = g(1.1);
    expect(near).not.toBe(at); // from afar, "at" begins under a metre
    expect([g(1.1, at), g(1.45, at)]).toEqual([at, at]);
    expect(g(1.6, at)).toBe(near); // left it: "near the lifts at 3 o'clock" again
    // another place's "at" is no reason to stay: the rule is per place
    const elsewhere = gist(answer({ nearest: { name: 'Room 1', distance_m: 0.5, bearing_deg: 0 } }));
    expect(g(1.1, elsewhere)).toBe(near);
  });

  it('"probably" firming up to sure is said again; a wobble about the sure line is not', () => {
    const g = (confidence: number, last = '') => gist(answer({ confidence }), last);
    const probably = g(SURE - 0.05);
    const sure = g(SURE);
    expect(sure).not.toBe(probably); // "You are probably in ..." then "You are in ..."
    expect(g(SURE - 0.01, probably)).toBe(probably);
    // once sure, it stays sure down to SURE_LEAVE, then is "probably" again
    expect([g(SURE - 0.05, sure), g(SURE_LEAVE, sure)]).toEqual([sure, sure]);
    expect(g(SURE_LEAVE - 0.01, sure)).toBe(probably);
    // and only from SURE back up
    expect(g(SURE, probably)).toBe(sure);
    expect(g(0.3, sure)).toBe(probably); // not low: still a place, said as probably
  });

  it('the margin holds at the same place only: another place is said as describe says it', () => {
    const at = (confidence: number, area: string, last = '') => gist(answer({ confidence, area }), last);
    const sureA = at(0.9, 'Corridor 1');
    const b = at(0.75, 'Corridor 2', sureA); // "You are probably in the Corridor 2 ..." is what is said
    expect(b).toBe(at(0.75, 'Corridor 2'));
    expect(b.startsWith('probably|')).toBe(true);
    expect(at(0.85, 'Corridor 2', b)).not.toBe(b); // firming up there is said
    // without `last`, the gist of the sentence said (what the session keeps after speaking)
    expect(gist(answer({ confidence: 0.75 })).startsWith('probably|')).toBe(true);
    expect(describe(answer({ confidence: 0.75 }), 'clock')).toMatch(/^You are probably /);
  });
});

group("the plan's text alternative", () => {
  it('says "probably" where the sentence does, and no position where it is not sure', () => {
    const a = answer({ area: 'Corridor 1', nearest: { name: 'Room 1', distance_m: 3.2, bearing_deg: 88 } });
    expect(planLabel('Floor 1', a)).toBe(
      'Floor plan of Floor 1: you are in Corridor 1, within about 2 m, facing the left of the plan; nearest place Room 1, 3 m away.',
    );
    const p = answer({ confidence: SURE - 0.01 });
    expect(planLabel('Floor 1', p)).toMatch(/^Floor plan of Floor 1: you are probably in Corridor 1, /);
    expect(describe(p, 'clock')).toMatch(/^You are probably in Corridor 1, /);
    expect([0, 22.4, 22.5, 90, 181, 300, 337.6, -10].map(planWay)).toEqual([
      'the top',
      'the top',
      'the top right',
      'the right',
      'the bottom',
      'the top left',
      'the top',
      'the top',
    ]);
    expect(planLabel('Floor 1', answer({ low_confidence: true }))).toBe(
      'Floor plan of Floor 1: no position shown, the last answer was not sure.',
    );
  });
});
