/**
 * The guidance loop (issue 14): take the user to a chosen place. Choosing a place locates once in
 * a new tracking session with `to` and says the route's preview ("Room 102: 45 metres, 2 turns,
 * first turn after 12 metres."); Start says the current instruction from a fresh answer (its
 * request films ~1 s, so that it comes soon), then films and locates again and again with the
 * phone's motion since the previous request: WALK_SECONDS a request, all the loop can film but
 * the answer's time and a MIN_GAP_MS pause (the server's filter walks it second by second: an
 * unseen second of walking is evidence lost; on the venue families it was never tuned on, more of
 * the walk filmed is right more often: docs/benchlog.md, "Filming throughout");
 * the server's filter and guide decide what is new, and this loop speaks only what it marks
 * `speak`. Off the route, arrival and a turn before its corner cut in (urgent); "not sure" is said once per spell; arrival
 * ends the loop, and only a sure one does: "You are probably at ..." (`probably_arrived`, a pose
 * under 0.8 or a track that has not settled) cuts in too, but the loop goes on until the server is
 * sure or guides on elsewhere. The screen is kept on while guiding (wakelock.ts) and the motion sensors run
 * (motion.ts) only then.
 *
 * The motion sent is what the phone felt since the session's previous answered request: a
 * request's reading counts as sent only once it is answered (a failed one's steps go with the
 * next), and the first request after Start, or after the page was hidden, sends none ("unknown"):
 * the server's time gap then covers walking that was not counted, and too few steps would make
 * the filter lose the user. While the page is hidden (the screen locked, another app, a call) the
 * loop pauses, and it goes on in the same session when the page is shown again; what went wrong
 * meanwhile is not said, nor does it end guidance. A camera taken by another app is said once,
 * and tried again.
 *
 * It owns no part of the page and no camera: the session films and locates (Session.track), the
 * Voice speaks, the screen (screens/goto.ts) listens to its events. Every dependency is passed in,
 * so that Vitest drives it with fake timers, a fake server and a fake voice.
 */
import { ApiProblem, Unreachable, newSessionId, type Answer, type Guidance } from './api';
import { CameraProblem } from './camera';
import { GUIDE_UNSURE_CHOSEN, type Style } from './directions';
import type { Motion, MotionReading } from './motion';
import { RecordMismatch, mapUpdated, problemText } from './problems';
import { Emitter, type Voice } from './session';
import type { Cue } from './speech';

/** From the start of one request to the start of the next (ms), at least: filming, then the answer. */
export const INTERVAL_MS = 2000;
/** What a request of the walk films after Start's first (s): all but the answer's time. */
export const WALK_SECONDS = 2;
/** At least this long between two requests (ms), however slow the last one was. */
export const MIN_GAP_MS = 250;
/** While the camera is taken by a "Where am I?", ask again this often (ms) for the preview. */
const BUSY_RETRY_MS = 500;
const BUSY_TRIES = 20;
/**
 * The screen-lock note waits until the voice is silent and the guide has said nothing for this
 * long (ms): said at once it would take the instruction's place in the live region before a
 * screen reader read it (and hold the instruction back).
 */
export const NOTE_QUIET_MS = 2000;
const NOTE_POLL_MS = 250;

export const STOPPED_GUIDANCE = 'Stopped guidance.';
export const NO_GUIDANCE =
  'This omninav server cannot guide you to places yet. Ask the venue’s administrator to update it.';
export const GUIDE_UNREACHABLE =
  'Cannot reach the omninav server; still trying. Check that the phone is on the building’s Wi-Fi.';
export const GUIDE_BUSY = 'The server is busy; still trying.';
export const GUIDE_MAP_UPDATED = 'The building’s map has just been updated; guidance goes on with the new one.';
export const SCREEN_ON =
  'This phone may lock its screen while you walk, and guidance then goes quiet. Set the phone to lock later, or unlock it when guidance goes quiet.';
export const CHOOSE_FIRST = 'Choose a place to go to first.';
export const GUIDE_CAMERA_BUSY =
  'The camera is in use by another app or a call; guidance goes on once it is free again.';
export const PREVIEW_CAMERA_BUSY =
  'The camera is in use by another app or a call. Choose the place again once it is free.';
export const CAMERA_TAKEN = 'The camera is still busy answering Where am I?. Choose the place again in a moment.';

