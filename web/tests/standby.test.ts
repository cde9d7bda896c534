// The last second, ready at the press (standby.ts): while the camera is open and nothing films, a
// frame every 100 ms, the last ten kept; a press sends them at once and films on after them; a
// pause, another lens profile or a stale ring never sends an old frame. The camera, the worker and
// the server are fakes.
import { afterEach, beforeEach, describe, expect, it, vi } from 'vitest';
import type { FrameResult } from '../src/client/bridge';
import { HEADER_AT } from '../src/shared/record';
import { Standby, clipOf, lyingFlat, Posture, type Kept } from '../src/client/standby';
import { VENUE, CK, answer, clip, session } from './fake-session';

const api = vi.hoisted(() => ({ venues: vi.fn(), venue: vi.fn(), locate: vi.fn() }));
const cam = vi.hoisted(() => ({ captureClip: vi.fn(), openCamera: vi.fn(), grabFrame: vi.fn() }));
vi.mock('../src/client/api', async (orig) => ({ ...(await orig<object>()), ...api }));
vi.mock('../src/client/camera', async (orig) => ({ ...(await orig<object>()), ...cam }));
vi.mock('../src/client/bridge', () => ({
  ExtractorClient: class {
    configured = 'fake';
    configure = () => Promise.resolve(1);
  },
}));

const frame = (ms = 4): FrameResult => ({ mag: new Uint16Array(CK), phase: new Int16Array(CK), ms });
const kept = (t: number, key: string | null = 'k'): Kept => ({ frame: frame(), t, key });
const ring = (n: number, from = 0, step = 100) => Array.from({ length: n }, (_, i) => kept(from + i * step));

describe('clipOf: the kept frames that make a clip', () => {
  it('the last ten, 100 ms apart, the newest fresh: one clip at 10 frames/s', () => {
    const c = clipOf(ring(12), 10, 1150, 100, 'k')!;
    expect(c.frames).toHaveLength(10);
    expect([c.startMs, c.endMs]).toEqual([200, 1100]);
    expect(c.fps).toBeCloseTo(10);
  });

  it('none: too few, the newest stale, a gap, another profile', () => {
    expect(clipOf(ring(9), 10, 900, 100, 'k')).toBeNull();
    expect(clipOf(ring(10), 10, 900 + 251, 100, 'k')).toBeNull(); // 2.5 intervals after the last
    expect(clipOf(ring(10), 10, 900 + 250, 100, 'k')).not.toBeNull();
    const gap = [...ring(5), ...ring(5, 801)];
    expect(clipOf(gap, 10, 1300, 100, 'k')).toBeNull(); // 401 ms between two frames
    expect(clipOf(ring(10), 10, 950, 100, 'other')).toBeNull();
  });
});

describe('Standby', () => {
  beforeEach(() => vi.useFakeTimers());
  afterEach(() => vi.useRealTimers());

  function standby(allowed = () => true, grab = () => Promise.resolve(frame())) {
    let now = 0;
    const grabs = vi.fn(grab);
    const sb = new Standby({ size: 10, intervalMs: 100, grab: grabs, allowed, key: () => 'k', now: () => now });
    const run = async (ms: number) => {
      for (let t = 0; t < ms; t += 10) {
        now += 10;
        await vi.advanceTimersByTimeAsync(10);
      }
    };
    return { sb, grabs, run };
  }

  it('grabs ten frames a second, keeps the last ten; take empties it; a pause empties it too', async () => {
    let allowed = true;
    const { sb, grabs, run } = standby(() => allowed);
    sb.start();
    await run(1500);
    expect(grabs.mock.calls.length).toBeGreaterThanOrEqual(14);
    expect(grabs.mock.calls.length).toBeLessThanOrEqual(16);
    expect(sb.kept).toBe(10);
    const c = sb.take()!;
    expect(c.frames).toHaveLength(10);
    expect(c.endMs - c.startMs).toBe(900);
    expect(sb.kept).toBe(0);
    expect(sb.take()).toBeNull(); // a frame is sent once
    await run(1000);
    expect(sb.kept).toBe(10);
    allowed = false; // the screen changed, the page hidden, the phone laid flat
    await run(300);
    expect(sb.kept).toBe(0);
    const before = grabs.mock.calls.length;
    await run(2000);
    expect(grabs.mock.calls.length).toBe(before); // nothing grabbed while paused
    expect(sb.duty()).toBeNull();
    sb.stop();
  });

  it('measures the worker time it costs: 4 ms a frame at 10 frames/s is 4 % of the time', async () => {
    const { sb, run } = standby();
    sb.start();
    await run(2000);
    expect(sb.duty()).toBeCloseTo(0.04, 2);
    sb.stop();
  });

  it('a slow worker: at most two frames in it, frames skipped rather than queued', async () => {
    const pending: ((f: FrameResult) => void)[] = [];
    const { sb, grabs, run } = standby(
      () => true,
      () => new Promise<FrameResult>((r) => pending.push(r)),
    );
    sb.start();
    await run(1000);
    expect(grabs).toHaveBeenCalledTimes(2);
    pending.shift()!(frame());
    await run(100);
    expect(grabs).toHaveBeenCalledTimes(3);
    sb.stop();
  });

  it('the camera gone: it stops, and grabs again only once started again', async () => {
    let gone = false;
    let now = 0;
    const grabs = vi.fn(() => Promise.resolve(frame()));
    const sb = new Standby({
      size: 10,
      intervalMs: 100,
      grab: grabs,
      allowed: () => true,
      key: () => 'k',
      gone: () => gone,
      now: () => now,
    });
    sb.start();
    await vi.advanceTimersByTimeAsync(500);
    gone = true;
    now += 500;
    await vi.advanceTimersByTimeAsync(200);
    const n = grabs.mock.calls.length;
    expect(vi.getTimerCount()).toBe(0); // no timer left polling
    gone = false;
    sb.start();
    await vi.advanceTimersByTimeAsync(300);
    expect(grabs.mock.calls.length).toBeGreaterThan(n);
    sb.stop();
  });

  it('nothing to grab (a press films its own frames): nothing grabbed, nothing counted', async () => {
    const { sb, run } = standby(() => true);
    const none = new Standby({ size: 10, intervalMs: 100, grab: () => null, allowed: () => true, key: () => 'k' });
    none.start();
    sb.start();
    await run(1500);
    expect(none.kept).toBe(0);
    expect(none.duty()).toBeNull();
    expect(sb.kept).toBe(10); // beside it, one with frames to grab keeps them
    none.stop();
    sb.stop();
  });
});

