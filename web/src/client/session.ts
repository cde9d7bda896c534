/**
 * The phone's session: the venue in use, the lens, the camera, the feature worker, and the locate
 * loop ("Where am I?" once, or "Keep telling me" every few seconds). It owns no part of the page:
 * screens listen to its events and show them; what it says goes through a Voice.
 *
 * A press films a second, and films on while that second is answered. When the answer is not
 * one to trust (TRUSTED_CONFIDENCE), the session says so, films on to 3 s in all while the user keeps turning, and sends the
 * three seconds as one clip: one more request, answered from all of it (the engine takes clips of
 * up to 5 s). Once per press; Stop ends it. A sure answer ends the filming on, unsent.
 *
 * A guided walk (guide.ts) asks `track()` instead: one second (the walk's later requests: two,
 * everything the loop can film between two answers, which the server's filter walks second by
 * second), located in a tracking session with the phone's clock and motion; the guide says what
 * is to be said. "Keep telling me" is such a walk
 * too: each turn locates with `track()` in one tracking session per start, so that the server's
 * filter remembers where the user was (on venues it was never tuned on, far fewer confident
 * answers far off than single clips): its first turn one second, every turn after an answered
 * one KEEP_SECONDS, at the same pace. It does not film on when unsure (the walk itself settles an unsure start) and
 * says only what changed.
 */
import {
  ApiProblem,
  UNREACHABLE,
  Unreachable,
  locate,
  newSessionId,
  type Tracked,
  venue as fetchVenue,
  venues as fetchVenues,
  type Venue,
} from './api';
import { CameraProblem, captureClip, grabFrame, joinClips, lensMismatch, openCamera, type Clip } from './camera';
import { SURE, change, describe, gist, type Answer } from './directions';
import { ExtractorClient } from './bridge';
import { LensWatch, checkLensOn, lensWords, phoneStorage } from './lenscheck';
import type { Motion, MotionFeed, MotionReading } from './motion';
import type { Lens } from '../shared/lens';
import type { LensCheck } from '../shared/protocol';
import { encodeRecord, recordMismatch, unknownFeatureKeys, type LocalBlock } from '../shared/record';
import type { Prefs } from './prefs';
import { NO_FRAMES, NO_LENS, RecordMismatch, mapUpdated, problemText, staleOrNot } from './problems';
import type { Cue } from './speech';
import { Standby } from './standby';

const CLIP_FRAMES = 10; // ~1 s at 10 fps: enough for the clip to outvote a single wrong frame
/** Frames filmed after a first answer that was not sure: 3 s in all, sent as one clip. */
export const MORE_FRAMES = 20;
const CLIP_INTERVAL_MS = 100;
/** The most frames a tracked request films (4.5 s at 10 fps; the server takes up to 5 s). */
const MAX_TRACK_FRAMES = 45;
/**
 * An answer a user may trust without more evidence: the line under which an answer is said as
 * "probably" (directions.ts's SURE). Below it, a press films on to 3 s.
 */
export const TRUSTED_CONFIDENCE = SURE;
const trusted = (a: Answer): boolean => !a.low_confidence && a.confidence >= TRUSTED_CONFIDENCE;
/** Said (polite, no cue) when the first second was not enough and the phone films on. */
export const KEEP_TURNING = 'Not sure yet. Keep turning slowly.';
/**
 * What a turn of "Keep telling me" films once one of its turns was answered (the first films 1 s,
 * so that the first answer comes as soon as ever): twice the evidence at the same pace, since the
 * wait after it is a second shorter. On the held-out venue families, with the phone's motion,
 * 93.3 -> 96.2 % of the answers within 2 m and "sure" 58 -> 85 % (docs/benchlog.md, "Keep
 * telling me").
 */
export const KEEP_SECONDS = 2;
/** Said when "Keep telling me" stops: pressed again, or another screen shown. */
export const STOPPED_TELLING = 'Stopped telling you.';

/** Said, and nothing started, when "Keep telling me" is pressed while a guided walk is on. */
export const GUIDING_NOW =
  'You are being guided, and guidance tells you as you walk. To hear where you are instead, stop guidance on the Go to screen.';
/** Said when Stop ends that filming: nothing is sent. */
export const STOPPED = 'Stopped.';
const RECHECK_MS = 500;
/**
 * A lens check beside the first second that moves the worker's profile by this much or more films
 * that second again. Less is kept: the accuracy benchmarks perturb every query by a 2 px lens shift.
 */
const REFILM_PX = 1;
/** How often a turn of "Keep telling me" looks again while a sentence is still being spoken. */
const BUSY_POLL_MS = 500;
/** On the venue line of a venue that checks answers with keypoints the user has not allowed. */
export const VERIFY_HINT =
  'This building can double-check answers if you turn on Send keypoints in Settings; that sends a little more about what your camera sees.';
