// Speech never talks over itself: while a sentence is spoken, only the latest new one waits;
// urgent sentences (errors) cut in. With the user's screen reader reading, the app stays silent.
// A fake synthesiser stands in for the platform's voice.
import { afterEach, beforeEach, describe, expect, it, vi } from 'vitest';

class FakeUtterance {
  rate = 1;
  lang = '';
  volume = 1;
  voice: unknown = null;
  onend: (() => void) | null = null;
  onerror: (() => void) | null = null;
  constructor(readonly text: string) {}
}

const synth = {
  spoken: [] as FakeUtterance[],
  cancelled: 0,
  speak(u: FakeUtterance) {
    this.spoken.push(u);
  },
  cancel() {
    this.cancelled++;
  },
  getVoices: () => [],
};

const region = () => ({ textContent: '' }) as unknown as HTMLElement;

describe('Speaker', () => {
  beforeEach(() => {
    vi.useFakeTimers();
    synth.spoken = [];
    synth.cancelled = 0;
    vi.stubGlobal('speechSynthesis', synth);
    vi.stubGlobal('SpeechSynthesisUtterance', FakeUtterance);
    vi.stubGlobal('navigator', {}); // no vibration: the earcon path, silent without an AudioContext
  });
  afterEach(() => {
    vi.useRealTimers();
    vi.unstubAllGlobals();
  });

  it('waits for the current sentence, keeps only the latest waiting one, and writes the live region', async () => {
    const { Speaker } = await import('../src/client/speech');
    const live = region();
    const s = new Speaker(live, region());
    s.say('one');
    s.say('two');
    s.say('three');
    expect(synth.spoken.map((u) => u.text)).toEqual(['one']);
    expect(s.busy).toBe(true);
    vi.advanceTimersByTime(60);
    expect(live.textContent).toBe('three'); // the screen reader gets the latest at once
    synth.spoken[0].onend!();
    expect(synth.spoken.map((u) => u.text)).toEqual(['one', 'three']);
    synth.spoken[1].onend!();
    expect(s.busy).toBe(false);
    s.repeat();
    expect(synth.spoken.at(-1)!.text).toBe('three');
  });

  it('a passing word is said but Repeat still says the last answer', async () => {
    const { Speaker } = await import('../src/client/speech');
    const live = region();
    const s = new Speaker(live, region());
    s.say('You are in Corridor 1.');
    synth.spoken[0].onend!();
    s.say('Stopped.', null, false, false);
    vi.advanceTimersByTime(60);
    expect(live.textContent).toBe('Stopped.');
    synth.spoken[1].onend!();
    s.repeat();
    expect(synth.spoken.at(-1)!.text).toBe('You are in Corridor 1.');
  });

  it('an urgent sentence cancels what is being said and drops what waits', async () => {
    const { Speaker } = await import('../src/client/speech');
    const alert = region();
    const s = new Speaker(region(), alert);
    s.say('You are in Corridor 1.');
    s.say('waiting');
    s.say('The camera is blocked.', 'error', true);
    vi.advanceTimersByTime(60);
    expect(alert.textContent).toBe('The camera is blocked.');
    expect(synth.cancelled).toBe(1);
    expect(synth.spoken.map((u) => u.text)).toEqual(['You are in Corridor 1.', 'The camera is blocked.']);
    synth.spoken[0].onend!(); // the cancelled utterance reports its end late: the urgent one still speaks
    expect(s.busy).toBe(true);
    s.say('after');
    expect(synth.spoken).toHaveLength(2);
    synth.spoken[1].onend!();
    expect(synth.spoken.map((u) => u.text)).toEqual(['You are in Corridor 1.', 'The camera is blocked.', 'after']);
    synth.spoken[2].onend!();
    vi.advanceTimersByTime(60);
    expect(alert.textContent).toBe(''); // the answer said after the error replaced it on screen too
  });

  it('a synthesiser that never reports the end does not block speech for good', async () => {
    const { Speaker } = await import('../src/client/speech');
    const s = new Speaker(region(), region());
    s.rate = 1;
    s.say('a sentence that never ends');
    s.say('next');
    vi.advanceTimersByTime(10_000);
    expect(synth.spoken.map((u) => u.text)).toEqual(['a sentence that never ends', 'next']);
  });

  describe('with the screen reader reading the answers', () => {
    it('never speaks, yet writes the live and alert regions, cues, and is never busy', async () => {
      const { Speaker } = await import('../src/client/speech');
      const vibrated: number[][] = [];
      vi.stubGlobal('navigator', { vibrate: (p: number[]) => vibrated.push(p) > 0 });
      const live = region();
      const alert = region();
      const s = new Speaker(live, alert);
      s.screenReader = true;
      s.prime(); // the first tap: nothing to unlock for a voice that never speaks
      s.say('You are in Corridor 1.');
      expect(s.busy).toBe(false); // "Keep telling me" and the guide's note wait for nothing
      vi.advanceTimersByTime(60);
      expect(live.textContent).toBe('You are in Corridor 1.');
      s.say('The camera is blocked.', 'error', true);
      vi.advanceTimersByTime(60);
      expect([live.textContent, alert.textContent]).toEqual(['', 'The camera is blocked.']);
      expect(vibrated).toEqual([[80], [300]]);
      expect(synth.spoken).toEqual([]);
      expect(synth.cancelled).toBe(0);
    });

    it('Repeat announces the last answer again: the region is emptied, then set', async () => {
      const { Speaker } = await import('../src/client/speech');
      const live = region();
      const s = new Speaker(live, region());
      s.screenReader = true;
      s.say('You are in Corridor 1.');
      s.say('Stopped.', null, false, false);
      vi.advanceTimersByTime(60);
      s.repeat();
      expect(live.textContent).toBe(''); // a screen reader announces a change, not the same text
      vi.advanceTimersByTime(60);
      expect(live.textContent).toBe('You are in Corridor 1.');
      s.repeat();
      expect(live.textContent).toBe('');
      vi.advanceTimersByTime(60);
      expect(live.textContent).toBe('You are in Corridor 1.');
      expect(synth.spoken).toEqual([]);
    });

    it('switched on mid-sentence, the voice stops; switched back off, the app speaks again', async () => {
      const { Speaker } = await import('../src/client/speech');
      const s = new Speaker(region(), region());
      s.say('one');
      s.say('waiting');
      s.screenReader = true;
      expect(synth.cancelled).toBe(1);
      expect(s.busy).toBe(false);
      synth.spoken[0].onend!(); // the cancelled sentence's late end does not bring the waiting one
      s.say('quiet');
      expect(synth.spoken.map((u) => u.text)).toEqual(['one']);
      s.screenReader = false;
      s.say('aloud');
      expect(synth.spoken.map((u) => u.text)).toEqual(['one', 'aloud']);
      expect(s.busy).toBe(true);
    });

    it('a first tap in screen-reader mode: choosing the app voice later unlocks speech then', async () => {
      const { Speaker } = await import('../src/client/speech');
      const s = new Speaker(region(), region());
      s.screenReader = true;
      s.prime();
      expect(synth.spoken).toEqual([]);
      s.screenReader = false; // from Settings: inside a gesture, as iOS needs
      expect(synth.spoken.map((u) => [u.text, u.volume])).toEqual([[' ', 0]]);
      s.screenReader = true;
      s.screenReader = false; // once is enough
      expect(synth.spoken).toHaveLength(1);
    });
  });
});
