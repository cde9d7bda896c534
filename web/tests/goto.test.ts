// The Go to screen's list: places grouped by floor in the server's order, filtered by what is typed
// or heard (words in any order, plurals, accents, kinds), the status line's counts, what a voice
// filter says, and which buttons work in each state of the guide. The page itself is driven by the
// Playwright walk (e2e); these are the rules it shows.
import { describe, expect, it } from 'vitest';
import type { Destinations } from '../src/client/api';
import {
  controls,
  countLine,
  groups,
  heardLine,
  matches,
  normalise,
  onlyPlace,
  pickHeard,
  recognitionClass,
} from '../src/client/screens/goto';
import { routeLabel } from '../src/client/views/plan';

const D: Destinations = {
  venue: 'demo',
  floors: [
    {
      id: '1',
      name: 'Ground floor',
      places: [
        { id: 'p1', name: 'Café', kind: 'other', x: 1, y: 1 },
        { id: 'p2', name: 'Lifts', kind: 'lift', x: 2, y: 2 },
        { id: 'p3', name: 'Room 101', kind: 'room', x: 3, y: 3 },
        { id: 'p4', name: 'Room 102', kind: 'room', x: 4, y: 4 },
        { id: 'p5', name: 'Toilets', kind: 'toilet', x: 5, y: 5 },
      ],
    },
    { id: '0', name: 'Basement', places: [] },
    {
      id: '2',
      name: 'Floor 2',
      places: [
        { id: 'p6', name: 'Lifts', kind: 'lift', x: 2, y: 2 },
        { id: 'p7', name: 'Room 201', kind: 'room', x: 6, y: 6 },
        { id: 'p8', name: 'Main exit', kind: 'exit', x: 7, y: 7 },
      ],
    },
  ],
};

const names = (q: string) => groups(D, q).map((g) => [g.floor.name, g.places.map((p) => p.name)]);

describe('the destinations list', () => {
  it('groups the places by floor in the server order, leaving out a floor without places', () => {
    expect(names('')).toEqual([
      ['Ground floor', ['Café', 'Lifts', 'Room 101', 'Room 102', 'Toilets']],
      ['Floor 2', ['Lifts', 'Room 201', 'Main exit']],
    ]);
  });

  it.each([
    [
      'room',
      [
        ['Ground floor', ['Room 101', 'Room 102']],
        ['Floor 2', ['Room 201']],
      ],
    ],
    ['ROOM 10', [['Ground floor', ['Room 101', 'Room 102']]]],
    ['102 room', [['Ground floor', ['Room 102']]]],
    [
      'the lift',
      [
        ['Ground floor', ['Lifts']],
        ['Floor 2', ['Lifts']],
      ],
    ],
    [
      'lifts',
      [
        ['Ground floor', ['Lifts']],
        ['Floor 2', ['Lifts']],
      ],
    ],
    ['cafe', [['Ground floor', ['Café']]]],
    ['exit', [['Floor 2', ['Main exit']]]],
    ['toilet', [['Ground floor', ['Toilets']]]],
    ['  ', names('')],
    ['ballroom', []],
  ])('filter “%s”', (q, want) => {
    expect(names(q)).toEqual(want);
  });

  it('a kind finds its places, a word inside a name does not', () => {
    const lift = D.floors[0].places[1];
    expect(matches(lift, 'lift')).toBe(true);
    expect(matches(D.floors[0].places[2], 'oom')).toBe(false);
    expect(normalise('Room 1.02 (Café)')).toBe('room 1 02 cafe');
  });

  it('Enter chooses the one place listed, and only when there is one', () => {
    expect(onlyPlace(D, 'room 102')?.id).toBe('p4');
    expect(onlyPlace(D, 'exit')?.id).toBe('p8');
    expect(onlyPlace(D, 'lifts')).toBeNull(); // one on each floor
    expect(onlyPlace(D, 'no such place')).toBeNull();
    expect(onlyPlace(D, '')).toBeNull();
  });

  it('the status line counts what is listed', () => {
    expect(countLine(D, '')).toBe('8 places to go to.');
    expect(countLine(D, 'room ')).toBe('3 of 8 places match “room”.');
    expect(countLine(D, 'zzz')).toBe('No place matches “zzz”.');
    expect(countLine({ venue: 'x', floors: [] }, '')).toBe('No places to go to in this venue yet.');
  });
});

describe('the voice filter', () => {
  it('takes the first alternative that finds a place, and says what matches', () => {
    expect(pickHeard(['rum one oh two', 'room 102'], D)).toBe('room 102');
    expect(pickHeard(['ballroom'], D)).toBe('ballroom');
    expect(pickHeard([], D)).toBe('');
    expect(heardLine(D, 'room 102')).toBe('Room 102, Ground floor. Press it to hear the way.');
    expect(heardLine(D, 'lifts')).toBe('2 places match “lifts”: Lifts, Ground floor; Lifts, Floor 2.');
    expect(heardLine(D, 'ballroom')).toBe('No place matches “ballroom”. Press Say a place to try again, or type it.');
  });

  it('is offered only where the browser has speech recognition', () => {
    class Rec {}
    expect(recognitionClass({})).toBeNull();
    expect(recognitionClass({ webkitSpeechRecognition: Rec })).toBe(Rec);
    expect(recognitionClass({ SpeechRecognition: Rec, webkitSpeechRecognition: class {} })).toBe(Rec);
  });
});

describe('the route controls', () => {
  it.each([
    ['idle', false, { start: false, next: false, stop: false }],
    ['previewing', false, { start: false, next: false, stop: true }],
    ['ready', true, { start: true, next: true, stop: true }],
    ['guiding', true, { start: false, next: true, stop: true }],
    ['arrived', true, { start: true, next: true, stop: false }],
    ['stopped', false, { start: true, next: false, stop: false }],
  ] as const)('%s (an instruction: %s)', (state, has, want) => {
    expect(controls(state, has)).toEqual(want);
  });

  it('the plan says the route in words', () => {
    expect(
      routeLabel({
        ahead: [
          [0, 0],
          [10, 0],
        ],
        walked: [
          [0, 5],
          [0, 0],
        ],
        to: { name: 'Room 102', x: 10, y: 0 },
        remaining_m: 10.4,
        toName: 'Room 102',
      }),
    ).toBe(
      'Route: 10 metres to Room 102. The route ahead is drawn as a thick purple line, ending at a diamond. You have walked about 5 metres since you started.',
    );
  });
});