/** The name the user's own lens profile is offered under, beside the venue's. */
export const MY_LENS = 'my lens';

/** What the session says: the Speaker, or a fake in tests. */
export interface Voice {
  say(text: string, cue?: Cue | null, urgent?: boolean, remember?: boolean): void;
  cue(kind: Cue): void;
  /** A sentence is being spoken. */
  readonly busy: boolean;
}

export interface SessionOptions {
  prefs: Prefs;
  save: (p: Prefs) => void;
  voice: Voice;
  /** The camera plays into it and clips are grabbed from it (it is never shown). */
  video: HTMLVideoElement;
  /** `?venue=` in the page's address: it wins over the saved choice. */
  askedVenue: string | null;
  /**
   * The phone's motion for "Keep telling me" (a MotionFeed of its own, not the guide's): `peek`
   * once a turn's clip is filmed, `commit` once it was answered. None: no steps or turn are sent.
   */
  motion?: Pick<MotionFeed, 'start' | 'stop' | 'peek' | 'commit'>;
  /** Asks for the motion sensors; called inside the tap that starts "Keep telling me" (iOS). */
  askMotion?: () => Promise<void>;
  /**
   * A guided walk is on (guide.ts): it already tells the user as they walk, and "Keep telling me"
   * beside it would take the camera from it every other turn and talk over it.
   */
  guiding?: () => boolean;
  /**
   * The last second may be kept now (standby.ts: the screen, the page shown, the phone held up,
   * the user's setting). Absent: never; every request films its own first second.
   */
  standby?: () => boolean;
}

/** A run of "Keep telling me": a new object per start, so that a stopped loop cannot revive. */
interface Loop {
  timer?: ReturnType<typeof setTimeout>;
  /** Its tracking session: a new one per start, so that the server starts over. */
  session: string;
  /** One of its turns was answered (until then each films 1 s). */
  answered?: boolean;
}

/** An answer and how it was made (for the helpers' details). */
export interface Located {
  answer: Answer;
  venue: Venue;
  recordBytes: number;
  frames: number;
  camera: [number, number];
  lens: string;
  fps: number;
  medianMs: number;
  rttMs: number;
  /** The last lens check (a donut lens), in words, and its ring finding per frame. */
  lensCheck?: { message: string; ms: number };
  /** Its first second was the one kept before the press (standby.ts), not filmed after it. */
  kept: boolean;
  /** The worker's share of the time while standing by (0-1), or null (no standby yet). */
  duty: number | null;
  /** Keypoints sent with the clip's last frame (a verifying venue, allowed in Settings), and their time in the worker. */
  keypoints?: number | null;
  keypointMs?: number;
}

export interface SessionEvents {
  /** The server's venues, and the one in use. */
  venues: { list: { id: string; name: string }[]; chosen: string };
  /** The lens profiles offered for the venue in use, and the chosen one. */
  lenses: { names: string[]; chosen: string };
  /** A venue document was loaded. */
  venue: Venue;
  /** The venue's name and state, or why it did not load. */
  line: string;
  /** A "Where am I?" started (true) or ended (false). */
  busy: boolean;
  answer: Located;
  /**
   * The sentence the last answer stands for, as said: in "Keep telling me" an answer about what was
   * said already ("at the lifts", kept until half a metre past the metre) is not said again, and
   * shows the sentence that was said, not its own slightly other words.
   */
  said: string;
  /** "Keep telling me" is on or off. */
  continuous: boolean;
  /** The first second was not sure: filming more (true), until that ends or is stopped (false). */
  asking: boolean;
  /** A preference was set. */
  pref: keyof Prefs;
  /** The lens was checked (the ring found in the camera's frames and compared with the profile). */
  lens: LensCheck;
}

/** Why this app cannot make the venue's records, or null. */
function mismatchOf(v: Venue): RecordMismatch | null {
  const why = recordMismatch(v.features);
  return why === null ? null : new RecordMismatch(why, unknownFeatureKeys(v.features).length > 0);
}

/** What every request needs before filming (Session.ready). */
interface Ready {
  v: Venue;
  lens: [string, Lens];
  ext: ExtractorClient;
  /** The camera was opened for this request. */
  fresh: boolean;
  donut: boolean;
}

/**
 * A named moment of a request on the page's performance timeline ("omninav: camera open"): what a
 * press waits on, for the browser's profiler and bench/press.mjs; each press clears the last one's.
 */
