// "Keep telling me": the session asks every few seconds, never while a sentence is being spoken,
// and a stop ends its loop for good. It is a walk: each turn locates in one tracking session per
// start (the server's filter remembers where the user was), the first 1 s and every turn after an
// answered one KEEP_SECONDS (2 s) with the wait after it a second shorter, with the clip's last
// frame on the phone's clock and the phone's motion since the previous answered turn when it has
// it; it never films on to 3 s when unsure, and says only what changed. The camera, the worker and
// the server are fakes.
import { afterEach, beforeEach, describe, expect, it, vi } from 'vitest';
import { ApiProblem, Unreachable, trackedQuery, type Answer, type Tracked } from '../src/client/api';
import { CameraProblem } from '../src/client/camera';
import { UNSURE } from '../src/client/directions';
import type { MotionReading } from '../src/client/motion';
import { MAP_UPDATED } from '../src/client/problems';
import { HEADER_AT } from '../src/shared/record';
import { GUIDING_NOW, KEEP_SECONDS } from '../src/client/session';
import { VENUE, answer, clip, session } from './fake-session';

const api = vi.hoisted(() => ({ venues: vi.fn(), venue: vi.fn(), locate: vi.fn() }));
const cam = vi.hoisted(() => ({ captureClip: vi.fn(), openCamera: vi.fn() }));
vi.mock('../src/client/api', async (orig) => ({ ...(await orig<object>()), ...api }));
vi.mock('../src/client/camera', async (orig) => ({ ...(await orig<object>()), ...cam }));
vi.mock('../src/client/bridge', () => ({
  ExtractorClient: class {
    configured = 'fake';
    configure = () => Promise.resolve(1);
  },
}));

const STOPPED_TELLING = 'Stopped telling you.';
const SESSION_ID = /^[A-Za-z0-9_-]{8,64}$/;

/** Each locate request's tracked part (undefined: a single clip), in order. */
const tracked = () => api.locate.mock.calls.map((c) => c[4] as Tracked | undefined);

/** A tracked answer: the single-clip fields, filtered, and the filter's state beside them. */
function trackedAnswer(low: boolean, updates = 1): Answer {
  const a = answer(low);
  const tracking = { session: 's', restarted: updates === 1, reason: updates === 1 ? ('new' as const) : null };
  return { ...a, tracking: { ...tracking, updates, single: { x: 3, y: 4, heading_deg: 90, confidence: 0.5 } } };
}

/** A fake motion feed: the readings it hands out in turn, and what was committed. */
function motionFeed(readings: Omit<MotionReading, 'mark'>[]) {
  let n = 0;
  return {
    start: vi.fn(),
    stop: vi.fn(),
    peek: vi.fn(
      (): MotionReading => ({ ...readings[Math.min(n, readings.length - 1)], mark: null, n: n++ }) as MotionReading,
    ),
    commit: vi.fn(),
  };
}

/** Fake timers; the venue, the camera and `first` as every locate answer (a test queues others). */
function fakes(first: Answer): void {
  vi.useFakeTimers();
  vi.resetAllMocks(); // and the answers queued by a test that failed early
  api.venues.mockResolvedValue([{ id: 'lab', name: 'Lab' }]);
  api.venue.mockResolvedValue(VENUE);
  api.locate.mockResolvedValue(first);
  cam.openCamera.mockResolvedValue({ getVideoTracks: () => [{ readyState: 'live' }] });
}

