import { describe as group, expect, it } from 'vitest';
import { UNSURE, clockHour, describe, direction, gist, withArticle, type Answer } from '../src/client/directions';

const answer = (over: Partial<Answer> = {}): Answer => ({
  x: 14,
  y: 2.3,
  heading_deg: 250,
  confidence: 0.95,
  floor: '1',
  place: 'Room 1',
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
  it('clock faces: 12 ahead, 3 right, 6 behind, 9 left', () => {
    expect([0, 14, 16, 90, 180, -180, -90, -100, 345, -15].map(clockHour)).toEqual([12, 12, 1, 3, 6, 6, 9, 9, 12, 12]);
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
    expect(direction(88.4, 'degrees')).toBe('88 degrees right');
    expect(direction(-30.6, 'degrees')).toBe('31 degrees left');
    expect(direction(0.2, 'degrees')).toBe('straight ahead');
    expect(direction(270, 'degrees')).toBe('90 degrees left');
  });
  it('articles as the server uses them', () => {
    expect(withArticle('Corridor 1')).toBe('Corridor 1');
    expect(withArticle('North corridor')).toBe('the North corridor');
    expect(withArticle('the lifts')).toBe('the lifts');
    expect(withArticle('Hall B')).toBe('Hall B');
  });
});

group('the sentence', () => {
  it('area, then the nearest place in the chosen style, then what the user faces', () => {
    expect(describe(answer(), 'clock')).toBe(
      "You are in Corridor 1. Room 1 at 3 o'clock, 3 metres. Facing the entrance.",
    );
    expect(describe(answer(), 'sides')).toBe(
      'You are in Corridor 1. Room 1 to your right, 3 metres. Facing the entrance.',
    );
    expect(describe(answer(), 'degrees')).toBe(
      'You are in Corridor 1. Room 1 88 degrees right, 3 metres. Facing the entrance.',
    );
  });
  it('a far place is not "near"; the floor stands in for a missing area; facing the nearest is said once', () => {
    const far = answer({
      area: null,
      nearest: { name: 'the lifts', distance_m: 14, bearing_deg: 2 },
      facing: 'the lifts',
    });
    expect(describe(far, 'clock', 'Ground floor')).toBe('You are on Ground floor. Facing the lifts.');
    const near = answer({ nearest: { name: 'the lifts', distance_m: 1.2, bearing_deg: 2 }, facing: 'the lifts' });
    expect(describe(near, 'clock')).toBe("You are in Corridor 1. The lifts at 12 o'clock, 1 metre.");
  });
  it('low confidence says so instead of a place', () => {
    expect(describe(answer({ low_confidence: true }), 'clock')).toBe(UNSURE);
  });
  it('the gist changes with what would be said, not with small moves', () => {
    const a = gist(answer(), 'clock');
    expect(
      gist(
        answer({ x: 14.4, heading_deg: 252, nearest: { name: 'Room 1', distance_m: 3.0, bearing_deg: 86 } }),
        'clock',
      ),
    ).toBe(a);
    expect(gist(answer({ nearest: { name: 'Room 1', distance_m: 3.0, bearing_deg: 170 } }), 'clock')).not.toBe(a);
    expect(gist(answer({ area: 'Corridor 2' }), 'clock')).not.toBe(a);
    expect(gist(answer({ low_confidence: true }), 'clock')).toBe('unsure');
  });
});