function mark(what: string): void {
  // a press starts the timeline afresh: marks would otherwise pile up for as long as the page lives
  if (what === 'press')
    for (const m of performance.getEntriesByType('mark'))
      if (m.name.startsWith('omninav: ')) performance.clearMarks(m.name);
  performance.mark(`omninav: ${what}`);
}

const median = (v: number[]): number => v.slice().sort((a, b) => a - b)[v.length >> 1] ?? 0;

/** Typed listeners, in the order they were added. */
export class Emitter<E> {
  private listeners: { [K in keyof E]?: ((v: E[K]) => void)[] } = {};

  on<K extends keyof E>(kind: K, fn: (v: E[K]) => void): void {
    (this.listeners[kind] ??= []).push(fn);
  }

  protected emit<K extends keyof E>(kind: K, v: E[K]): void {
    for (const fn of this.listeners[kind] ?? []) fn(v);
  }
}

export class Session extends Emitter<SessionEvents> {
  readonly prefs: Prefs;
  /** The venue in use; null until loaded, and again when it must be asked for afresh. */
  venue: Venue | null = null;
  lastAnswer: Answer | null = null;
  /** Its venue line: the reason given when no venue could be loaded. */
  private line = '';
  private ext: ExtractorClient | null = null;
  private stream: MediaStream | null = null;
  // the correction in use is kept on the phone between runs (only its numbers: nothing of a frame)
  private readonly lensWatch = new LensWatch(phoneStorage());
  private lastCheck: LensCheck | null = null;
  private busy = false;
  /** The sentence of the answer last said (Located's `said`), and that answer. */
  private lastSaid = '';
  private lastTold: Answer | null = null;
  /** What was last said (or would have been): continuous mode speaks only when it changes. */
  private lastGist = '';
  /** The running continuous loop. */
  private loop: Loop | null = null;
  /** A turn of the loop is filming or being answered (tellTracked). */
  private inTurn = false;
  /** "Where am I?" was pressed while a turn of the loop ran: that turn's answer is said in full. */
  private pressedInTurn = false;
  /** The filming on after a press's first second; `stopped` ends it (an answer, Stop). */
  private filming: { stopped: boolean } | null = null;
  /** The first second was not sure: that filming goes on for an answer (Stop would end it). */
  private askingMore = false;
  /** The last second, kept while the camera is open and nothing films (null: not asked for). */
  private readonly standby: Standby | null;
  /** The lens in use is a donut's (its check comes before any frame is kept). */
  private donut = false;
  /**
   * The last first second was the one kept before the press (firstClip): of the press or turn being
   * answered, since one films at a time (read by located() and by "Keep telling me").
   */
  private lastKept = false;
  /** The keypoints a frame the worker was last told are wanted (prepareLocal; -1: its telling failed). */
  private localPrepared = 0;

  constructor(private readonly o: SessionOptions) {
    super();
    this.prefs = o.prefs;
    const allowed = o.standby;
    this.standby = allowed
      ? new Standby({
          size: CLIP_FRAMES,
          intervalMs: CLIP_INTERVAL_MS,
          // nothing is grabbed while a request films its own frames
          grab: () => (this.busy || !this.ext || !this.cameraLive() ? null : grabFrame(o.video, this.ext)),
          // a donut lens is checked before any frame of it is kept
          allowed: () =>
            allowed() && this.cameraLive() && !(this.donut && this.lensWatch.due(this.ext?.configured ?? null)),
          key: () => this.ext?.configured ?? null,
          // the camera ended (the phone locked, another app took it): the next request starts it again
          gone: () => !this.cameraLive(),
        })
      : null;
  }

  /** The camera is open and gives frames. */
  private cameraLive(): boolean {
    return !!this.stream?.getVideoTracks().some((t) => t.readyState === 'live');
  }

  /** Set and keep one preference; a new venue is loaded at once. */
  set<K extends keyof Prefs>(key: K, value: Prefs[K]): void {
    this.prefs[key] = value;
    this.o.save(this.prefs);
    this.emit('pref', key);
    if (key === 'venue') {
      this.venue = null;
      void this.loadVenue();
    } else if (key === 'keypoints' && this.venue) {
      this.setLine(this.lineOf(this.venue)); // the hint comes or goes
      // the worker readied for them (or let go of them) now, not on the next press; the lens and
      // its correction stay as they are
      if (this.ext) void this.prepareLocal(this.ext, this.venue);
    }
  }

  /** The venue's lens profiles, and the user's own one when they loaded it. */
  lensesOf(v: Venue): Record<string, Lens> {
    return this.prefs.myLens ? { ...v.lenses, [MY_LENS]: this.prefs.myLens } : v.lenses;
  }