/** A place to go to (a destination of GET /destinations). */
export interface Target {
  id: string;
  name: string;
}

/** How guidance is put into words in the user's style (directions.ts; fakes in tests). */
export interface Words {
  guidance(g: Guidance, style: Style): string;
  preview(g: Guidance): string;
}

export interface GuideDeps {
  voice: Voice;
  /**
   * Film `seconds` (less, never under 1 s, once `stop` says so) and locate them once in a
   * tracking session (Session.track); null: the camera is taken, try later.
   */
  track(
    q: { session: string; to: string; style: Style },
    motion: () => Motion,
    seconds: number,
    stop: () => boolean,
  ): Promise<Answer | null>;
  /**
   * The phone's motion (MotionFeed): `peek` reads what happened since the last `commit`, which
   * the guide calls once the request that carried the reading was answered.
   */
  motion: { start(): void; stop(): void; peek(): MotionReading; commit(r: MotionReading): void };
  screen: { hold(): Promise<boolean>; release(): Promise<void> };
  /** Asks for the motion sensors; must be called inside the Start tap (iOS). */
  askMotion(): Promise<void>;
  style(): Style;
  words: Words;
  /** A new tracking session id; random by default. */
  newSession?: () => string;
  /** Whether the page is on screen, and when that changes: the document by default. */
  page?: PageHost;
}

/** The document's visibility (a fake in tests). */
export interface PageHost {
  readonly hidden: boolean;
  addEventListener(type: 'visibilitychange', fn: () => void): void;
  removeEventListener(type: 'visibilitychange', fn: () => void): void;
}

/** The page's document; always shown where there is none. */
function pageHost(): PageHost {
  const d = (globalThis as { document?: PageHost }).document;
  return d ?? { hidden: false, addEventListener: () => undefined, removeEventListener: () => undefined };
}

const UNKNOWN: Motion = { steps: null, turn_deg: null };

/**
 * idle: nothing chosen; previewing: the first answer for a chosen place is on its way; ready: the
 * preview was said, Start may be pressed; guiding: the loop runs; arrived; stopped (by the user or
 * by a problem that more requests cannot mend).
 */
export type GuideState = 'idle' | 'previewing' | 'ready' | 'guiding' | 'arrived' | 'stopped';

export interface GuideEvents {
  state: GuideState;
  /** A new answer with its guidance (for the text and the plan). */
  guidance: { guidance: Guidance; answer: Answer };
  /** What was said about a problem, or '' once requests answer again. */
  problem: string;
}

/** Where the user is, not what to do: no instruction in them ("not sure", "outside the mapped area"). */
const LOST_KINDS = new Set<Guidance['kind']>(['unsure', 'not_here']);
// probably arrived cuts in too: the walker should stop and listen, though guidance goes on
const URGENT_KINDS = new Set<Guidance['kind']>(['off_route', 'arrived', 'probably_arrived']);

/** The vibration or earcon with a sentence: reassurance comes without one, so walking stays quiet. */
function cueOf(g: Guidance): Cue | null {
  if (g.kind === 'off_route') return 'error';
  if (LOST_KINDS.has(g.kind)) return 'unsure';
  if (g.kind === 'continue' || g.kind === 'reassure') return null;
  return 'ok';
}

/**
 * A problem that more requests will not mend: guidance stops after saying it. A camera taken by
 * another app (a call) is given back; a lens that does not fit may be moved. (A camera refused
 * while the page is hidden does not get here: the loop pauses instead.)
 */
function fatal(e: unknown): boolean {
  if (e instanceof CameraProblem) return e.kind !== 'lens' && e.kind !== 'busy';
  if (e instanceof RecordMismatch) return true;
  // the venue modelled anew meanwhile: the session reads it again at the next turn, and guidance goes on
  if (mapUpdated(e)) return false;
  if (e instanceof ApiProblem) return e.status === 400 || e.status === 404 || e.status === 409 || e.status === 422;
  // the server cannot guide at all; anything else (the network, a worker's hiccup) may pass
  return e instanceof Error && e.message === NO_GUIDANCE;
}