describe('continuous mode', () => {
  beforeEach(() => {
    fakes(trackedAnswer(false));
    // each clip is filmed a second after the last on the phone's clock: 0-900 ms, 1000-1900 ms, ...
    let at = 0;
    cam.captureClip.mockImplementation((_v, _e, n: number) => {
      const c = clip(n, at);
      at += 1000;
      return Promise.resolve(c);
    });
  });
  afterEach(() => vi.useRealTimers());

  it('pressed during a guided walk: says so and starts nothing (the two would fight over the camera)', async () => {
    let guiding = true;
    const { s, said } = session({ guiding: () => guiding });
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(10_000);
    expect(s.continuous).toBe(false);
    expect(api.locate).not.toHaveBeenCalled();
    expect(said).toEqual([GUIDING_NOW]);
    guiding = false; // guidance stopped: it starts
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0);
    expect(s.continuous).toBe(true);
    expect(api.locate).toHaveBeenCalledTimes(1);
    s.stopContinuous();
  });

  it('asks at once, then every interval, quietly; puts a turn off while speech is busy; stops when told', async () => {
    const { s, voice, said } = session();
    const pressed: boolean[] = [];
    s.on('continuous', (on) => pressed.push(on));
    s.toggleContinuous();
    expect(pressed).toEqual([true]);
    expect(s.continuous).toBe(true);
    await vi.advanceTimersByTimeAsync(0);
    expect(api.locate).toHaveBeenCalledTimes(1);
    await vi.advanceTimersByTimeAsync(2999);
    expect(api.locate).toHaveBeenCalledTimes(1);
    await vi.advanceTimersByTimeAsync(1);
    expect(api.locate).toHaveBeenCalledTimes(2);
    voice.busy = true; // the next turn is due 2 s after that (2 s filmed): speech holds it back
    await vi.advanceTimersByTimeAsync(3000);
    expect(api.locate).toHaveBeenCalledTimes(2);
    voice.busy = false; // and it comes within half a second of the sentence's end, not an interval later
    await vi.advanceTimersByTimeAsync(500);
    expect(api.locate).toHaveBeenCalledTimes(3);
    await vi.advanceTimersByTimeAsync(1999); // then the 2 s turn's wait
    expect(api.locate).toHaveBeenCalledTimes(3);
    s.toggleContinuous();
    expect(pressed).toEqual([true, false]);
    expect(voice.say).toHaveBeenCalledWith(STOPPED_TELLING, null);
    await vi.advanceTimersByTimeAsync(30_000);
    expect(api.locate).toHaveBeenCalledTimes(3);
    // the user stood still: three answers, one sentence, and no "start" cue per turn
    expect(said).toEqual([s.sentence(answer(false), VENUE), STOPPED_TELLING]);
    expect(voice.cue).not.toHaveBeenCalled();
  });

  it('an answer not said again (about what was said) shows the sentence that was said, not its own words', async () => {
    const at = (distance_m: number): Answer => ({
      ...trackedAnswer(false),
      nearest: { name: 'the entrance', distance_m, bearing_deg: 180 },
    });
    api.locate.mockResolvedValueOnce(at(0.6)).mockResolvedValueOnce(at(1.2)).mockResolvedValue(at(1.3));
    const { s, said } = session();
    const shown: string[] = [];
    s.on('said', (t) => shown.push(t));
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0);
    await vi.advanceTimersByTimeAsync(3000);
    await vi.advanceTimersByTimeAsync(4000);
    s.stopContinuous();
    // 1.2 and 1.3 m are still "at the entrance" for a user who was at it (AT_LEAVE_M): not said,
    // and shown as said, where describe() alone words them "near the entrance at 6 o'clock, 1 metre"
    const first = s.sentence(at(0.6), VENUE);
    expect(first).toContain('at the entrance');
    expect(s.sentence(at(1.2), VENUE)).toContain('near the entrance');
    expect(said).toEqual([first]);
    expect(shown.length).toBeGreaterThanOrEqual(3);
    expect(new Set(shown)).toEqual(new Set([first]));
  });

  it('says only the news while walking: a place passed is not said again, a new one without the area', async () => {
    const near = (name: string, bearing_deg: number): Answer => ({
      ...trackedAnswer(false),
      nearest: { name, distance_m: 3, bearing_deg },
    });
    api.locate
      .mockResolvedValueOnce(near('Room 1', 60))
      .mockResolvedValueOnce(near('Room 1', 150)) // walked past it: not news
      .mockResolvedValue(near('Room 2', -60));
    const { s, said } = session();
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0);
    await vi.advanceTimersByTimeAsync(3000);
    await vi.advanceTimersByTimeAsync(4000);
    s.stopContinuous();
    expect(said).toEqual([s.sentence(near('Room 1', 60), VENUE), "Near Room 2 at 10 o'clock, 3 metres."]);
  });

  it('stops, saying so, when another screen is shown (its sentences would talk over it); Locate itself leaves it on', async () => {
    const { s, said } = session();
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0);
    s.screenShown('locate');
    expect(s.continuous).toBe(true);
    s.screenShown('goto');
    expect(s.continuous).toBe(false);
    expect(said.at(-1)).toBe(STOPPED_TELLING);
    const asked = api.locate.mock.calls.length;
    await vi.advanceTimersByTimeAsync(30_000);
    expect(api.locate).toHaveBeenCalledTimes(asked);
    s.screenShown('settings'); // nothing running: nothing said
    expect(said.filter((t) => t === STOPPED_TELLING)).toHaveLength(1);
  });

  it('each turn is tracked in one session with the clip clock increasing; a stop and a start begin a new session', async () => {
    const { s } = session();
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0);
    await vi.advanceTimersByTimeAsync(3000); // 1 s filmed, then the interval (3 s)
    await vi.advanceTimersByTimeAsync(2000); // 2 s filmed, then a second less
    const first = tracked();
    expect(first).toHaveLength(3);
    const id = first[0]!.session;
    expect(id).toMatch(SESSION_ID);
    expect(first.map((q) => q!.session)).toEqual([id, id, id]);
    // t: each clip's last frame, in seconds on the phone's clock (the fake films 1 s a call)
    expect(first.map((q) => q!.t)).toEqual([0.9, 2.9, 4.9]);
    // without motion sensors nothing but the session and the clock is sent: no place, no steps
    expect(trackedQuery(first[0]!)).toEqual({ session: id, t: '0.900' });
    // the first turn films 1 s, the answered loop's turns KEEP_SECONDS: its first second, then on
    expect(KEEP_SECONDS).toBe(2);
    expect(cam.captureClip.mock.calls.map((c) => c[2])).toEqual([10, 10, 10, 10, 10]);
    const sent = (c: unknown[]) => {
      const rec = c[1] as Uint8Array;
      return new DataView(rec.buffer, rec.byteOffset).getUint32(HEADER_AT.frames, true);
    };
    expect(api.locate.mock.calls.map(sent)).toEqual([10, 20, 20]); // each 2 s turn one clip
    s.toggleContinuous();
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0);
    const again = tracked()[3]!;
    expect(again.session).toMatch(SESSION_ID);
    expect(again.session).not.toBe(id);
    s.stopContinuous();
  });

  it('a turn that failed before filming (no venue) waits the whole interval, as a 1 s turn does', async () => {
    const { s } = session();
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0); // answered: from now on 2 s, then a second less
    const venueReads = api.venue.mock.calls.length;
    // the second turn films 2 s and is refused (the venue changed): the next reads the venue
    // again, and cannot reach the server, so it films nothing
    api.locate.mockRejectedValueOnce(new ApiProblem(409, 'the venue is being modelled', { error: '', status: 409 }));
    api.venue.mockRejectedValue(new Unreachable('Cannot reach the server.'));
    await vi.advanceTimersByTimeAsync(3000);
    expect(cam.captureClip).toHaveBeenCalledTimes(3);
    await vi.advanceTimersByTimeAsync(2000); // the third turn, a second sooner after the 2 s one
    expect(api.venue.mock.calls.length).toBe(venueReads + 1);
    expect(cam.captureClip).toHaveBeenCalledTimes(3); // nothing filmed
    await vi.advanceTimersByTimeAsync(2999); // so the fourth waits the whole interval
    expect(api.venue.mock.calls.length).toBe(venueReads + 1);
    await vi.advanceTimersByTimeAsync(1);
    expect(api.venue.mock.calls.length).toBe(venueReads + 2);
    s.stopContinuous();
  });

  it('films 1 s a turn until one was answered; stopped while filming on, the turn sends nothing', async () => {
    api.locate.mockRejectedValueOnce(new Unreachable('Cannot reach the server.'));
    const { s, said } = session();
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0); // 1 s, not answered
    await vi.advanceTimersByTimeAsync(3000); // 1 s again, answered
    await vi.advanceTimersByTimeAsync(3000); // from now on 2 s
    expect(cam.captureClip.mock.calls.map((c) => c[2])).toEqual([10, 10, 10, 10]);
    expect(api.locate).toHaveBeenCalledTimes(3);
    // the next turn: its first second filmed, then "Keep telling me" pressed off while it films on
    cam.captureClip
      .mockImplementationOnce((_v, _e, n: number) => Promise.resolve(clip(n, 9000)))
      .mockImplementationOnce((_v, _e, n: number) => {
        s.toggleContinuous();
        return Promise.resolve(clip(n, 10000));
      });
    await vi.advanceTimersByTimeAsync(2000);
    expect(cam.captureClip).toHaveBeenCalledTimes(6);
    expect(api.locate).toHaveBeenCalledTimes(3); // nothing sent
    expect(s.continuous).toBe(false);
    expect(said.at(-1)).toBe(STOPPED_TELLING);
  });

  it('an unsure turn sends no 3-s clip and is said as "not sure", once while it lasts', async () => {
    api.locate
      .mockResolvedValueOnce(trackedAnswer(true, 1))
      .mockResolvedValueOnce(trackedAnswer(true, 2))
      .mockResolvedValueOnce(trackedAnswer(false, 3));
    const { s, said, asking, voice } = session();
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0);
    await vi.advanceTimersByTimeAsync(3000);
    await vi.advanceTimersByTimeAsync(2000);
    // 1 s, then 2 s turns (KEEP_SECONDS, all filmed anyway): nothing more for being unsure
    expect(cam.captureClip.mock.calls.map((c) => c[2])).toEqual([10, 10, 10, 10, 10]);
    expect(api.locate).toHaveBeenCalledTimes(3);
    expect(said).toEqual([UNSURE, s.sentence(answer(false), VENUE)]);
    expect(voice.say).toHaveBeenNthCalledWith(1, UNSURE, 'unsure');
    expect(voice.say).toHaveBeenNthCalledWith(2, s.sentence(answer(false), VENUE), 'ok');
    expect(asking).toEqual([]); // the Where am I? button never turns into a Stop
    s.stopContinuous();
  });

  it('sends the motion since the previous answered turn, asked for inside the tap', async () => {
    const motion = motionFeed([
      { steps: null, turn_deg: null }, // the first reading after start: unknown
      { steps: 3, turn_deg: -20.5 },
      { steps: 5, turn_deg: 10 },
      { steps: 7, turn_deg: 12 },
    ]);
    const askMotion = vi.fn(() => Promise.resolve());
    const { s } = session({ motion, askMotion });
    api.locate
      .mockResolvedValueOnce(trackedAnswer(false, 1))
      .mockResolvedValueOnce(trackedAnswer(false, 2))
      .mockRejectedValueOnce(new Unreachable('Cannot reach the server.'))
      .mockResolvedValue(trackedAnswer(false, 3));
    s.toggleContinuous();
    expect(askMotion).toHaveBeenCalledTimes(1); // still inside the user's tap
    await vi.advanceTimersByTimeAsync(0);
    expect(motion.start).toHaveBeenCalledTimes(1);
    await vi.advanceTimersByTimeAsync(3000); // after the first turn (1 s): the interval
    for (let i = 0; i < 2; i++) await vi.advanceTimersByTimeAsync(2000); // after a 2 s turn: a second less
    const qs = tracked().map((q) => trackedQuery(q!));
    expect(qs.map((q) => [q.steps, q.turn_deg])).toEqual([
      [undefined, undefined],
      ['3', '-20.5'],
      ['5', '10'],
      ['7', '12'],
    ]);
    // a reading counts as sent only once its request was answered: not the failed third one's
    const committed = motion.commit.mock.calls.map((c) => (c[0] as unknown as { n: number }).n);
    expect(committed).toEqual([0, 1, 3]);
    s.toggleContinuous();
    expect(motion.stop).toHaveBeenCalledTimes(1);
  });

  it('a server error mid-loop is said once while it lasts, and the loop goes on', async () => {
    const gone = new Unreachable('Cannot reach the server.');
    api.locate.mockRejectedValueOnce(gone).mockRejectedValueOnce(gone).mockResolvedValue(trackedAnswer(false, 1));
    const { s, said, voice } = session();
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0);
    await vi.advanceTimersByTimeAsync(3000);
    await vi.advanceTimersByTimeAsync(3000);
    expect(said).toEqual([gone.message, s.sentence(answer(false), VENUE)]);
    expect(voice.say).toHaveBeenNthCalledWith(1, gone.message, 'error', true);
    expect(s.continuous).toBe(true);
    s.stopContinuous();
  });

  it('a camera refused ends the loop, said once', async () => {
    cam.openCamera.mockRejectedValue(new CameraProblem('denied', 'Camera access was refused.'));
    const { s, said } = session();
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0);
    await vi.advanceTimersByTimeAsync(30_000);
    expect(said).toEqual(['Camera access was refused.']);
    expect(s.continuous).toBe(false);
    expect(api.locate).not.toHaveBeenCalled();
  });

  it('turning it off while a turn is answered: that answer is not said, no more requests', async () => {
    const motion = motionFeed([{ steps: null, turn_deg: null }]);
    const { s, said } = session({ motion });
    api.locate.mockImplementationOnce(async () => {
      s.toggleContinuous(); // off while the turn is being answered
      return trackedAnswer(false);
    });
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0);
    await vi.advanceTimersByTimeAsync(30_000);
    expect(api.locate).toHaveBeenCalledTimes(1);
    expect(said).toEqual([STOPPED_TELLING]);
    expect(motion.stop).toHaveBeenCalledTimes(1);
  });

  it('a stop and a new start while a turn is still locating leave one loop, not two', async () => {
    const { s } = session();
    let finish = () => {};
    api.locate.mockImplementationOnce(() => new Promise<Answer>((r) => (finish = () => r(trackedAnswer(false)))));
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0); // the first turn is now locating
    s.toggleContinuous();
    s.toggleContinuous();
    finish();
    await vi.advanceTimersByTimeAsync(0); // the new loop's first turn
    expect(api.locate).toHaveBeenCalledTimes(2);
    await vi.advanceTimersByTimeAsync(3000);
    expect(api.locate).toHaveBeenCalledTimes(3);
    s.stopContinuous();
  });

  it('"Where am I?" pressed while a turn is answered: that answer is said in full, though nothing changed', async () => {
    const { s, said } = session();
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0);
    const sentence = s.sentence(answer(false), VENUE);
    expect(said).toEqual([sentence]);
    // the next turn's answer is held back; the press comes while it is awaited
    let release: (a: Answer) => void = () => undefined;
    api.locate.mockImplementationOnce(() => new Promise<Answer>((res) => (release = res)));
    await vi.advanceTimersByTimeAsync(3000);
    expect(api.locate).toHaveBeenCalledTimes(2);
    await s.whereAmI();
    expect(api.locate).toHaveBeenCalledTimes(2); // no second filming beside the turn's
    release(trackedAnswer(false, 2));
    await vi.advanceTimersByTimeAsync(0);
    expect(said).toEqual([sentence, sentence]); // the same place, said again: it was asked for
    await vi.advanceTimersByTimeAsync(3000);
    expect(said).toEqual([sentence, sentence]); // and the next turn is quiet again
    s.stopContinuous();
  });

  it('a press beside another press (not a turn) is not carried to a later turn', async () => {
    const { s, said } = session();
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0);
    const sentence = s.sentence(answer(false), VENUE);
    // between two turns, a press's own locate is held back and a second press comes meanwhile
    let release: (a: Answer) => void = () => undefined;
    api.locate.mockImplementationOnce(() => new Promise<Answer>((res) => (release = res)));
    await vi.advanceTimersByTimeAsync(500);
    const press = s.whereAmI();
    await vi.advanceTimersByTimeAsync(0);
    await s.whereAmI(); // the double tap
    release(answer(false));
    await press;
    expect(said).toEqual([sentence, sentence]); // the press's own answer
    await vi.advanceTimersByTimeAsync(3000);
    expect(said).toEqual([sentence, sentence]); // the next turn is quiet: the same place
    s.stopContinuous();
  });

  it('a new interval applies to the running loop from its next wait', async () => {
    const { s } = session();
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0); // first turn; the next one is due in 3 s
    s.prefs.interval = 10;
    await vi.advanceTimersByTimeAsync(3000);
    expect(api.locate).toHaveBeenCalledTimes(2); // it filmed 2 s: the next in 10 - 1 s
    await vi.advanceTimersByTimeAsync(8999);
    expect(api.locate).toHaveBeenCalledTimes(2);
    await vi.advanceTimersByTimeAsync(1);
    expect(api.locate).toHaveBeenCalledTimes(3);
    s.prefs.interval = 2; // the shortest offered: after a 2 s turn, a second
    await vi.advanceTimersByTimeAsync(8999);
    expect(api.locate).toHaveBeenCalledTimes(3);
    await vi.advanceTimersByTimeAsync(1);
    expect(api.locate).toHaveBeenCalledTimes(4);
    await vi.advanceTimersByTimeAsync(999);
    expect(api.locate).toHaveBeenCalledTimes(4);
    await vi.advanceTimersByTimeAsync(1);
    expect(api.locate).toHaveBeenCalledTimes(5);
    s.stopContinuous();
  });
});