  chosenLens(v: Venue): [string, Lens] | null {
    const all = this.lensesOf(v);
    const names = Object.keys(all);
    const name = names.includes(this.prefs.lens) ? this.prefs.lens : names[0];
    return name ? [name, all[name]] : null;
  }

  /** Offer the user's own (already checked) lens profile and use it from now on. */
  useMyLens(lens: Lens): void {
    this.prefs.myLens = lens;
    this.prefs.lens = MY_LENS;
    this.o.save(this.prefs);
    if (this.venue) this.emit('lenses', { names: Object.keys(this.lensesOf(this.venue)), chosen: MY_LENS });
  }

  /** The sentence for an answer in the user's style, with the floor's name from the venue. */
  sentence(a: Answer, v: Venue): string {
    return describe(a, this.prefs.style, v.floors.find((f) => f.id === a.floor)?.name);
  }

  /**
   * Load the chosen venue (or the first modelled one: a venue an admin has only begun cannot answer
   * a new user; else the first); start the feature worker on its lens meanwhile.
   */
  async loadVenue(): Promise<Venue | null> {
    try {
      const list = await fetchVenues();
      if (!list.length) return this.setLine('This server has no venues yet.');
      const want = this.o.askedVenue || this.prefs.venue;
      const id = list.some((v) => v.id === want) ? want : (list.find((v) => v.modelled) ?? list[0]).id;
      this.emit('venues', { list, chosen: id });
      const v = await fetchVenue(id);
      this.venue = v;
      this.prefs.venue = id;
      const lens = this.chosenLens(v);
      this.emit('lenses', { names: Object.keys(this.lensesOf(v)), chosen: lens?.[0] ?? '' });
      const missing = want && want !== id ? `This server has no venue “${want}”; showing ${v.name} instead. ` : '';
      this.setLine(missing + this.lineOf(v));
      if (lens) {
        this.ext ??= new ExtractorClient();
        // warm up (errors surface on use); the keypoints' detector too, so the standby keeps frames for them
        const ext = this.ext;
        ext
          .configure(lens[1], v.features.settings)
          .then(() => this.prepareLocal(ext, v))
          .catch(() => undefined);
      }
      this.emit('venue', v);
      return v;
    } catch (e) {
      return this.setLine(e instanceof Unreachable ? UNREACHABLE : `The venue did not load: ${(e as Error).message}`);
    }
  }

  /** The venue line of a loaded venue: its name and state, or why this app cannot use it. */
  private lineOf(v: Venue): string {
    const mismatch = mismatchOf(v); // shown now on the venue line, not only when the user asks
    if (!v.modelled) return `Venue: ${v.name}. Not modelled yet.`;
    if (mismatch) return `Venue: ${v.name}. ${mismatch.message}`;
    return `Venue: ${v.name}. Ready (${v.frames} modelled frames).${this.verifyHint(v)}`;
  }

  /**
   * The ORB keypoints to send with a single request's last frame: the venue's count where it
   * verifies answers with them and the user allowed it (Settings), else 0.
   */
  keypointsFor(v: Venue): number {
    return this.prefs.keypoints === true ? (v.features.settings.local_features ?? 0) : 0;
  }

  /**
   * The worker told how many keypoints a frame are wanted now (keypointsFor), when that changed:
   * it keeps its last frames and a detector only while some are. A failure leaves the curves to
   * answer (and is tried again at the next request).
   */
  private async prepareLocal(ext: ExtractorClient, v: Venue): Promise<void> {
    const n = this.keypointsFor(v);
    if (n === this.localPrepared) return;
    this.localPrepared = n;
    await ext.prepareLocal(n).catch(() => (this.localPrepared = -1));
  }

  /** Said on the venue line where the venue could check answers and the user has not allowed it. */
  private verifyHint(v: Venue): string {
    return v.features.settings.local_features && this.prefs.keypoints !== true ? ` ${VERIFY_HINT}` : '';
  }

  /**
   * The keypoints of a clip's last frame where they are to be sent now (keypointsFor: the setting
   * is read at each request, so turning it off stops the very next one), else null. The worker
   * keeps the last few frames it extracted: asked as soon as the clip is complete. A failure
   * leaves the curves to answer alone.
   */
  private keypoints(ext: ExtractorClient, v: Venue, clip: Clip): Promise<(LocalBlock & { ms: number }) | null> {
    const last = clip.frames[clip.frames.length - 1]?.id;
    return this.keypointsFor(v) && last !== undefined ? ext.local(last).catch(() => null) : Promise.resolve(null);
  }

  private setLine(text: string): null {
    this.line = text;
    this.emit('line', text);
    return null;
  }

