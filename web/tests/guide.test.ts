// The guidance loop with fake timers, a fake server (each request films 1 s, then answers the next
// guidance of a script) and a fake voice: what is spoken, in order, with which urgency; the
// requests' session, place, clock and motion (none on the first request after Start, a failed
// request's steps sent with the next); Stop and arrival end the filming, the sensors and the
// screen lock; a hidden page pauses the loop, a camera taken by a call does not end it; the
// screen-lock note never takes the instruction's place in the live region.
import { afterEach, beforeEach, describe, expect, it, vi } from 'vitest';
import { ApiProblem, Unreachable, newSessionId, type Answer, type Guidance } from '../src/client/api';
import { CameraProblem } from '../src/client/camera';
import {
  GUIDE_CAMERA_BUSY,
  GUIDE_MAP_UPDATED,
  PREVIEW_CAMERA_BUSY,
  GUIDE_UNREACHABLE,
  Guide,
  INTERVAL_MS,
  NOTE_QUIET_MS,
  WALK_SECONDS,
  NO_GUIDANCE,
  SCREEN_ON,
  STOPPED_GUIDANCE,
  type GuideState,
  type PageHost,
  type Words,
} from '../src/client/guide';
import {
  GUIDE_UNSURE,
  GUIDE_UNSURE_CHOSEN,
  guidanceSentence,
  previewSentence,
  type Style,
} from '../src/client/directions';
import type { MotionReading } from '../src/client/motion';
import type { Voice } from '../src/client/session';

const TO = { id: 'p3', name: 'Room 102', floor: '1' };

/** A guidance as the server sends it; its `sentence` stands for the words (fake words below). */
function g(kind: Guidance['kind'], sentence: string, more: Partial<Guidance> = {}): Guidance {
  return {
    to: TO,
    kind,
    speak: true,
    urgent: kind === 'off_route' || kind === 'arrived' || kind === 'probably_arrived',
    bearing_deg: 0,
    walk_m: 10,
    in_m: null,
    until: null,
    next_turn_m: 10,
    remaining_m: 40,
    on_route: kind !== 'off_route',
    arrived: kind === 'arrived',
    floor_change: null,
    route: [
      [0, 0],
      [10, 0],
    ],
    sentence,
    ...more,
  };
}

const PREVIEW = { length_m: 45, turns: 2, first_turn_m: 12, floors: ['1'] };

function answer(guidance?: Guidance): Answer {
  return {
    clip: 'c',
    x: 1,
    y: 2,
    heading_deg: 90,
    confidence: 0.9,
    floor: '1',
    place: null,
    frame: 9,
    area: null,
    nearest: null,
    facing: null,
    sentence: '',
    low_confidence: false,
    accuracy_m: 2,
    frames: 10,
    sent: 'features',
    guidance,
  };
}

type Step = Guidance | Error | undefined;

/**
 * A phone walking 2 steps and turning 5 degrees a second from the sensors' start, read by a naive
 * feed: counts since start() or the last commit, never unknown while running (the guide must
 * leave out what it cannot vouch for itself).
 */
function fakeMotion() {
  let since: number | null = null;
  let base = { steps: 0, turn: 0 };
  const counts = () => {
    const s = (Date.now() - since!) / 1000;
    return { steps: Math.floor(2 * s), turn: 5 * s };
  };
  return {
    start: vi.fn(() => {
      since = Date.now();
      base = { steps: 0, turn: 0 };
    }),
    stop: vi.fn(() => (since = null)),
    peek: vi.fn((): MotionReading => {
      if (since === null) return { steps: null, turn_deg: null, mark: null };
      const c = counts();
      const mark = { run: 1, ...c, accel: { n: 1, stalls: 0 }, yaw: { n: 1, stalls: 0 } };
      return { steps: c.steps - base.steps, turn_deg: c.turn - base.turn, mark };
    }),
    commit: vi.fn((r: MotionReading) => {
      if (r.mark && since !== null) base = { steps: r.mark.steps, turn: r.mark.turn };
    }),
  };
}

/** The document's visibility: hide() and show() fire visibilitychange. */
function fakePage() {
  const fns = new Set<() => void>();
  const page = {
    hidden: false,
    addEventListener: (_t: 'visibilitychange', fn: () => void) => fns.add(fn),
    removeEventListener: (_t: 'visibilitychange', fn: () => void) => fns.delete(fn),
    set(hidden: boolean) {
      page.hidden = hidden;
      for (const fn of [...fns]) fn();
    },
    listeners: () => fns.size,
  };
  return page satisfies PageHost;
}

