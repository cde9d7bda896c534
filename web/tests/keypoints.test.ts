// Keypoints on a verifying venue: a single "Where am I?" sends its clip's last frame's local
// features (record version 2) only where the venue checks answers with them and the user allowed it
// in Settings (read at each request); the worker is asked for the frame by its id; the longer clip
// of an unsure press sends its own last frame's; a failure leaves the curves to answer; tracked
// requests (the server does not verify them) send none; the setting's toggle readies the worker
// without touching its lens. The camera, the worker and the server are fakes.
import { beforeEach, describe, expect, it, vi } from 'vitest';
import { VERIFY_HINT } from '../src/client/session';
import { HEADER_AT, LOCAL_VERSION, RECORD_VERSION, recordLocal, type LocalBlock } from '../src/shared/record';
import { VENUE, answer, clip, session } from './fake-session';

const api = vi.hoisted(() => ({ venues: vi.fn(), venue: vi.fn(), locate: vi.fn() }));
const cam = vi.hoisted(() => ({ captureClip: vi.fn(), openCamera: vi.fn() }));
const worker = vi.hoisted(() => ({ local: vi.fn(), configure: vi.fn(), prepareLocal: vi.fn(), log: [] as string[] }));
vi.mock('../src/client/api', async (orig) => ({ ...(await orig<object>()), ...api }));
vi.mock('../src/client/camera', async (orig) => ({ ...(await orig<object>()), ...cam }));
vi.mock('../src/client/bridge', () => ({
  ExtractorClient: class {
    configured = 'fake';
    configure = worker.configure;
    prepareLocal = worker.prepareLocal;
    local = worker.local;
  },
}));

const VERIFIED = {
  ...VENUE,
  features: { ...VENUE.features, settings: { ...VENUE.features.settings, local_features: 900 } },
};

/** `n` fake keypoints, the first at azimuth unit `first`. */
const block = (n: number, first: number): LocalBlock & { ms: number } => ({
  az: Uint16Array.from({ length: n }, (_, i) => first + i),
  el: Int16Array.from({ length: n }, (_, i) => -i),
  desc: new Uint8Array(32 * n).fill(first & 0xff),
  ms: 20,
});

/** Each locate request's record version and the first azimuth unit of its keypoints (null: none). */
const sent = () =>
  api.locate.mock.calls.map((c) => {
    const rec = c[1] as Uint8Array;
    return [rec[HEADER_AT.version], recordLocal(rec)?.az[0] ?? null];
  });