  /**
   * The venue, its lens, the camera and the feature worker, ready to film: the first steps of
   * every request (a venue not modelled yet may have been since: the server is asked again).
   */
  private async ready(): Promise<Ready> {
    const v = this.venue?.modelled ? this.venue : await this.loadVenue();
    if (!v) throw new Unreachable(this.line || UNREACHABLE);
    if (!v.modelled) throw new ApiProblem(409, NO_FRAMES);
    const mismatch = mismatchOf(v);
    if (mismatch) throw mismatch;
    const lens = this.chosenLens(v);
    if (!lens) throw new ApiProblem(422, NO_LENS);
    const ext = (this.ext ??= new ExtractorClient());
    const configured = ext.configure(lens[1], v.features.settings).then(() => this.prepareLocal(ext, v));
    const video = this.o.video;
    // a stream ends when the phone locks or another app takes the camera: open it again
    if (this.stream?.getVideoTracks().every((t) => t.readyState === 'ended')) this.stream = null;
    let fresh = false;
    if (!this.stream) {
      this.stream = await openCamera(video, lens[1]);
      mark('camera open');
      this.lensWatch.reset(); // a new session of the camera: the lens may sit elsewhere now
      fresh = true;
    }
    const bad = lensMismatch(video.videoWidth, video.videoHeight, lens[1], lens[0]);
    if (bad) throw new CameraProblem('lens', bad);
    await configured;
    this.donut = lens[1].model === 'catadioptric';
    this.standby?.start();
    return { v, lens, ext, fresh, donut: this.donut };
  }

  /**
   * ~1 s of frames: the second kept before the press when there is one (standby.ts), else filmed
   * now. A donut lens due a check (a camera just opened) is checked while the second is filmed: a
   * check that changes the worker's profile films it again, through the new one. A picture that
   * jumped since the last check is checked again, and filmed again. A 360 camera has no ring.
   */
  private async firstClip(r: Ready): Promise<Clip> {
    const { ext, donut } = r;
    const due = donut && this.lensWatch.due(ext.configured);
    const kept = due ? null : (this.standby?.take() ?? null);
    this.lastKept = !!kept && !(donut && this.lensWatch.changed(kept.frames));
    if (kept && this.lastKept) return kept;
    const film = (stop?: () => boolean) => captureClip(this.o.video, ext, CLIP_FRAMES, CLIP_INTERVAL_MS, stop);
    if (due) {
      const stopped = { now: false };
      const filming = film(() => stopped.now);
      filming.catch(() => undefined); // a failed check is the error said
      const { check, again } = await this.checkLens(ext, r.fresh).catch((e: unknown) => {
        stopped.now = true;
        throw e;
      });
      mark('lens checked');
      // the frames beside it are not the lens's now (the profile moved), or not the picture the
      // check passed (it had to look again: the camera was still settling): film the second anew
      if (again || check.changed_px >= REFILM_PX) {
        stopped.now = true;
        return film();
      }
      const clip = await filming;
      return this.lensWatch.changed(clip.frames) ? film() : clip;
    }
    const clip = await film();
    if (!donut || !this.lensWatch.changed(clip.frames)) return clip;
    await this.checkLens(ext);
    return film();
  }

  /**
   * `seconds` of frames (at most 4.5 s: the server takes 5 s at the fps the phone measured, which
   * a slow camera makes lower than 10): the first second as firstClip, then filmed on to follow it
   * until `stop` says so (Stop guidance): never less than the first second.
   */
  private async longClip(r: Ready, seconds: number, stop: () => boolean): Promise<Clip> {
    const first = await this.firstClip(r);
    const more = Math.min(MAX_TRACK_FRAMES, Math.round((seconds * 1000) / CLIP_INTERVAL_MS)) - first.frames.length;
    if (more <= 0 || stop()) return first;
    const rest = await captureClip(this.o.video, r.ext, more, CLIP_INTERVAL_MS, stop, first);
    return rest.frames.length ? joinClips(first, rest) : first;
  }

  /** An answer with how it was made, for the screens. */
  private located(a: Answer, r: Ready, clip: Clip, recordBytes: number, rttMs: number): Located {
    const ms = clip.frames.map((f) => f.ms).sort((x, y) => x - y);
    const video = this.o.video;
    return {
      answer: a,
      venue: r.v,
      recordBytes,
      frames: clip.frames.length,
      camera: [video.videoWidth, video.videoHeight],
      lens: r.lens[0],
      fps: clip.fps,
      medianMs: ms[ms.length >> 1],
      rttMs,
      lensCheck:
        r.donut && this.lastCheck ? { message: this.lastCheck.message, ms: median(this.lastCheck.ms) } : undefined,
      kept: this.lastKept,
      duty: this.standby?.duty() ?? null,
    };
  }

