// "Ask for more": a press films on while its first second is answered; when that answer is not
// sure it says so and sends the 30 frames (the first 10 and the 20 filmed on) as one record: one
// more request, answered from all of it. Once per press; Stop ends it; a sure answer ends the filming.
// The camera, the worker and the server are fakes: this is the session's logic, not the locating.
import { beforeEach, describe, expect, it, vi } from 'vitest';
import type { Answer, Venue } from '../src/client/api';
import type { Clip } from '../src/client/camera';
import { UNSURE } from '../src/client/directions';
import { DEFAULTS } from '../src/client/prefs';
import { KEEP_TURNING, MORE_FRAMES, STOPPED, Session, TRUSTED_CONFIDENCE } from '../src/client/session';
import { HEADER_AT } from '../src/shared/record';

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

const CK = 2; // curves x harmonics of the fake venue: small records
const VENUE: Venue = {
  id: 'lab',
  name: 'Lab',
  revision: 1,
  modelled: true,
  frames: 100,
  floors: [{ id: '1', name: 'Ground floor', plan_url: null, plan_size_px: null, px_per_m: null }],
  places: [],
  // a 360 camera: no donut ring to check first
  lenses: { pano: { model: 'equirectangular', image_size: [640, 320], forward_x: 320 } },
  features: {
    settings: {
      pano_width: 360,
      oversample: 4,
      row_step_deg: 1,
      bands: [[-20, 20]],
      channels: ['I'],
      gray_world: false,
      n_harmonics: CK,
    },
    settings_id: 7,
    n_curves: 1,
    n_harmonics: CK,
    record_header_bytes: 20,
    record_bytes_per_frame: 4 * CK,
  },
};

function answer(lowConfidence: boolean): Answer {
  return {
    ...{ clip: 'c', x: 3, y: 4, heading_deg: 90, confidence: lowConfidence ? 0.3 : 0.9, floor: '1' },
    ...{ place: null, frame: 5, area: 'the Hall', nearest: null, facing: null, sentence: '' },
    ...{ low_confidence: lowConfidence, accuracy_m: lowConfidence ? null : 2, frames: 10, sent: 'features' },
  };
}

/** A clip of `n` fake frames, grabbed 100 ms apart from `at` ms. */
function clip(n: number, at: number): Clip {
  const frames = Array.from({ length: n }, () => ({ mag: new Uint16Array(CK), phase: new Int16Array(CK), ms: 1 }));
  return { frames, fps: 10, startMs: at, endMs: at + 100 * (n - 1) };
}

function session() {
  const said: string[] = [];
  const voice = { busy: false, say: vi.fn((text: string) => said.push(text)), cue: vi.fn() };
  const s = new Session({
    prefs: { ...DEFAULTS },
    save: vi.fn(),
    voice,
    video: { videoWidth: 640, videoHeight: 320 } as HTMLVideoElement,
    askedVenue: null,
  });
  const asking: boolean[] = [];
  s.on('asking', (on) => asking.push(on));
  const answers: number[] = [];
  s.on('answer', (r) => answers.push(r.frames));
  return { s, said, asking, answers, voice };
}

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
    expect(said).toEqual([KEEP_TURNING, s.sentence(answer(false), VENUE)]);
    expect(asking).toEqual([true, false]);
    expect(answers).toEqual([30]); // only the answer that was said is shown
    // "keep turning" is polite and without a cue: the answer that follows has its own
    expect(voice.say).toHaveBeenNthCalledWith(1, KEEP_TURNING, null, false, false); // Repeat keeps the answer
  });

  it('a first answer said without "not sure" but below the trusted confidence still asks for more', async () => {
    const middling = { ...answer(false), confidence: TRUSTED_CONFIDENCE - 0.2 };
    api.locate.mockResolvedValueOnce(middling).mockResolvedValueOnce(answer(false));
    const { s, said } = session();
    await s.whereAmI();
    expect(sent().map((r) => r.frames)).toEqual([10, 30]);
    expect(said).toEqual([KEEP_TURNING, s.sentence(answer(false), VENUE)]);
  });

  it('unsure twice: the usual "not sure", and no third request', async () => {
    api.locate.mockResolvedValue(answer(true));
    const { s, said } = session();
    await s.whereAmI();
    expect(sent().map((r) => r.frames)).toEqual([10, 30]);
    expect(said).toEqual([KEEP_TURNING, UNSURE]);
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

  it('continuous mode asks for more without saying so', async () => {
    api.locate.mockResolvedValue(answer(true));
    const { s, said, asking } = session();
    await s.whereAmI(true);
    expect(sent().map((r) => r.frames)).toEqual([10, 30]);
    expect(said).toEqual([UNSURE]);
    expect(asking).toEqual([]); // the button does not turn into a Stop that would leave the loop running
  });

  it('turning "Keep telling me" off while the first second is answered: nothing more is sent', async () => {
    const { s, said, asking } = session();
    api.locate.mockImplementation(async () => {
      s.toggleContinuous(); // on
      s.toggleContinuous(); // and off again while the first second is being answered
      return answer(true);
    });
    await s.whereAmI(true);
    expect(sent().map((r) => r.frames)).toEqual([10]);
    expect(said).toEqual(['Stopped telling you.']);
    expect(asking).toEqual([]);
  });
});