function rig(script: Step[], o: { screen?: boolean; words?: Words; voice?: Voice } = {}) {
  const said: { text: string; cue: unknown; urgent: boolean }[] = [];
  const voice = o.voice ?? {
    busy: false,
    say: vi.fn((text: string, cue: unknown = 'ok', urgent = false) => said.push({ text, cue, urgent })),
    cue: vi.fn(),
  };
  const requests: { session: string; to: string; style: Style; steps: number | null; turn: number | null }[] = [];
  const seconds: number[] = []; // what each request asked to film
  const stops: (() => boolean)[] = []; // and when it is to stop filming
  let filming = 0;
  let n = 0;
  const motion = fakeMotion();
  const page = fakePage();
  const screen = { hold: vi.fn(async () => o.screen ?? true), release: vi.fn(async () => undefined) };
  const askMotion = vi.fn(async () => undefined);
  let style: Style = 'clock';
  const guide = new Guide({
    voice,
    // each request films 1 s (whatever it asked for: the timing of these tests), then asks the
    // motion and answers the script's next step
    track: async (q, m, s, stop) => {
      seconds.push(s);
      stops.push(stop);
      filming++;
      await new Promise((r) => setTimeout(r, 1000));
      filming--;
      const mo = m();
      requests.push({ ...q, steps: mo.steps, turn: mo.turn_deg });
      const step = script[Math.min(n++, script.length - 1)];
      if (step instanceof Error) throw step;
      return answer(step);
    },
    motion,
    screen,
    askMotion,
    style: () => style,
    words: o.words ?? { guidance: (x) => x.sentence, preview: (x) => `${x.to.name}: ${x.preview!.length_m} metres.` },
    newSession: () => 'session-1',
    page,
  });
  const states: GuideState[] = [];
  guide.on('state', (s) => states.push(s));
  return {
    guide,
    said,
    texts: () => said.map((s) => s.text),
    requests,
    seconds,
    stops,
    motion,
    page,
    screen,
    askMotion,
    states,
    filming: () => filming,
    setStyle: (s: Style) => (style = s),
  };
}

const START = g('start', 'Turn to 2 o’clock and walk 12 metres, to the end of the corridor.', { preview: PREVIEW });
const GO = g('turn', 'Turn to 2 o’clock and walk 12 metres, to the end of the corridor.', { speak: false });
const REASSURE = g('reassure', 'Keep going, 8 metres to the lifts.');
const QUIET = g('reassure', 'Keep going, 8 metres to the lifts.', { speak: false });
const OFF = g('off_route', 'You are off the route; turn to 7 o’clock.');
const TURN = g('turn', 'Turn to 9 o’clock and walk 20 metres, to Room 102.');
/** The server's guidance carries the place's own sentence, and its words say it (once). */
const SAY = 'The door is on your left.';
const ARRIVED = g('arrived', `You have arrived at Room 102; it is at 3 o’clock, 2 metres. ${SAY}`, {
  to: { ...TO, say: SAY },
});

/** A live region as a screen reader gets it: each text it held, into `heard` (the Speaker clears it first). */
function liveRegion(heard: string[]): HTMLElement {
  return {
    set textContent(t: string) {
      if (t) heard.push(t);
    },
    get textContent() {
      return '';
    },
  } as unknown as HTMLElement;
}