  /**
   * One "Where am I?": capture ~1 s, extract in the worker, send features only, say the answer;
   * when that answer is not sure, answer once more from the 3 s filmed (see the top of the file).
   */
  async whereAmI(): Promise<void> {
    if (this.busy) {
      // a turn of "Keep telling me" is filming or being answered: its answer is this press's, said
      // in full when it comes (another press's own answer is on its way already)
      if (this.inTurn) this.pressedInTurn = true;
      return;
    }
    this.busy = true;
    mark('press');
    this.emit('busy', true);
    try {
      try {
        await this.answerHere();
      } catch (e) {
        // the venue was modelled anew since it was read: read it again and film once more (its
        // frames were extracted with the old settings), rather than have the user press again
        if (!mapUpdated(e)) throw e;
        this.venue = null;
        await this.answerHere();
      }
    } catch (e) {
      this.forgetVenueOn(e);
      this.sayProblem(e, false);
    } finally {
      this.busy = false;
      this.emit('busy', false);
    }
  }

  /** The work of one "Where am I?" (whereAmI): errors are thrown, for it to say. */
  private async answerHere(): Promise<void> {
    const { voice, video } = this.o;
    let filming: { stopped: boolean } | null = null;
    try {
      const r = await this.ready();
      const { v, ext } = r;
      voice.cue('start');
      let clip = await this.firstClip(r);
      // the keypoints of the clip's last frame: asked before the worker is given the next one
      const first = this.keypoints(ext, v, clip);
      // film on while the first second is answered: an unsure answer then needs no gap in the clip
      const more = { stopped: false };
      filming = this.filming = more;
      const rest = captureClip(video, ext, MORE_FRAMES, CLIP_INTERVAL_MS, () => more.stopped, clip);
      rest.catch(() => undefined); // a failure matters only when the frames are used (filmMore)
      let local = await first;
      let record = encodeRecord(clip.frames, v.features.settings, v.features.settings_id, local);
      const ask = (): Promise<Answer> =>
        locate(v.id, record, clip.fps, `web-${Date.now()}`).catch((e: unknown) => {
          throw staleOrNot(e, v.features.settings_id);
        });
      /** An answer shown and said (`quiet`: only if it is news since the last said); the press's first marked. */
      let marked = false;
      const answered = (a: Answer, rttMs: number, quiet: boolean): void => {
        if (!marked) mark('answer');
        marked = true;
        this.lastAnswer = a;
        this.emit('answer', {
          ...this.located(a, r, clip, record.length, rttMs),
          keypoints: local ? local.az.length : null,
          keypointMs: local?.ms,
        });
        this.tell(a, v, quiet, false);
      };
      let t0 = performance.now();
      mark('first second');
      const a = await ask();
      if (trusted(a)) {
        more.stopped = true;
        return answered(a, performance.now() - t0, false);
      }
      // a place, though not sure of it ("probably"), is said at once while the phone films on, and
      // the longer clip's answer only if it is news (another place, or now sure); "not sure" asks
      // the user to keep turning (a first answer of 0.57-0.66, right, was "not sure yet" before)
      const probable = !a.low_confidence;
      if (probable) answered(a, performance.now() - t0, false);
      const longer = await this.filmMore(clip, rest, more, !probable);
      if (!longer) return; // stopped: nothing sent, nothing more said
      clip = longer;
      local = await this.keypoints(ext, v, clip); // of the longer clip's last frame
      record = encodeRecord(clip.frames, v.features.settings, v.features.settings_id, local);
      t0 = performance.now();
      const b = await ask();
      // not sure after a "probably" is no news: it would take back the place the user just heard
      if (probable && b.low_confidence) return;
      answered(b, performance.now() - t0, probable);
    } finally {
      if (filming) filming.stopped = true;
      if (this.filming === filming) this.filming = null;
    }
  }

  /**
   * Say an answer; `quiet`: only when what it is about changed since the last said (continuous
   * mode, a press's longer clip after a "probably"); `news` (continuous mode): then only what
   * changed, not the area the user is still in.
   */
  private tell(a: Answer, v: Venue, quiet: boolean, news = quiet): void {
    const g = gist(a, this.lastGist);
    const say = !quiet || g !== this.lastGist;
    if (say) {
      const floor = v.floors.find((f) => f.id === a.floor)?.name;
      this.lastSaid = news ? change(this.lastTold, a, this.prefs.style, floor) : this.sentence(a, v);
      this.lastTold = a;
      this.o.voice.say(this.lastSaid, a.low_confidence ? 'unsure' : 'ok');
    }
    this.emit('said', this.lastSaid);
    // what was said is what the next answer is compared with: its own gist, without the margins
    // that kept the last one ("probably" said at 0.75 after a sure answer is remembered as said)
    this.lastGist = say ? gist(a) : g;
  }