describe('a single "Where am I?"', () => {
  beforeEach(() => {
    fakes(answer(false));
    cam.captureClip.mockImplementation((_v, _e, n: number) => Promise.resolve(clip(n, 0)));
  });
  afterEach(() => vi.useRealTimers());

  it('after "Keep telling me" was stopped: no tracking session, the start cue, the answer said', async () => {
    const { s, said, voice } = session();
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0);
    s.toggleContinuous();
    await s.whereAmI();
    expect(tracked().map((q) => q?.session === undefined)).toEqual([false, true]);
    expect(voice.cue).toHaveBeenCalledWith('start');
    // the same place again: a press always says it
    const sentence = s.sentence(answer(false), VENUE);
    expect(said).toEqual([sentence, STOPPED_TELLING, sentence]);
  });

  const stale = "features were made with other settings (id 7) than this venue's (8); extract them with ...";
  const mapUpdatedProblem = (now = 8) =>
    new ApiProblem(400, stale, { error: stale, status: 400, venue_settings_id: now });
  /** The settings id in each locate request's record (its header, little-endian). */
  const sentIds = () =>
    api.locate.mock.calls.map((c) => {
      const rec = c[1] as Uint8Array;
      return new DataView(rec.buffer, rec.byteOffset).getUint32(HEADER_AT.settings_id, true);
    });
  const MODELLED_ANEW = { ...VENUE, features: { ...VENUE.features, settings_id: 8 } };

  it('the venue modelled anew since it was read: reads it again, films again and answers, in one press', async () => {
    const { s, said, voice } = session();
    api.venue.mockResolvedValueOnce(VENUE).mockResolvedValueOnce(MODELLED_ANEW);
    api.locate.mockRejectedValueOnce(mapUpdatedProblem());
    await s.whereAmI();
    expect(api.venue).toHaveBeenCalledTimes(2);
    expect(sentIds()).toEqual([7, 8]); // a clip made with the new settings, not the first one again
    expect(voice.cue.mock.calls.filter((c) => c[0] === 'start')).toHaveLength(2);
    expect(said).toEqual([s.sentence(answer(false), MODELLED_ANEW)]);
  });

  it('a mismatch naming the very settings sent is no update: said as the server put it, not retried', async () => {
    const { s, said } = session();
    api.locate.mockRejectedValueOnce(mapUpdatedProblem(7));
    await s.whereAmI();
    expect(api.locate).toHaveBeenCalledTimes(1);
    expect(said).toEqual([`The server could not answer: ${stale}`]);
  });

  it('modelled anew twice in one press: says the map was updated, once, and asks again no more', async () => {
    const { s, said } = session();
    api.locate.mockRejectedValueOnce(mapUpdatedProblem()).mockRejectedValueOnce(mapUpdatedProblem());
    await s.whereAmI();
    expect(api.locate).toHaveBeenCalledTimes(2);
    expect(said).toEqual([MAP_UPDATED]);
    await s.whereAmI();
    expect(api.venue).toHaveBeenCalledTimes(3);
    expect(said).toEqual([MAP_UPDATED, s.sentence(answer(false), VENUE)]);
  });

  it('another 400 is said as the server put it', async () => {
    const { s, said } = session();
    api.locate.mockRejectedValueOnce(new ApiProblem(400, 'feature record magnitudes must lie in [0, 1]'));
    await s.whereAmI();
    expect(said).toEqual(['The server could not answer: feature record magnitudes must lie in [0, 1]']);
  });
});
