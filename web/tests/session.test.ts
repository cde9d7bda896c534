// "Keep telling me": the session asks every few seconds, never while a sentence is being spoken,
// and a stop ends its loop for good. whereAmI is stubbed: this is the loop, not the locating.
import { afterEach, beforeEach, describe, expect, it, vi } from 'vitest';
import { DEFAULTS } from '../src/client/prefs';
import { Session } from '../src/client/session';

function session() {
  const voice = { busy: false, say: vi.fn(), cue: vi.fn() };
  const s = new Session({
    prefs: { ...DEFAULTS, interval: 3 },
    save: vi.fn(),
    voice,
    video: {} as HTMLVideoElement,
    askedVenue: null,
  });
  const asked = vi.spyOn(s, 'whereAmI').mockResolvedValue();
  const pressed: boolean[] = [];
  s.on('continuous', (on) => pressed.push(on));
  return { s, voice, asked, pressed };
}

describe('continuous mode', () => {
  beforeEach(() => vi.useFakeTimers());
  afterEach(() => vi.useRealTimers());

  it('asks at once, then every interval, quietly; skips a turn while speech is busy; stops when told', async () => {
    const { s, voice, asked, pressed } = session();
    s.toggleContinuous();
    expect(pressed).toEqual([true]);
    expect(s.continuous).toBe(true);
    await vi.advanceTimersByTimeAsync(0);
    expect(asked.mock.calls).toEqual([[true]]);
    await vi.advanceTimersByTimeAsync(2999);
    expect(asked).toHaveBeenCalledTimes(1);
    await vi.advanceTimersByTimeAsync(1);
    expect(asked).toHaveBeenCalledTimes(2);
    voice.busy = true;
    await vi.advanceTimersByTimeAsync(3000);
    expect(asked).toHaveBeenCalledTimes(2);
    voice.busy = false;
    await vi.advanceTimersByTimeAsync(3000);
    expect(asked).toHaveBeenCalledTimes(3);
    s.toggleContinuous();
    expect(pressed).toEqual([true, false]);
    expect(voice.say).toHaveBeenCalledWith('Stopped telling you.', null);
    await vi.advanceTimersByTimeAsync(30_000);
    expect(asked).toHaveBeenCalledTimes(3);
  });

  it('a new interval applies to the running loop from its next wait', async () => {
    const { s, asked } = session();
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0); // first turn; the next one is due in 3 s
    s.prefs.interval = 10;
    await vi.advanceTimersByTimeAsync(3000);
    expect(asked).toHaveBeenCalledTimes(2);
    await vi.advanceTimersByTimeAsync(9999);
    expect(asked).toHaveBeenCalledTimes(2);
    await vi.advanceTimersByTimeAsync(1);
    expect(asked).toHaveBeenCalledTimes(3);
    s.stopContinuous();
  });

  it('a stop and a new start while a turn is still locating leave one loop, not two', async () => {
    const { s, asked } = session();
    let finish = () => {};
    asked.mockImplementationOnce(() => new Promise<void>((r) => (finish = r)));
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0); // the first turn is now locating
    s.toggleContinuous();
    s.toggleContinuous();
    finish();
    await vi.advanceTimersByTimeAsync(0); // the new loop's first turn
    expect(asked).toHaveBeenCalledTimes(2);
    await vi.advanceTimersByTimeAsync(3000);
    expect(asked).toHaveBeenCalledTimes(3);
    s.stopContinuous();
  });
});