  /** Say a problem (`quiet`: not again while it lasts); a camera gone ends "Keep telling me". */
  private sayProblem(e: unknown, quiet: boolean): void {
    const text = problemText(e);
    if (!quiet || this.lastGist !== text) this.o.voice.say(text, 'error', true);
    this.lastGist = text;
    this.lastTold = null; // the next answer said whole: a place alone would hang on nothing
    if (e instanceof CameraProblem && e.kind !== 'lens') this.stopContinuous();
  }

  /** The venue changed under us (re-modelled with other settings, emptied): reload it next time. */
  private forgetVenueOn(e: unknown): void {
    if (e instanceof ApiProblem && (e.status === 400 || e.status === 409)) this.venue = null;
  }

  /**
   * One request of a guided walk (guide.ts; of "Keep telling me" too, tellTracked): film `seconds`
   * (~1 s unless asked for more; less, never under 1 s, once `stop` says so) and locate it in tracking session `q.session` (with `q.to`: guidance), `t` the clip's last frame on
   * the phone's clock, and the phone's motion since the session's previous answered request, asked
   * of `motion` once the clip is filmed (the caller counts that reading as sent only when this
   * resolves with an answer). Nothing is said here: errors are thrown, for the caller to say. Null
   * when the camera is taken (a "Where am I?" is filming; `motion` is not asked): the caller tries
   * again at its next turn; null too when `stop` said so while filming (nothing is sent).
   */
  async track(
    q: Omit<Tracked, 't' | 'steps' | 'turn_deg'>,
    motion?: () => Motion,
    seconds = 1,
    stop: () => boolean = () => false,
  ): Promise<Located | null> {
    if (this.busy) return null;
    this.busy = true;
    this.emit('busy', true);
    try {
      const r = await this.ready();
      const clip = await this.longClip(r, seconds, stop);
      if (stop()) return null; // stopped while filming (Stop guidance): nothing to ask
      const record = encodeRecord(clip.frames, r.v.features.settings, r.v.features.settings_id);
      const m = motion?.();
      const t0 = performance.now();
      const a = await locate(r.v.id, record, clip.fps, `web-${Date.now()}`, {
        ...q,
        t: clip.endMs / 1000,
        steps: m?.steps,
        turn_deg: m?.turn_deg,
      }).catch((e: unknown) => {
        throw staleOrNot(e, r.v.features.settings_id);
      });
      this.lastAnswer = a;
      const located = this.located(a, r, clip, record.length, performance.now() - t0);
      this.emit('answer', located);
      return located;
    } catch (e) {
      this.forgetVenueOn(e);
      throw e;
    } finally {
      this.busy = false;
      this.emit('busy', false);
    }
  }

  /**
   * The first second was not sure: say so (`keepTurning`; a "probably" was said instead), wait for
   * the MORE_FRAMES filmed on and -> the whole clip, or null when stopped.
   */
  private async filmMore(
    first: Clip,
    rest: Promise<Clip>,
    more: { stopped: boolean },
    keepTurning = true,
  ): Promise<Clip | null> {
    if (keepTurning) this.o.voice.say(KEEP_TURNING, null, false, false);
    this.askingMore = true;
    this.emit('asking', true);
    try {
      const after = await rest;
      return more.stopped ? null : joinClips(first, after);
    } finally {
      this.askingMore = false;
      this.emit('asking', false);
    }
  }

  /** Filming on after an unsure first second (Stop would end it). */
  get asking(): boolean {
    return this.askingMore;
  }

  /** Stop: end the filming on after an unsure first second; nothing is sent. */
  stop(): void {
    if (!this.askingMore || !this.filming || this.filming.stopped) return;
    this.filming.stopped = true;
    this.o.voice.say(STOPPED, null, false, false);
  }

  /**
   * The lens check (lenscheck.ts): the worker finds the ring and from now on extracts with the
   * corrected profile; no ring, a cut ring or one too far off stops here, before any request.
   */
  private async checkLens(ext: ExtractorClient, fresh = false): Promise<{ check: LensCheck; again: boolean }> {
    let c = await checkLensOn(this.o.video, ext);
    // a camera that has just started may still be finding its exposure: look once more before saying no
    const again = fresh && !!lensWords(c);
    if (again) {
      await new Promise((r) => setTimeout(r, RECHECK_MS));
      c = await checkLensOn(this.o.video, ext);
    }
    this.lastCheck = c;
    this.emit('lens', c);
    const said = this.lensWatch.record(c, ext.configured);
    if (said?.stop) throw new CameraProblem('lens', said.text);
    if (said) this.o.voice.say(said.text, null);
    return { check: c, again };
  }