/** What the user hears about a problem while guided: what went wrong, and whether it goes on. */
export function guideProblemText(e: unknown, to: Target | null, guiding = true): string {
  if (e instanceof Unreachable) return GUIDE_UNREACHABLE;
  if (mapUpdated(e)) return GUIDE_MAP_UPDATED;
  if (e instanceof ApiProblem) {
    if (e.status === 429 || e.status >= 500) return GUIDE_BUSY;
    if (e.status === 404 && /no place/i.test(e.message))
      return `${to?.name ?? 'That place'} is no longer a place omninav can guide you to. Choose another one.`;
  }
  // while guiding the loop tries again; the preview is asked for again by choosing the place
  if (e instanceof CameraProblem && e.kind === 'busy') return guiding ? GUIDE_CAMERA_BUSY : PREVIEW_CAMERA_BUSY;
  if (e instanceof Error && (e.message === NO_GUIDANCE || e.message === CAMERA_TAKEN)) return e.message;
  return problemText(e);
}

/** The run a timer or an answer belongs to: a stop or a new place starts another, so old ones fall silent. */
interface Run {
  timer?: ReturnType<typeof setTimeout>;
  /** The screen-lock note's wait. */
  note?: ReturnType<typeof setTimeout>;
  /** The page was hidden at the loop's turn: the next one waits for it to be shown. */
  paused?: boolean;
  /** An instruction (or "not sure") was said in this run. */
  spoke?: boolean;
  /** A request of the loop was answered in this run (until then each films 1 s). */
  answered?: boolean;
}

function endRun(run: Run): void {
  clearTimeout(run.timer);
  clearTimeout(run.note);
}

export class Guide extends Emitter<GuideEvents> {
  state: GuideState = 'idle';
  /** The chosen place. */
  place: Target | null = null;
  /** The latest guidance, and the latest that was an instruction (What next? says it). */
  latest: Guidance | null = null;
  /** The chosen place's route in words ("Room 102: 45 metres, 2 turns, ..."), once known. */
  previewText = '';
  private current: Guidance | null = null;
  private session = '';
  private run: Run = {};
  private unsureSaid = false;
  private lastSpoken = '';
  private problemSaid = '';
  private screenTold = false;
  /** The screen could not be kept on: to be said once the run spoke and the voice is quiet (noteLater). */
  private screenNote = false;
  /** Start's instruction is still to be said (whatever the server marks), by the first sure answer. */
  private owed = false;
  /** The motion since the last answered request can be sent: not on the first request after Start or a hidden page. */
  private motionKnown = false;
  /** How often the page was hidden: a request during which it was is not judged by its failure. */
  private hides = 0;
  /** When the guide last said anything (ms, Date.now()). */
  private saidAt = -Infinity;
  private readonly page: PageHost;

  constructor(private readonly d: GuideDeps) {
    super();
    this.page = d.page ?? pageHost();
  }

  private set(state: GuideState): void {
    this.state = state;
    this.emit('state', state);
  }

  private newRun(): Run {
    endRun(this.run);
    this.run = {};
    return this.run;
  }

  /** Everything the guide says goes through here: when it last spoke delays the screen-lock note. */
  private voice(text: string, cue: Cue | null, urgent: boolean, remember = true): void {
    this.d.voice.say(text, cue, urgent, remember);
    this.saidAt = Date.now();
  }

  /** An instruction (or "not sure"), remembered so that it is not said twice running. */
  private say(text: string, cue: Cue | null, urgent = false): void {
    this.voice(text, cue, urgent);
    this.lastSpoken = text;
    this.run.spoke = true;
  }

  /**
   * Words for an instruction in the user's style, said as the words make them: on arrival they
   * carry the place's own sentence (the guidance's `to.say`, from the server), once. Nothing is
   * added here: a second copy from the venue the app loaded would be said twice, or an old one
   * beside the new once the place was edited.
   */
  words(g: Guidance): string {
    return this.d.words.guidance(g, this.d.style());
  }

