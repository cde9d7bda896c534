// "Ask for more": a press films on while its first second is answered; when that answer is not
// sure it says so and sends the 30 frames (the first 10 and the 20 filmed on) as one record: one
// more request, answered from all of it. Once per press; Stop ends it; a sure answer ends the filming.
// ("Keep telling me" never films on: its turns are tracked, session.test.ts.)
// The camera, the worker and the server are fakes: this is the session's logic, not the locating.
import { beforeEach, describe, expect, it, vi } from 'vitest';
import { UNSURE } from '../src/client/directions';
import { KEEP_TURNING, MORE_FRAMES, STOPPED, TRUSTED_CONFIDENCE } from '../src/client/session';
import { HEADER_AT } from '../src/shared/record';
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

/** Frames in each record the session sent, and the frame rate it stated. */
const sent = () =>
  api.locate.mock.calls.map((c) => ({
    frames: new DataView((c[1] as Uint8Array).buffer).getUint32(HEADER_AT.frames, true),
    fps: c[2] as number,
  }));

describe('asking for more when the first second is not sure', () => {
  beforeEach(() => {
    vi.clearAllMocks();
    api.venues.mockResolvedValue([{ id: 'lab', name: 'Lab' }]);
    api.venue.mockResolvedValue(VENUE);
    cam.openCamera.mockResolvedValue({ getVideoTracks: () => [{ readyState: 'live' }] });
    // the 20 frames follow on from the first 10 (grabbed 0-900 ms): 1000-2900 ms
    cam.captureClip.mockImplementation((_v, _e, n: number) => Promise.resolve(clip(n, n === 10 ? 0 : 1000)));
  });

  it('a sure first second answers at once: one request of 10 frames, the filming on ended', async () => {
    api.locate.mockResolvedValue(answer(false));
    const { s, said, asking } = session();
    await s.whereAmI();
    expect(sent().map((r) => r.frames)).toEqual([10]);
    const [first, on] = cam.captureClip.mock.calls;
    expect(on[2]).toBe(MORE_FRAMES);
    expect(on[5]).toEqual(clip(10, 0)); // filmed to follow the first second
    expect(first[2]).toBe(10);
    expect(on[4]()).toBe(true); // stopped by the sure answer
    expect(said).toEqual([s.sentence(answer(false), VENUE)]);
    expect(asking).toEqual([]);
  });

  it('an unsure first second: "keep turning", 20 frames more, one request of all 30, its answer said', async () => {
    api.locate.mockResolvedValueOnce(answer(true)).mockResolvedValueOnce(answer(false));
    const { s, said, asking, answers, voice } = session();
    await s.whereAmI();
    expect(cam.captureClip.mock.calls.map((c) => c[2])).toEqual([10, MORE_FRAMES]);
    const recs = sent();
    expect(recs.map((r) => r.frames)).toEqual([10, 30]);
    expect(recs[1].fps).toBeCloseTo(10, 6); // 30 frames, 100 ms apart: no gap for the first answer
    // a press is a single question: no tracking session (only "Keep telling me" and the guide track)
    expect(api.locate.mock.calls.map((c) => c[4])).toEqual([undefined, undefined]);
    expect(said).toEqual([KEEP_TURNING, s.sentence(answer(false), VENUE)]);
    expect(asking).toEqual([true, false]);
    expect(answers).toEqual([30]); // only the answer that was said is shown
    // "keep turning" is polite and without a cue: the answer that follows has its own
    expect(voice.say).toHaveBeenNthCalledWith(1, KEEP_TURNING, null, false, false); // Repeat keeps the answer
  });

  it('a first answer of a place, not sure of it: said at once as "probably", then the sure one after 3 s', async () => {
    const middling = { ...answer(false), confidence: TRUSTED_CONFIDENCE - 0.2 };
    api.locate.mockResolvedValueOnce(middling).mockResolvedValueOnce(answer(false));
    const { s, said, answers } = session();
    await s.whereAmI();
    expect(sent().map((r) => r.frames)).toEqual([10, 30]);
    // no "not sure yet" first: the place, as probable, while the phone films on; then sure
    expect(said).toEqual([s.sentence(middling, VENUE), s.sentence(answer(false), VENUE)]);
    expect(said[0]).toMatch(/^You are probably /);
    expect(answers).toEqual([10, 30]);
  });

  it('the same place, still not sure after the 3 s: said once, as "probably", with the usual cue', async () => {
    const middling = { ...answer(false), confidence: TRUSTED_CONFIDENCE - 0.15 };
    api.locate.mockResolvedValue(middling);
    const { s, said, voice } = session();
    await s.whereAmI();
    expect(sent().map((r) => r.frames)).toEqual([10, 30]);
    expect(said).toHaveLength(1);
    expect(said[0]).toMatch(/^You are probably /);
    expect(said[0].replace('You are probably ', 'You are ')).toBe(s.sentence(answer(false), VENUE));
    expect(voice.say).toHaveBeenLastCalledWith(said[0], 'ok');
  });

  it('"probably", then not sure from the 3 s: the probable place stands, nothing withdrawn', async () => {
    const middling = { ...answer(false), confidence: TRUSTED_CONFIDENCE - 0.2 };
    api.locate.mockResolvedValueOnce(middling).mockResolvedValueOnce(answer(true));
    const { s, said, answers } = session();
    await s.whereAmI();
    expect(sent().map((r) => r.frames)).toEqual([10, 30]);
    // the longer clip is no news: "Not sure where you are" would take back what the user just heard
    expect(said).toEqual([s.sentence(middling, VENUE)]);
    expect(answers).toEqual([10]);
  });

  it('unsure twice: the usual "not sure", and no third request', async () => {
    api.locate.mockResolvedValue(answer(true));
    const { s, said } = session();
    await s.whereAmI();
    expect(sent().map((r) => r.frames)).toEqual([10, 30]);
    expect(said).toEqual([KEEP_TURNING, UNSURE]);
  });

  it('no venue chosen: the first modelled one, not one an admin has only begun that sorts first', async () => {
    api.venues.mockResolvedValue([
      { id: 'begun', name: 'Begun', modelled: false },
      { id: 'lab', name: 'Lab', modelled: true },
    ]);
    const { s } = session();
    await s.loadVenue();
    expect(api.venue).toHaveBeenCalledWith('lab');
    // none modelled: the first, which then says it is not modelled yet
    api.venues.mockResolvedValue([{ id: 'begun', name: 'Begun', modelled: false }]);
    api.venue.mockClear();
    await session().s.loadVenue();
    expect(api.venue).toHaveBeenCalledWith('begun');
  });

  it('once per press: the next press starts again from one second', async () => {
    api.locate.mockResolvedValue(answer(true));
    const { s } = session();
    await s.whereAmI();
    await s.whereAmI();
    expect(sent().map((r) => r.frames)).toEqual([10, 30, 10, 30]);
  });

  it('Stop while filming more: nothing more is sent, "Stopped." is said', async () => {
    api.locate.mockResolvedValue(answer(true));
    const { s, said, asking, answers } = session();
    let release = () => {};
    let stopAsked = () => false;
    cam.captureClip.mockImplementation((_v, _e, n: number, _ms, stop: () => boolean) => {
      if (n === 10) return Promise.resolve(clip(10, 0));
      stopAsked = stop;
      return new Promise((r) => (release = () => r(clip(stop() ? 7 : n, 1000))));
    });
    s.on('asking', (on) => {
      if (!on) return;
      expect(s.asking).toBe(true);
      s.stop(); // the user presses Stop while the phone films on
      release();
    });
    await s.whereAmI();
    expect(stopAsked()).toBe(true);
    expect(sent().map((r) => r.frames)).toEqual([10]);
    expect(said).toEqual([KEEP_TURNING, STOPPED]);
    expect(asking).toEqual([true, false]);
    expect(answers).toEqual([]);
    expect(s.asking).toBe(false);
    s.stop(); // nothing to stop now: nothing said
    expect(said).toHaveLength(2);
  });
});
