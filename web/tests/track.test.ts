// A guided walk's request (Session.track, for guide.ts): ~1 s filmed, then located in the tracking
// session with the place, the clip's last frame on the phone's clock and the motion since the last
// request, asked for once the clip is filmed; nothing said, errors thrown for the guide; the camera
// taken by a "Where am I?" answers null. The camera, the worker and the server are fakes.
import { beforeEach, describe, expect, it, vi } from 'vitest';
import { ApiProblem, type Answer } from '../src/client/api';
import type { Clip } from '../src/client/camera';
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

describe('Session.track', () => {
  beforeEach(() => {
    vi.clearAllMocks();
    api.venues.mockResolvedValue([{ id: 'lab', name: 'Lab' }]);
    api.venue.mockResolvedValue(VENUE);
    cam.openCamera.mockResolvedValue({ getVideoTracks: () => [{ readyState: 'live' }] });
    cam.captureClip.mockImplementation((_v, _e, n: number) => Promise.resolve(clip(n, 4000)));
  });

  it('films 10 frames and locates them in the session, with the clock and the motion since the last', async () => {
    api.locate.mockResolvedValue(answer(false));
    const { s, said, answers } = session();
    const order: string[] = [];
    cam.captureClip.mockImplementation((_v, _e, n: number) => {
      order.push('film');
      return Promise.resolve(clip(n, 4000));
    });
    const motion = vi.fn(() => {
      order.push('motion');
      return { steps: 4, turn_deg: 30.5 };
    });
    const r = await s.track({ session: 'abcdefgh12', to: 'p3', style: 'sides' }, motion);
    expect(r?.answer).toEqual(answer(false));
    expect(order).toEqual(['film', 'motion']);
    expect(cam.captureClip.mock.calls.map((c) => c[2])).toEqual([10]);
    const [venueId, , fps, , tracked] = api.locate.mock.calls[0];
    expect([venueId, fps]).toEqual(['lab', 10]);
    // the clip's last frame: 4000 ms + 9 x 100 ms on performance.now()'s clock
    expect(tracked).toEqual({ session: 'abcdefgh12', to: 'p3', style: 'sides', t: 4.9, steps: 4, turn_deg: 30.5 });
    expect(said).toEqual([]); // the guide says what is to be said
    expect(answers).toEqual([10]); // the locate screen shows the latest pose too
  });

  it('films as many seconds as asked (a guided walk under way: 2 s), all sent as one clip', async () => {
    api.locate.mockResolvedValue(answer(false));
    // a clip that follows another is filmed on from it: its frames 100 ms after the other's last
    cam.captureClip.mockImplementation((_v, _e, n: number, _ms, _stop, follow?: Clip) =>
      Promise.resolve(clip(n, follow ? follow.endMs + 100 : 4000)),
    );
    const { s } = session();
    await s.track({ session: 'abcdefgh12', to: 'p3' }, undefined, 2);
    await s.track({ session: 'abcdefgh12', to: 'p3' }, undefined, 9); // at most 4.5 s (the server: 5 s)
    // the first second (the lens checked on it), then the rest filmed on from it
    expect(cam.captureClip.mock.calls.map((c) => c[2])).toEqual([10, 10, 10, 35]);
    const [, record, fps, , tracked] = api.locate.mock.calls[0];
    expect(fps).toBe(10);
    expect(tracked.t).toBeCloseTo(4 + 1.9); // the clip's last frame: 4000 ms + 19 x 100 ms
    // every frame filmed is in the record: 45 frames' is 2.25 times 20 frames' (less the header)
    const header = (20 * (api.locate.mock.calls[1][1] as Uint8Array).length - 45 * (record as Uint8Array).length) / -25;
    expect(header).toBeGreaterThanOrEqual(0);
    expect(header).toBeLessThan(64);
  });

  it('a stop ends the filming after the first second, never before, and nothing is sent', async () => {
    api.locate.mockResolvedValue(answer(false));
    const { s } = session();
    let stopped = false;
    cam.captureClip.mockImplementation((_v, _e, n: number) => {
      stopped = true; // Stop guidance while the first second is filmed
      return Promise.resolve(clip(n, 4000));
    });
    expect(await s.track({ session: 'abcdefgh12', to: 'p3' }, undefined, 3, () => stopped)).toBeNull();
    expect(cam.captureClip.mock.calls.map((c) => c[2])).toEqual([10]);
    expect(api.locate).not.toHaveBeenCalled();
    stopped = false; // a later request films and asks as usual
    cam.captureClip.mockImplementation((_v, _e, n: number) => Promise.resolve(clip(n, 4000)));
    expect(await s.track({ session: 'abcdefgh12', to: 'p3' }, undefined, 1, () => stopped)).not.toBeNull();
  });

  it('throws the problem for the guide to say, and answers null while a "Where am I?" films', async () => {
    const { s, said } = session();
    api.locate.mockRejectedValueOnce(new ApiProblem(404, "no place 'x' in venue 'lab'"));
    await expect(s.track({ session: 'abcdefgh12', to: 'x' })).rejects.toThrow('no place');
    expect(said).toEqual([]);
    let release: (a: Answer) => void = () => undefined;
    api.locate.mockReturnValueOnce(new Promise<Answer>((r) => (release = r)));
    const asking = s.whereAmI();
    await vi.waitFor(() => expect(api.locate).toHaveBeenCalledTimes(2));
    expect(await s.track({ session: 'abcdefgh12', to: 'p3' })).toBeNull();
    release(answer(false));
    await asking;
    api.locate.mockResolvedValue(answer(false));
    expect(await s.track({ session: 'abcdefgh12', to: 'p3' })).not.toBeNull();
  });
});

describe('the tracked query', () => {
  it('sends what is known, within the server bounds, and leaves out what is not', async () => {
    const { trackedQuery } = await import('../src/client/api');
    expect(
      trackedQuery({ session: 's-123456', to: 'Room 102', t: 12.34567, steps: 3, turn_deg: -45.26, style: 'degrees' }),
    ).toEqual({
      session: 's-123456',
      to: 'Room 102',
      t: '12.346',
      steps: '3',
      turn_deg: '-45.3',
      style: 'degrees',
    });
    expect(trackedQuery({ session: 's-123456', steps: null, turn_deg: null })).toEqual({ session: 's-123456' });
    expect(trackedQuery({ session: 's-123456', steps: 20000, turn_deg: 50000 })).toMatchObject({
      steps: '10000',
      turn_deg: '36000',
    });
  });
});