describe('the phone lying flat pauses it', () => {
  it('within 20 degrees of level, face up or down; upright or tilted is not flat', () => {
    expect(lyingFlat(3, -5)).toBe(true);
    expect(lyingFlat(-175, 10)).toBe(true);
    expect(lyingFlat(85, 2)).toBe(false); // upright, lens on top
    expect(lyingFlat(40, 0)).toBe(false);
    expect(lyingFlat(5, 60)).toBe(false); // on its side
  });

  it('follows deviceorientation; without readings it is never flat', () => {
    const target = new EventTarget();
    const p = new Posture(target as unknown as Window);
    expect(p.flat).toBe(false);
    target.dispatchEvent(Object.assign(new Event('deviceorientation'), { beta: 2, gamma: 1 }));
    expect(p.flat).toBe(true);
    target.dispatchEvent(Object.assign(new Event('deviceorientation'), { beta: 88, gamma: 1 }));
    expect(p.flat).toBe(false);
  });
});

describe('the session answers at the press from the kept second', () => {
  const frames = (c: unknown[]) => {
    const rec = c[1] as Uint8Array;
    return new DataView(rec.buffer, rec.byteOffset).getUint32(HEADER_AT.frames, true);
  };

  let grabbedAt: number[] = [];

  beforeEach(() => {
    vi.useFakeTimers();
    vi.resetAllMocks();
    api.venues.mockResolvedValue([{ id: 'lab', name: 'Lab' }]);
    api.venue.mockResolvedValue(VENUE);
    api.locate.mockResolvedValue(answer(false));
    cam.openCamera.mockResolvedValue({ getVideoTracks: () => [{ readyState: 'live' }] });
    cam.captureClip.mockImplementation((_v, _e, n: number) => Promise.resolve(clip(n, performance.now())));
    grabbedAt = [];
    cam.grabFrame.mockImplementation(() => {
      grabbedAt.push(performance.now());
      return Promise.resolve(frame());
    });
  });
  afterEach(() => vi.useRealTimers());

  it('the first press films its second; the next sends the kept one at once and films on after it', async () => {
    let allowed = true;
    const { s } = session({ standby: () => allowed });
    const seen: { kept: boolean; duty: number | null }[] = [];
    s.on('answer', (r) => seen.push({ kept: r.kept, duty: r.duty }));
    // the camera was closed: nothing kept yet; the server takes a second to answer
    api.locate.mockImplementationOnce(() => new Promise((r) => setTimeout(() => r(answer(false)), 1000)));
    const first = s.whereAmI();
    await vi.advanceTimersByTimeAsync(1000);
    await first;
    expect(cam.captureClip.mock.calls.map((c) => c[2])).toEqual([10, 20]);
    // while a press films and is answered, standing by grabs nothing
    expect(grabbedAt.filter((t) => t < 1000)).toEqual([]);
    await vi.advanceTimersByTimeAsync(1500);
    expect(cam.grabFrame.mock.calls.length).toBeGreaterThanOrEqual(14);
    await s.whereAmI();
    // no second filmed after the press: the kept ten sent, and the filming on follows them
    expect(cam.captureClip.mock.calls.map((c) => c[2])).toEqual([10, 20, 20]);
    expect(api.locate.mock.calls.map(frames)).toEqual([10, 10]);
    const follow = cam.captureClip.mock.calls[2][5];
    expect(follow.frames).toHaveLength(10);
    expect(performance.now() - follow.endMs).toBeLessThanOrEqual(100);
    expect(seen).toEqual([
      { kept: false, duty: null },
      { kept: true, duty: expect.closeTo(0.04, 2) },
    ]);
    // a press at once after it finds nothing kept (those frames were sent): it films its own
    await s.whereAmI();
    expect(cam.captureClip.mock.calls.map((c) => c[2])).toEqual([10, 20, 20, 10, 20]);
    // the user's setting off (or the page hidden): nothing kept, each press films its second
    allowed = false;
    await vi.advanceTimersByTimeAsync(1500);
    const grabs = cam.grabFrame.mock.calls.length;
    await vi.advanceTimersByTimeAsync(1500);
    expect(cam.grabFrame.mock.calls.length).toBe(grabs);
    await s.whereAmI();
    expect(cam.captureClip.mock.calls.map((c) => c[2])).toEqual([10, 20, 20, 10, 20, 10, 20]);
  });

  it('a tracked request (Keep telling me, guidance) takes the kept second as its first', async () => {
    const { s } = session({ standby: () => true });
    await s.whereAmI();
    await vi.advanceTimersByTimeAsync(1500);
    const r = await s.track({ session: 'abcdefgh' }, undefined, 2);
    expect(r!.kept).toBe(true);
    // the kept 10 and 10 more filmed after them: one 2 s clip
    expect(cam.captureClip.mock.calls.map((c) => c[2])).toEqual([10, 20, 10]);
    expect(api.locate.mock.calls.map(frames)).toEqual([10, 20]);
  });

  it('Keep telling me: a turn every interval + 1 s as ever, each answered from its kept second first', async () => {
    const { s } = session({ standby: () => true });
    await s.whereAmI(); // the camera opens
    await vi.advanceTimersByTimeAsync(1500);
    // filming takes its time from here on: 100 ms a frame
    cam.captureClip.mockImplementation(
      (_v, _e, n: number) => new Promise((r) => setTimeout(() => r(clip(n, performance.now())), 100 * n)),
    );
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0); // the first turn: the kept second, answered at once
    expect(api.locate).toHaveBeenCalledTimes(2);
    // the second turn 4 s later (the default interval, 3 s, + 1 s): the kept second + 1 s filmed
    // after it, asked at 5 s; the third turn at 8 s, asked at 9 s: a turn every 4 s, as ever
    await vi.advanceTimersByTimeAsync(4999);
    expect(api.locate).toHaveBeenCalledTimes(2);
    await vi.advanceTimersByTimeAsync(1);
    expect(api.locate).toHaveBeenCalledTimes(3);
    await vi.advanceTimersByTimeAsync(3999);
    expect(api.locate).toHaveBeenCalledTimes(3);
    await vi.advanceTimersByTimeAsync(1);
    expect(api.locate).toHaveBeenCalledTimes(4);
    expect(api.locate.mock.calls.map(frames)).toEqual([10, 10, 20, 20]);
    s.stopContinuous();
  });

  it('Keep telling me: a turn from a kept second that the server refused still waits interval + 1 s', async () => {
    const { s } = session({ standby: () => true });
    await s.whereAmI();
    await vi.advanceTimersByTimeAsync(1500);
    api.locate.mockRejectedValueOnce(new Error('the server failed'));
    s.toggleContinuous();
    await vi.advanceTimersByTimeAsync(0); // the kept second, refused at once
    expect(api.locate).toHaveBeenCalledTimes(2);
    await vi.advanceTimersByTimeAsync(3999);
    expect(api.locate).toHaveBeenCalledTimes(2);
    await vi.advanceTimersByTimeAsync(1);
    expect(api.locate).toHaveBeenCalledTimes(3);
    s.stopContinuous();
  });

  it('without standby asked for (tests, other pages) nothing is grabbed', async () => {
    const { s } = session();
    await s.whereAmI();
    await vi.advanceTimersByTimeAsync(3000);
    expect(cam.grabFrame).not.toHaveBeenCalled();
  });
});