  /**
   * One request, waiting while the camera is taken; null when this run ended meanwhile. The
   * motion is read once the clip is filmed and counts as sent only when the request is answered.
   */
  private async request(run: Run, patient: boolean, seconds = 1): Promise<Answer | null> {
    for (let i = 0; ; i++) {
      let reading: MotionReading | null = null;
      const hides = this.hides;
      const q = { session: this.session, to: this.place!.id, style: this.d.style() };
      const motion = () => {
        reading = this.d.motion.peek();
        return this.motionKnown && this.hides === hides
          ? { steps: reading.steps, turn_deg: reading.turn_deg }
          : UNKNOWN;
      };
      const a = await this.d.track(q, motion, seconds, () => run !== this.run); // Stop: film no more
      if (run !== this.run) return null;
      if (a && reading) {
        // the server has this request's time now: the next motion counts from its clip, and is
        // known unless the page was hidden meanwhile (the sensors stop then)
        this.d.motion.commit(reading);
        this.motionKnown = this.hides === hides && !this.page.hidden;
      }
      if (a || !patient || i >= BUSY_TRIES) return a;
      await new Promise((r) => setTimeout(r, BUSY_RETRY_MS));
      if (run !== this.run) return null;
    }
  }

  /** A place was chosen: a new session, one answer, its preview said. */
  async choose(place: Target): Promise<void> {
    this.halt(); // a new run: whatever the last one still had in flight is dropped
    const run = this.run;
    this.place = place;
    this.session = this.d.newSession?.() ?? newSessionId();
    this.latest = this.current = null;
    this.previewText = '';
    this.unsureSaid = false;
    this.lastSpoken = '';
    this.problemSaid = '';
    this.motionKnown = false;
    this.set('previewing');
    try {
      const a = await this.request(run, true);
      if (run !== this.run) return;
      if (!a) throw new Error(CAMERA_TAKEN);
      const g = a.guidance;
      if (!g) throw new Error(NO_GUIDANCE);
      if (g.preview && g.kind !== 'unsure') this.previewText = this.d.words.preview(g);
      this.show(g, a);
      if (g.kind === 'arrived') {
        this.say(this.words(g), 'ok', true);
        this.halt();
        this.set('arrived');
        return;
      }
      if (g.kind === 'unsure') {
        this.unsureSaid = true;
        this.say(GUIDE_UNSURE_CHOSEN, 'unsure');
      } else this.say(this.previewText || this.words(g), 'ok');
      this.set('ready');
    } catch (e) {
      if (run !== this.run) return;
      this.problem(e);
      // nothing to guide by yet: the user chooses the place again (or another)
      this.set('stopped');
    }
  }

  /** Start: inside the tap (motion permission), then the current instruction and the loop. */
  start(): void {
    const asked = this.d.askMotion(); // first, still inside the user's gesture
    if (!this.place) {
      this.d.voice.say(CHOOSE_FIRST, 'error', true, false);
      return;
    }
    if (this.state === 'guiding' || this.state === 'previewing') return;
    const run = this.newRun();
    this.set('guiding');
    void asked.finally(() => {
      if (run === this.run) this.d.motion.start();
    });
    // where the screen cannot be kept on, the user hears so once, after the first instruction
    // and once the voice is silent (said at once, it would take the instruction's place)
    void this.d.screen.hold().then((held) => {
      if (!held && !this.screenTold && run === this.run) {
        this.screenNote = true;
        this.noteLater(run);
      }
    });
    this.page.removeEventListener('visibilitychange', this.onVisibility);
    this.page.addEventListener('visibilitychange', this.onVisibility);
    this.unsureSaid = false;
    this.lastSpoken = '';
    this.owed = true;
    this.screenNote = false;
    // the counts since the session's previous request were lost with the sensors: none sent
    this.motionKnown = false;
    void this.tick(run);
  }

  /** Hidden: requests pause (the camera stops); shown again: the loop goes on in the same session. */
  private readonly onVisibility = (): void => {
    if (this.page.hidden) {
      this.hides++;
      this.motionKnown = false;
      return;
    }
    const run = this.run;
    if (this.state !== 'guiding' || !run.paused) return;
    run.paused = false;
    void this.tick(run);
  };