describe('Guide', () => {
  beforeEach(() => vi.useFakeTimers());
  afterEach(() => vi.useRealTimers());

  it('a walk: preview, the instruction at Start, reassurance once, off route cutting in, arrival stops', async () => {
    const r = rig([START, GO, REASSURE, QUIET, REASSURE, OFF, TURN, ARRIVED, REASSURE]);
    const choosing = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await choosing;
    expect(r.guide.state).toBe('ready');
    expect(r.texts()).toEqual(['Room 102: 45 metres.']);
    expect(r.requests[0]).toMatchObject({ session: 'session-1', to: 'p3', style: 'clock' });

    r.guide.start();
    expect(r.askMotion).toHaveBeenCalledTimes(1); // inside the tap, before anything is awaited
    await vi.advanceTimersByTimeAsync(1000);
    // Start: the current instruction from a fresh answer, though the server did not mark it new
    expect(r.texts().at(-1)).toBe(GO.sentence);
    expect(r.motion.start).toHaveBeenCalled();
    expect(r.screen.hold).toHaveBeenCalled();
    await vi.advanceTimersByTimeAsync(INTERVAL_MS * 7);
    expect(r.texts()).toEqual([
      'Room 102: 45 metres.',
      GO.sentence,
      REASSURE.sentence, // said once: the quiet repeat and the same words again are not
      OFF.sentence,
      TURN.sentence,
      'You have arrived at Room 102; it is at 3 o’clock, 2 metres. The door is on your left.',
    ]);
    expect(r.said.filter((s) => s.urgent).map((s) => s.text)).toEqual([OFF.sentence, ARRIVED.sentence]);
    expect(r.said.find((s) => s.text === REASSURE.sentence)?.cue).toBeNull();
    // arrival ends the loop: no more filming, sensors off, the screen may lock again
    expect(r.guide.state).toBe('arrived');
    const n = r.requests.length;
    expect(n).toBe(8); // the preview's, Start's, then one every 2 s until arrival
    await vi.advanceTimersByTimeAsync(INTERVAL_MS * 5);
    expect(r.requests.length).toBe(n);
    expect(r.motion.stop).toHaveBeenCalled();
    expect(r.screen.release).toHaveBeenCalled();
    expect(r.states.slice(-3)).toEqual(['ready', 'guiding', 'arrived']);
  });

  it('every request names the session and the place, in the user style, with the motion since the last', async () => {
    const r = rig([START, GO, QUIET]);
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    r.setStyle('sides');
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS * 2);
    const q = { session: 'session-1', to: 'p3', style: 'sides' };
    expect(r.requests).toEqual([
      { ...q, style: 'clock', steps: null, turn: null }, // the preview: no sensors yet
      // Start: the walk since the preview's request was not counted, so none is claimed
      { ...q, steps: null, turn: null },
      // then what the phone felt from one clip to the next: 2 s, 2 steps and 5 degrees a second
      { ...q, steps: 4, turn: 10 },
      { ...q, steps: 4, turn: 10 },
    ]);
  });

  it('a failed request keeps its motion for the next; Start again on the session claims none at first', async () => {
    const r = rig([START, GO, QUIET, new Unreachable('down'), QUIET, QUIET, QUIET]);
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS * 3);
    const motion = () => r.requests.map((q) => [q.steps, q.turn]);
    expect(motion().slice(1)).toEqual([
      [null, null],
      [4, 10],
      [4, 10], // not answered...
      [8, 20], // ...so its 2 s of walking go with the next request, which has 4 s of it
    ]);
    expect(r.motion.commit).toHaveBeenCalledTimes(4); // each answered request's reading, the preview's too
    // Stop, wait, Start again in the same session: the walk meanwhile was not counted
    r.guide.stop();
    await vi.advanceTimersByTimeAsync(5000);
    const n = r.requests.length;
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS);
    expect(r.requests.slice(n).map((q) => [q.session, q.steps, q.turn])).toEqual([
      ['session-1', null, null],
      ['session-1', 4, 10],
    ]);
  });

  it('Stop guidance stops the filming, the sensors and the screen lock; an answer in flight is not said', async () => {
    const r = rig([START, GO, REASSURE, OFF]);
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS - 500); // the second request is filming
    expect(r.filming()).toBe(1);
    r.guide.stop();
    expect(r.guide.state).toBe('stopped');
    expect(r.texts().at(-1)).toBe(STOPPED_GUIDANCE);
    const n = r.requests.length;
    await vi.advanceTimersByTimeAsync(INTERVAL_MS * 5);
    expect(r.requests.length).toBe(n + 1); // the one filming finished, and nothing after it
    expect(r.filming()).toBe(0);
    expect(r.texts().at(-1)).toBe(STOPPED_GUIDANCE); // its reassurance is not said
    expect(r.motion.stop).toHaveBeenCalled();
    expect(r.screen.release).toHaveBeenCalled();
  });

  it('What next? repeats the current instruction; "not sure" is said once per spell, then the instruction', async () => {
    const UNSURE = g('unsure', 'Not sure where you are; keep walking slowly.');
    const r = rig([START, UNSURE, UNSURE, g('unsure', 'Not sure where you are; keep walking slowly.'), GO, QUIET]);
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    r.guide.whatNext();
    expect(r.texts().at(-1)).toBe(START.sentence); // before Start: the first instruction
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS * 2);
    expect(r.texts().slice(1)).toEqual([START.sentence, UNSURE.sentence]);
    r.guide.whatNext();
    expect(r.texts().at(-1)).toBe(UNSURE.sentence);
    // once sure, the instruction Start owed is said, though the server did not mark it new
    await vi.advanceTimersByTimeAsync(INTERVAL_MS);
    expect(r.texts().at(-1)).toBe(GO.sentence);
    await vi.advanceTimersByTimeAsync(INTERVAL_MS);
    r.guide.whatNext();
    expect(r.texts().at(-1)).toBe(QUIET.sentence);
  });

  it('not sure where the user is when the place is chosen: asked to press Start and walk, not to keep walking', async () => {
    const UNSURE = g('unsure', GUIDE_UNSURE);
    const r = rig([UNSURE, UNSURE, START]);
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    expect(r.texts()).toEqual([GUIDE_UNSURE_CHOSEN]);
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS * 2);
    // Start says the current instruction, now that the user walks; then the way once sure
    expect(r.texts()).toEqual([GUIDE_UNSURE_CHOSEN, GUIDE_UNSURE, START.sentence]);
  });

  it('"outside the mapped area" is said inside a spell of "not sure", once; What next? repeats it; guiding goes on', async () => {
    const UNSURE = g('unsure', 'Not sure where you are yet; keep walking slowly.');
    const LOST = g('not_here', 'You may be outside the mapped area; keep walking slowly, or stop guidance.', {
      bearing_deg: null,
      on_route: false,
    });
    const AGAIN = { ...GO, speak: true }; // the server says the instruction again once sure
    const r = rig([START, GO, UNSURE, UNSURE, LOST, { ...UNSURE, speak: true }, { ...LOST, speak: false }, AGAIN]);
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS * 5);
    expect(r.texts().slice(1)).toEqual([GO.sentence, UNSURE.sentence, LOST.sentence]);
    expect(r.said.find((x) => x.text === LOST.sentence)).toMatchObject({ cue: 'unsure', urgent: false });
    r.guide.whatNext();
    expect(r.texts().at(-1)).toBe(LOST.sentence);
    expect(r.guide.state).toBe('guiding');
    await vi.advanceTimersByTimeAsync(INTERVAL_MS * 2);
    expect(r.texts().at(-1)).toBe(AGAIN.sentence); // sure again: the instruction, as after "not sure"
  });

  it('Start’s request films 1 s (its instruction soon), then each films all it can, unsure or not', async () => {
    const UNSURE = g('unsure', 'Not sure where you are; keep walking slowly.');
    const r = rig([START, UNSURE, GO, QUIET, QUIET]);
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS * 3);
    expect(WALK_SECONDS).toBeGreaterThan(1);
    // the preview's, Start's (not sure), then the walk's: the owed instruction comes with more of it
    expect(r.seconds).toEqual([1, 1, WALK_SECONDS, WALK_SECONDS, WALK_SECONDS]);
    expect(r.texts().slice(1)).toEqual([UNSURE.sentence, GO.sentence]);
    // Stop and Start again: Start's request films 1 s again (and its retry, when it failed)
    r.guide.stop();
    const n = r.seconds.length;
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS);
    expect(r.seconds.slice(n)).toEqual([1, WALK_SECONDS]);
    // Stop guidance ends the filming of the request in flight (after its first second)
    expect(r.stops.map((f) => f())).toEqual([...r.stops.slice(0, n).map(() => true), false, false]);
    r.guide.stop();
    expect(r.stops.at(-1)!()).toBe(true);
  });

  it('until a request of the run was answered, each films 1 s (Start’s instruction still soon)', async () => {
    const r = rig([START, new Unreachable('down'), GO, QUIET]);
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS * 3);
    expect(r.seconds.slice(0, 4)).toEqual([1, 1, 1, WALK_SECONDS]); // the preview, Start's (failed), its retry, the walk
    expect(r.texts()).toContain(GO.sentence);
    r.guide.stop();
  });

  it('a problem is said once while the loop keeps trying; a lost venue stops it', async () => {
    const down = new Unreachable('down');
    const r = rig([START, GO, down, down, down, REASSURE, new ApiProblem(409, 'no frames'), REASSURE]);
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    const problems: string[] = [];
    r.guide.on('problem', (p) => problems.push(p));
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS * 4);
    expect(r.texts().filter((t) => t === GUIDE_UNREACHABLE)).toHaveLength(1);
    expect(r.said.find((s) => s.text === GUIDE_UNREACHABLE)?.urgent).toBe(true);
    expect(r.texts().at(-1)).toBe(REASSURE.sentence);
    expect(problems).toEqual([GUIDE_UNREACHABLE, '']);
    await vi.advanceTimersByTimeAsync(INTERVAL_MS);
    expect(r.guide.state).toBe('stopped');
    expect(r.texts().at(-1)).toContain('no modelled frames');
    const n = r.requests.length;
    await vi.advanceTimersByTimeAsync(INTERVAL_MS * 3);
    expect(r.requests.length).toBe(n);
    expect(r.screen.release).toHaveBeenCalled();
  });

  it('the venue modelled anew meanwhile: said once, and guidance goes on', async () => {
    const stale = "features were made with other settings (id 1) than this venue's (2)";
    const updated = new ApiProblem(400, stale, { error: stale, status: 400, venue_settings_id: 2 });
    const r = rig([START, GO, updated, REASSURE]);
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS * 2);
    expect(r.texts().filter((t) => t === GUIDE_MAP_UPDATED)).toHaveLength(1);
    expect(r.guide.state).toBe('guiding');
    expect(r.texts().at(-1)).toBe(REASSURE.sentence);
  });

  it('a camera taken by a call is said once and tried again; guidance goes on when it is free', async () => {
    const taken = new CameraProblem('busy', 'The camera is in use by another app.');
    const r = rig([START, GO, taken, taken, taken, REASSURE]);
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    const problems: string[] = [];
    r.guide.on('problem', (p) => problems.push(p));
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS * 4);
    expect(r.guide.state).toBe('guiding');
    expect(r.texts().slice(1)).toEqual([GO.sentence, GUIDE_CAMERA_BUSY, REASSURE.sentence]);
    expect(problems).toEqual([GUIDE_CAMERA_BUSY, '']);
    // before Start nothing tries again: the place is chosen again
    const p = rig([taken]);
    const c2 = p.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c2;
    expect(p.texts()).toEqual([PREVIEW_CAMERA_BUSY]);
    expect(p.guide.state).toBe('stopped');
  });

  it('a hidden page pauses the loop, a camera refused meanwhile is not the end; shown again it goes on', async () => {
    const denied = new CameraProblem('denied', 'The camera is blocked.');
    const r = rig([START, GO, denied, REASSURE, QUIET]);
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS - 500); // the second request is filming
    const released = r.screen.release.mock.calls.length;
    r.page.set(true); // the screen locks: the browser stops the camera
    await vi.advanceTimersByTimeAsync(INTERVAL_MS * 10);
    expect(r.requests).toHaveLength(3); // the one filming failed, nothing more while hidden
    expect(r.guide.state).toBe('guiding');
    expect(r.texts()).toEqual(['Room 102: 45 metres.', GO.sentence]); // nothing said of the refusal
    expect(r.screen.release).toHaveBeenCalledTimes(released); // the screen lock is still wanted
    r.page.set(false); // unlocked: at once, in the same session, without the walk it could not count
    await vi.advanceTimersByTimeAsync(1000);
    expect(r.requests.slice(3)).toMatchObject([{ session: 'session-1', steps: null, turn: null }]);
    expect(r.texts().at(-1)).toBe(REASSURE.sentence);
    await vi.advanceTimersByTimeAsync(INTERVAL_MS);
    expect(r.requests.slice(4)).toMatchObject([{ steps: 4, turn: 10 }]);
    r.guide.stop();
    expect(r.page.listeners()).toBe(0);
  });

  it('a camera that is refused stops guidance; a server without guidance says so', async () => {
    const r = rig([START, new CameraProblem('denied', 'The camera is blocked.')]);
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000);
    expect(r.guide.state).toBe('stopped');
    expect(r.texts().at(-1)).toBe('The camera is blocked.');
    const old = rig([undefined]);
    const c2 = old.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c2;
    expect(old.texts()).toEqual([NO_GUIDANCE]);
    expect(old.guide.state).toBe('stopped');
  });

  it('where the screen cannot be kept on, the user is told once, after the first instruction', async () => {
    const r = rig([START, GO, QUIET], { screen: false });
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000);
    expect(r.texts().at(-1)).toBe(GO.sentence); // not at once: it would take the instruction's place
    await vi.advanceTimersByTimeAsync(NOTE_QUIET_MS);
    r.guide.stop();
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + NOTE_QUIET_MS * 2);
    expect(r.texts().filter((t) => t === SCREEN_ON)).toHaveLength(1);
    expect(r.texts().slice(0, 3)).toEqual(['Room 102: 45 metres.', GO.sentence, SCREEN_ON]);
  });

  it('with the Speaker: the first instruction and the screen-lock note both reach the live region', async () => {
    // a synthesiser that takes 50 ms a character to say a sentence
    class Utterance {
      rate = 1;
      lang = '';
      volume = 1;
      voice: unknown = null;
      onend: (() => void) | null = null;
      onerror: (() => void) | null = null;
      constructor(readonly text: string) {}
    }
    const synth = {
      speak: (u: Utterance) => setTimeout(() => u.onend?.(), 50 * u.text.length),
      cancel: () => undefined,
      getVoices: () => [],
    };
    vi.stubGlobal('speechSynthesis', synth);
    vi.stubGlobal('SpeechSynthesisUtterance', Utterance);
    vi.stubGlobal('navigator', {});
    try {
      const { Speaker } = await import('../src/client/speech');
      const heard: string[] = [];
      const region = () => liveRegion(heard);
      const r = rig([START, GO, QUIET], { screen: false, voice: new Speaker(region(), region()) });
      const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
      await vi.advanceTimersByTimeAsync(1000);
      await c;
      r.guide.start();
      await vi.advanceTimersByTimeAsync(1000 + 50 * GO.sentence.length + NOTE_QUIET_MS + 500);
      expect(heard).toEqual(['Room 102: 45 metres.', GO.sentence, SCREEN_ON]);
    } finally {
      vi.unstubAllGlobals();
    }
  });

  it('with the Speaker and the screen reader reading: paced by the live region alone, never spoken', async () => {
    // a synthesiser that would never report an end: the guide must not wait for one
    const spoken: string[] = [];
    vi.stubGlobal('speechSynthesis', { speak: (u: { text: string }) => spoken.push(u.text), cancel: () => 0 });
    vi.stubGlobal('SpeechSynthesisUtterance', class {});
    vi.stubGlobal('navigator', {});
    try {
      const { Speaker } = await import('../src/client/speech');
      const heard: string[] = [];
      const region = () => liveRegion(heard);
      const speaker = new Speaker(region(), region());
      speaker.screenReader = true;
      const r = rig([START, GO, QUIET], { screen: false, voice: speaker });
      const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
      await vi.advanceTimersByTimeAsync(1000);
      await c;
      r.guide.start();
      await vi.advanceTimersByTimeAsync(1000 + NOTE_QUIET_MS + 500);
      expect(heard).toEqual(['Room 102: 45 metres.', GO.sentence, SCREEN_ON]);
      r.guide.whatNext(); // What next? puts the latest instruction in the live region again
      await vi.advanceTimersByTimeAsync(100);
      expect(heard.at(-1)).toBe(QUIET.sentence);
      expect(spoken).toEqual([]);
    } finally {
      vi.unstubAllGlobals();
    }
  });

  it('speaks the app words in the user style: the preview, then the instruction for where they face', async () => {
    const words: Words = { guidance: guidanceSentence, preview: (x) => previewSentence(x.preview!, x.to) };
    const start = g('start', '', { bearing_deg: 60, walk_m: 12, until: 'the end of the corridor', preview: PREVIEW });
    const r = rig([start, { ...start, kind: 'turn', speak: false, preview: undefined }], { words });
    r.setStyle('sides');
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    expect(r.guide.previewText).toBe('Room 102: 45 metres, 2 turns, first turn after 12 metres.');
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000);
    expect(r.texts()).toEqual([
      'Room 102: 45 metres, 2 turns, first turn after 12 metres.',
      'Bear right and walk 12 metres, to the end of the corridor.',
    ]);
    r.setStyle('clock');
    r.guide.whatNext();
    expect(r.texts().at(-1)).toBe("Turn to 2 o'clock and walk 12 metres, to the end of the corridor.");
  });

  it('on arrival says what the words make, the place’s own sentence once, in each style', async () => {
    const words: Words = { guidance: guidanceSentence, preview: (x) => previewSentence(x.preview!, x.to) };
    const to = { ...TO, say: SAY };
    const start = g('start', '', { to, bearing_deg: 0, walk_m: 12, until: 'Room 102', preview: PREVIEW });
    const arrived = g('arrived', '', { to, bearing_deg: 90, walk_m: 2, remaining_m: 0 });
    const heard: Record<Style, string[]> = { clock: [], sides: [], degrees: [] };
    for (const style of ['clock', 'sides', 'degrees'] as const) {
      const r = rig([start, { ...start, kind: 'continue', speak: false, preview: undefined }, arrived], { words });
      r.setStyle(style);
      const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
      await vi.advanceTimersByTimeAsync(1000);
      await c;
      r.guide.start();
      await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS);
      expect(r.guide.state).toBe('arrived');
      heard[style] = r.said.filter((s) => s.urgent).map((s) => s.text);
      expect(r.texts().join(' ').split(SAY).length - 1).toBe(1); // the place's sentence, said once
    }
    expect(heard).toEqual({
      clock: ["You have arrived at Room 102; it is at 3 o'clock, 2 metres. The door is on your left."],
      sides: ['You have arrived at Room 102; it is to your right, 2 metres. The door is on your left.'],
      degrees: ['You have arrived at Room 102; it is at 90 degrees to your right, 2 metres. The door is on your left.'],
    });
    // arriving at the preview (the walk began at the place): the same words, once
    const r = rig([g('arrived', '', { to, bearing_deg: 0, walk_m: 0.3, remaining_m: 0, preview: PREVIEW })], {
      words,
    });
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    expect(r.guide.state).toBe('arrived');
    expect(r.said).toEqual([
      { text: 'You have arrived at Room 102. The door is on your left.', cue: 'ok', urgent: true },
    ]);
  });

  it('"probably at" cuts in but does not end guidance; the sure arrival after it does', async () => {
    const words: Words = { guidance: guidanceSentence, preview: (x) => previewSentence(x.preview!, x.to) };
    const to = { ...TO, say: SAY };
    const start = g('start', '', { to, bearing_deg: 0, walk_m: 12, until: 'Room 102', preview: PREVIEW });
    const probably = g('probably_arrived', '', { to, bearing_deg: 90, walk_m: 2, remaining_m: 0, next_turn_m: null });
    const arrived = g('arrived', '', { to, bearing_deg: 90, walk_m: 2, remaining_m: 0, next_turn_m: null });
    const r = rig([start, start, probably, { ...probably, speak: false }, arrived, REASSURE], { words });
    const c = r.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await c;
    r.guide.start();
    await vi.advanceTimersByTimeAsync(1000 + INTERVAL_MS);
    expect(r.guide.state).toBe('guiding'); // "probably" is not the end: still filming
    expect(r.said.at(-1)).toEqual({
      text: "You are probably at Room 102; it is at 3 o'clock, 2 metres. The door is on your left.",
      cue: 'ok',
      urgent: true,
    });
    await vi.advanceTimersByTimeAsync(INTERVAL_MS * 4);
    expect(r.guide.state).toBe('arrived');
    expect(r.requests.length).toBe(5); // the preview's, Start's, the probable two, the sure arrival
    expect(r.said.filter((s) => s.urgent).map((s) => s.text)).toEqual([
      "You are probably at Room 102; it is at 3 o'clock, 2 metres. The door is on your left.",
      "You have arrived at Room 102; it is at 3 o'clock, 2 metres. The door is on your left.",
    ]);
    // a probable arrival at the preview (the walk began there): said, and Start may be pressed
    const p = rig([{ ...probably, walk_m: 0.3 }], { words });
    const cp = p.guide.choose({ id: 'p3', name: 'Room 102' });
    await vi.advanceTimersByTimeAsync(1000);
    await cp;
    expect(p.guide.state).toBe('ready');
    expect(p.texts()).toEqual(['You are probably at Room 102. The door is on your left.']);
  });

  it('a session id the server takes: [A-Za-z0-9_-]{8,64}, a new one each time', () => {
    const a = newSessionId();
    expect(a).toMatch(/^[A-Za-z0-9_-]{8,64}$/);
    expect(newSessionId()).not.toBe(a);
  });
});