describe('keypoints of the last frame, on a verifying venue', () => {
  beforeEach(() => {
    vi.resetAllMocks();
    worker.log.length = 0;
    api.venues.mockResolvedValue([{ id: 'lab', name: 'Lab' }]);
    api.venue.mockResolvedValue(VERIFIED);
    api.locate.mockResolvedValue(answer(false));
    cam.openCamera.mockResolvedValue({ getVideoTracks: () => [{ readyState: 'live' }] });
    // each frame has its worker request's id: the first second 1-10, the 20 filmed on 11-30
    cam.captureClip.mockImplementation((_v, _e, n: number) => {
      worker.log.push(`film ${n}`);
      const c = clip(n, n === 10 ? 0 : 1000);
      c.frames.forEach((f, i) => Object.assign(f, { id: i + (n === 10 ? 1 : 11) }));
      return Promise.resolve(c);
    });
    worker.configure.mockResolvedValue(1);
    worker.prepareLocal.mockResolvedValue(5);
    let at = 100;
    worker.local.mockImplementation((frame: number) => {
      worker.log.push(`keypoints of ${frame}`);
      return Promise.resolve(block(3, (at += 100)));
    });
  });

  it("allowed: the press sends version 2 with the last frame's keypoints, asked before the next frame", async () => {
    const { s, said } = session();
    s.set('keypoints', true);
    await s.whereAmI();
    expect(sent()).toEqual([[LOCAL_VERSION, 200]]);
    // the worker was readied for 900 keypoints and asked for those of the clip's last frame
    expect(worker.prepareLocal.mock.calls.at(-1)).toEqual([900]);
    expect(worker.log).toEqual(['film 10', 'keypoints of 10', 'film 20']);
    expect(said).toEqual([s.sentence(answer(false), VERIFIED)]);
  });

  it('not allowed (the default): version 1, no keypoints asked, and the venue line says how to allow them', async () => {
    const { s } = session();
    const lines: string[] = [];
    s.on('line', (l) => lines.push(l));
    await s.whereAmI();
    expect(sent()).toEqual([[RECORD_VERSION, null]]);
    expect(worker.local).not.toHaveBeenCalled();
    expect(worker.prepareLocal).not.toHaveBeenCalled(); // the worker keeps no frames for them
    expect(lines.at(-1)).toContain(VERIFY_HINT);
    // allowed in Settings: the hint goes, and the worker is readied for 900 keypoints at once,
    // its lens (and any correction of it) left alone: no new configuration
    const configured = worker.configure.mock.calls.length;
    s.set('keypoints', true);
    expect(lines.at(-1)).not.toContain(VERIFY_HINT);
    expect(lines.at(-1)).toContain('Ready');
    expect(worker.prepareLocal.mock.calls.at(-1)).toEqual([900]);
    expect(worker.configure.mock.calls.length).toBe(configured);
  });

  it('a venue that does not verify: version 1 though allowed, and no hint', async () => {
    api.venue.mockResolvedValue(VENUE);
    const { s } = session();
    s.set('keypoints', true);
    const lines: string[] = [];
    s.on('line', (l) => lines.push(l));
    await s.whereAmI();
    expect(sent()).toEqual([[RECORD_VERSION, null]]);
    expect(worker.local).not.toHaveBeenCalled();
    expect(lines.at(-1)).not.toContain(VERIFY_HINT);
  });

  it("an unsure first second: the 3 s clip brings its own last frame's keypoints", async () => {
    api.locate.mockResolvedValueOnce(answer(true)).mockResolvedValueOnce(answer(false));
    const { s } = session();
    s.set('keypoints', true);
    await s.whereAmI();
    expect(sent()).toEqual([
      [LOCAL_VERSION, 200],
      [LOCAL_VERSION, 300],
    ]);
    expect(worker.log).toEqual(['film 10', 'keypoints of 10', 'film 20', 'keypoints of 30']);
  });

  it('turned off while an unsure press films on: the 3 s clip goes without them', async () => {
    const { s } = session();
    s.set('keypoints', true);
    api.locate
      .mockImplementationOnce(async () => {
        s.set('keypoints', false); // while the first second is answered
        return answer(true);
      })
      .mockResolvedValueOnce(answer(false));
    await s.whereAmI();
    expect(sent()).toEqual([
      [LOCAL_VERSION, 200],
      [RECORD_VERSION, null],
    ]);
    expect(worker.prepareLocal.mock.calls.at(-1)).toEqual([0]);
  });

  it('a stored setting that is not true (an old or hand-edited value) sends none', async () => {
    const { s } = session();
    (s.prefs as unknown as Record<string, unknown>).keypoints = 'false';
    await s.whereAmI();
    expect(sent()).toEqual([[RECORD_VERSION, null]]);
  });

  it('keypoints that fail in the worker: the curves are sent alone and answered', async () => {
    worker.local.mockRejectedValue(new Error('out of memory'));
    const { s, said } = session();
    s.set('keypoints', true);
    await s.whereAmI();
    expect(sent()).toEqual([[RECORD_VERSION, null]]);
    expect(said).toEqual([s.sentence(answer(false), VERIFIED)]);
  });

  it('a tracked request (guidance, "Keep telling me") sends none: the server verifies single clips', async () => {
    const { s } = session();
    s.set('keypoints', true);
    await s.track({ session: 'abcdefgh' });
    expect(sent()).toEqual([[RECORD_VERSION, null]]);
    expect(worker.local).not.toHaveBeenCalled();
  });
});