  private async tick(run: Run): Promise<void> {
    if (this.page.hidden) {
      run.paused = true; // onVisibility goes on
      return;
    }
    const started = Date.now();
    const hides = this.hides;
    let again = true;
    try {
      // Start's request films 1 s (its instruction soon); then all the loop can film, unsure or
      // not (the unseen walk is lost evidence, and an unsure start needs it most)
      // (the first to be answered: a retry after a taken camera or an error is still quick)
      const a = await this.request(run, false, run.answered ? WALK_SECONDS : 1);
      if (run !== this.run) return;
      if (a) run.answered = true;
      if (!a) return; // the camera is taken: the next turn asks again
      const g = a.guidance;
      if (!g) throw new Error(NO_GUIDANCE);
      if (this.problemSaid) {
        this.problemSaid = '';
        this.emit('problem', '');
      }
      again = this.answered(g, a);
    } catch (e) {
      if (run !== this.run) return;
      // the page was hidden meanwhile: the browser stops the camera (a refusal, an ended stream)
      // and the network; nothing is said, and the loop goes on once the page is shown
      if (!this.page.hidden && this.hides === hides) {
        this.problem(e);
        if (fatal(e)) {
          this.halt();
          this.set('stopped');
          again = false;
        }
      }
    } finally {
      if (run === this.run && again && this.state === 'guiding') {
        const wait = Math.max(MIN_GAP_MS, INTERVAL_MS - (Date.now() - started));
        run.timer = setTimeout(() => void this.tick(run), wait);
      }
    }
  }

  private show(g: Guidance, a: Answer): void {
    this.latest = g;
    if (!LOST_KINDS.has(g.kind)) this.current = g;
    this.emit('guidance', { guidance: g, answer: a });
  }

  /** Speak what is new in an answer; false when guidance ends with it (arrival). */
  private answered(g: Guidance, a: Answer): boolean {
    this.show(g, a);
    const first = this.owed;
    if (LOST_KINDS.has(g.kind)) {
      // "not sure" once a spell; "outside the mapped area" when the server marks it, even inside
      // a spell of "not sure": it is news
      if ((g.speak || first) && (g.kind === 'not_here' || !this.unsureSaid)) this.say(this.words(g), 'unsure');
      this.unsureSaid = true;
      return true;
    }
    this.unsureSaid = false;
    this.owed = false;
    const urgent = g.urgent || URGENT_KINDS.has(g.kind);
    const text = this.words(g);
    // the first answer after Start is said whatever the server marks; a sentence just said is not
    // said again unless it is urgent
    if (first || (g.speak && (urgent || text !== this.lastSpoken))) this.say(text, cueOf(g), urgent);
    if (g.kind === 'arrived' || g.arrived) {
      this.halt();
      this.set('arrived');
      return false;
    }
    return true;
  }

  /**
   * Once per app run: the screen will lock by itself. Said after the run's first instruction,
   * once the voice is silent and the guide said nothing for NOTE_QUIET_MS: a sentence said while
   * another waits for its 50 ms live-region write would take its place (Speaker.say), and a
   * screen reader would never get the instruction.
   */
  private noteLater(run: Run): void {
    const check = (): void => {
      if (run !== this.run || !this.screenNote || this.screenTold) return;
      const quiet = !this.d.voice.busy && Date.now() - this.saidAt >= NOTE_QUIET_MS;
      if (run.spoke && quiet && !this.page.hidden) {
        this.screenNote = false;
        this.screenTold = true;
        this.voice(SCREEN_ON, null, false, false);
        return;
      }
      run.note = setTimeout(check, NOTE_POLL_MS);
    };
    check();
  }

  private problem(e: unknown): void {
    const text = guideProblemText(e, this.place, this.state === 'guiding');
    if (text === this.problemSaid) return;
    this.voice(text, 'error', true);
    this.problemSaid = text;
    this.emit('problem', text);
  }

  /** What next?: the current instruction again, in the user's style (or that it is not sure). */
  whatNext(): void {
    const g = this.latest && LOST_KINDS.has(this.latest.kind) ? this.latest : this.current;
    if (!g) {
      this.voice(this.place ? 'No instruction yet.' : CHOOSE_FIRST, null, false, false);
      return;
    }
    this.say(this.words(g), null);
  }

  /** Stop guidance: the loop, the sensors and the screen lock end; said. */
  stop(): void {
    if (this.state !== 'guiding' && this.state !== 'ready' && this.state !== 'previewing') return;
    this.halt();
    this.set('stopped');
    this.voice(STOPPED_GUIDANCE, null, false, false);
  }

  /** End the loop quietly: timers, sensors, screen lock. */
  private halt(): void {
    this.newRun();
    this.page.removeEventListener('visibilitychange', this.onVisibility);
    this.d.motion.stop();
    void this.d.screen.release();
  }
}
