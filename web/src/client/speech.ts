/**
 * Speech, vibration and earcons. Speech never talks over itself: a new sentence while one is being
 * spoken waits, and only the latest waiting sentence is kept. iOS speaks only after a first
 * utterance made inside a user gesture, so `prime()` runs on the first tap.
 *
 * A screen reader reads the live regions aloud; the app's own voice on top of it would say every
 * sentence twice, at once. Browsers cannot tell whether a screen reader runs, so the user chooses
 * (Settings): with `screenReader` on, the app only writes the regions and cues, and stays silent.
 */

export type Cue = 'ok' | 'unsure' | 'error' | 'start';

const PATTERNS: Record<Cue, number[]> = { ok: [80], unsure: [80, 80, 80], error: [300], start: [30] };
// earcon tones (Hz, ms) where there is no vibration (iOS Safari)
const TONES: Record<Cue, [number, number][]> = {
  ok: [[880, 90]],
  unsure: [
    [440, 90],
    [0, 60],
    [440, 90],
  ],
  error: [[220, 250]],
  start: [[660, 40]],
};

export class Speaker {
  rate = 1;
  voiceName = '';
  cues = true;
  last = '';
  private waiting: string | null = null;
  private current: SpeechSynthesisUtterance | null = null;
  private pendingText: ReturnType<typeof setTimeout> | undefined;
  private primed = false;
  /** The silent first utterance went out inside a gesture (iOS speaks only after one). */
  private unlocked = false;
  private reader = false;
  private audio: AudioContext | null = null;
  private readonly synth: SpeechSynthesis | null = 'speechSynthesis' in globalThis ? speechSynthesis : null;

  constructor(
    private readonly live: HTMLElement,
    private readonly alert: HTMLElement,
  ) {}

  get available(): boolean {
    return this.synth !== null;
  }

  /** The user's screen reader reads the answers: the app never speaks (see the module's comment). */
  get screenReader(): boolean {
    return this.reader;
  }

  /**
   * Switched from Settings, so inside a gesture: turned on, what the app is saying stops (the
   * screen reader says it); turned off, speech is unlocked now if the first tap did not.
   */
  set screenReader(on: boolean) {
    if (on === this.reader) return;
    this.reader = on;
    if (on) {
      this.waiting = null;
      if (this.current) this.synth?.cancel();
      this.current = null; // its late end is ignored: only the current utterance's end counts
    } else if (this.primed) this.unlock();
  }

  /** Inside the first user gesture: unlock speech (iOS) and audio. */
  prime(): void {
    if (this.primed) return;
    this.primed = true;
    if (!this.reader) this.unlock();
    const AC =
      globalThis.AudioContext ??
      (globalThis as unknown as { webkitAudioContext?: typeof AudioContext }).webkitAudioContext;
    if (AC) {
      this.audio = new AC();
      void this.audio.resume().catch(() => undefined);
    }
  }

  /** A silent utterance, inside a gesture: iOS speaks only after one. */
  private unlock(): void {
    if (!this.synth || this.unlocked) return;
    this.unlocked = true;
    const u = new SpeechSynthesisUtterance(' ');
    u.volume = 0;
    this.synth.speak(u);
  }

  voices(): SpeechSynthesisVoice[] {
    return this.synth?.getVoices() ?? [];
  }

  /**
   * Say a sentence: in the live region (screen readers read it), aloud unless the user's screen
   * reader reads it, with a cue. `urgent` sentences (errors) go to the assertive region and are
   * spoken at once, cutting a waiting one. `remember` false: a passing word ("Keep turning slowly",
   * "Stopped") that Repeat skips, so that it still says the last answer.
   */
  say(text: string, cue: Cue | null = 'ok', urgent = false, remember = true): void {
    if (remember) this.last = text;
    const region = urgent ? this.alert : this.live;
    // one message on screen at a time: the other region empties, and its pending text is dropped
    clearTimeout(this.pendingText);
    this.live.textContent = '';
    this.alert.textContent = '';
    // the same text twice in a row would not be announced again: clear, then set a moment later
    // (a timer, not an animation frame: those stop while the screen is off)
    this.pendingText = setTimeout(() => (region.textContent = text), 50);
    if (cue) this.cue(cue);
    if (urgent) this.waiting = null;
    this.speak(text, urgent);
  }

  repeat(): void {
    if (this.last) this.say(this.last, null);
  }

  private speak(text: string, now: boolean): void {
    const synth = this.synth;
    // the screen reader reads the live region; `busy` stays false, so nothing waits for an end
    if (!synth || this.reader) return;
    if (this.current && !now) {
      this.waiting = text;
      return;
    }
    if (now) synth.cancel();
    const u = new SpeechSynthesisUtterance(text);
    u.rate = this.rate;
    u.lang = 'en';
    const v = this.voices().find((x) => x.name === this.voiceName);
    if (v) u.voice = v;
    this.current = u;
    // only this utterance's own end moves on: a cancelled one may report its end late
    const done = () => {
      if (this.current !== u) return;
      this.current = null;
      const next = this.waiting;
      this.waiting = null;
      if (next) this.speak(next, false);
    };
    u.onend = done;
    u.onerror = done;
    // a synthesiser that never reports the end (some Android voices) must not block speech forever
    setTimeout(done, 1500 + (120 * text.length) / Math.max(this.rate, 0.5));
    synth.speak(u);
  }

  /** The app's voice is saying a sentence (never with a screen reader: its reading is not known). */
  get busy(): boolean {
    return this.current !== null;
  }

  cue(kind: Cue): void {
    if (!this.cues) return;
    if (typeof navigator.vibrate === 'function' && navigator.vibrate(PATTERNS[kind])) return;
    this.beep(TONES[kind]);
  }

  private beep(tones: [number, number][]): void {
    const ac = this.audio;
    if (!ac) return;
    let t = ac.currentTime;
    for (const [hz, ms] of tones) {
      if (hz > 0) {
        const o = ac.createOscillator();
        const g = ac.createGain();
        o.frequency.value = hz;
        g.gain.setValueAtTime(0.2, t);
        g.gain.exponentialRampToValueAtTime(0.001, t + ms / 1000);
        o.connect(g).connect(ac.destination);
        o.start(t);
        o.stop(t + ms / 1000);
      }
      t += ms / 1000;
    }
  }
}