  get continuous(): boolean {
    return this.loop !== null;
  }

  /**
   * "Keep telling me" (called inside the user's tap: iOS asks for the motion sensors only then):
   * locate every `prefs.interval` seconds in a new tracking session, speak only what changed; or stop.
   */
  toggleContinuous(): void {
    if (this.loop) {
      this.stopContinuous();
      this.o.voice.say(STOPPED_TELLING, null);
      return;
    }
    if (this.o.guiding?.()) {
      this.o.voice.say(GUIDING_NOW, 'unsure');
      return;
    }
    const asked = this.o.askMotion?.() ?? Promise.resolve(); // first, still inside the tap
    const loop: Loop = { session: newSessionId() };
    this.loop = loop;
    this.emit('continuous', true);
    this.lastGist = '';
    this.lastTold = null;
    // denied or no sensors: the feed reads "unknown", and the filter goes on from the pictures alone
    void asked.finally(() => {
      if (this.loop === loop) this.o.motion?.start();
    });
    const tick = async () => {
      if (this.o.voice.busy) {
        // never talk over itself: the turn waits for the sentence to end, then comes at once
        // (skipping it for a whole interval made a walk's changing answers ~7 s apart)
        if (this.loop === loop) loop.timer = setTimeout(tick, BUSY_POLL_MS);
        return;
      }
      const filmed = await this.tellTracked(loop);
      // a turn that filmed longer waits as much less: a turn every `interval` + 1 s, as ever
      const wait = Math.max(1, this.prefs.interval - (filmed - 1));
      if (this.loop === loop) loop.timer = setTimeout(tick, wait * 1000);
    };
    loop.timer = setTimeout(tick, 0);
  }

  /**
   * One turn of "Keep telling me": 1 s (KEEP_SECONDS once a turn was answered) located in the
   * loop's tracking session with the phone's motion since the previous answered turn (the feed
   * counts a reading as sent only once its request was answered). Said only when it changed;
   * nothing once the loop was stopped meanwhile ("Stopped telling you." stays the last word; a stop
   * while filming sends nothing). The camera taken by a press: the next turn. -> the seconds it
   * filmed: `seconds` once its clip was filmed and the motion asked, less the second kept before
   * it (standby.ts) when it was answered from one, else 1 (the camera taken, a failure before or
   * while filming: the next turn waits the whole interval). A turn thus comes every `interval` + 1
   * s with or without a kept second: the kept second brings its answer sooner, not more often.
   */
  private async tellTracked(loop: Loop): Promise<number> {
    const feed = this.o.motion;
    const read: { reading?: MotionReading; filmed?: boolean; kept?: boolean } = {};
    const seconds = loop.answered ? KEEP_SECONDS : 1;
    // what it filmed: `seconds` once the clip was (the motion is asked then), else nothing to shorten
    const filmed = () => (read.filmed ? seconds - (read.kept ? 1 : 0) : 1);
    try {
      let r: Located | null;
      this.inTurn = !this.busy; // busy: track() skips this turn at once
      try {
        const motion = () => {
          read.filmed = true;
          read.kept = this.lastKept;
          const m = feed?.peek();
          read.reading = m;
          return { steps: m?.steps ?? null, turn_deg: m?.turn_deg ?? null };
        };
        r = await this.track({ session: loop.session }, motion, seconds, () => this.loop !== loop);
      } finally {
        this.inTurn = false;
      }
      if (!r || this.loop !== loop) {
        this.pressedInTurn = false;
        return filmed(); // null: the camera was taken (nothing filmed), or the loop stopped
      }
      loop.answered = true;
      if (read.reading) feed?.commit(read.reading);
      const pressed = this.pressedInTurn;
      this.pressedInTurn = false;
      this.tell(r.answer, r.venue, !pressed);
    } catch (e) {
      if (this.loop !== loop) return filmed();
      this.sayProblem(e, !this.pressedInTurn);
      this.pressedInTurn = false;
    }
    return filmed();
  }

  /**
   * A tab showed screen `name`: "Keep telling me" lives on the Locate screen, and stops (saying so)
   * when another is shown, where its sentences would talk over what the user is reading.
   */
  screenShown(name: string): void {
    if (name === 'locate' || !this.loop) return;
    this.stopContinuous();
    this.o.voice.say(STOPPED_TELLING, null);
  }

  stopContinuous(): void {
    clearTimeout(this.loop?.timer);
    this.loop = null;
    this.pressedInTurn = false;
    this.o.motion?.stop();
    this.emit('continuous', false);
  }
}
