// Speech never talks over itself: while a sentence is spoken, only the latest new one waits;
// urgent sentences (errors) cut in. A fake synthesiser stands in for the platform's voice.
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
});
