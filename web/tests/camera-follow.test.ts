// Filming on after a first second (issue 13): the frames that follow a clip are an interval apart,
// also when the phone was late for the first of them (no back-to-back burst of near-equal frames
// whose times the clip's one frame rate would then misstate).
import { afterEach, beforeEach, describe, expect, it, vi } from 'vitest';
import { captureClip, joinClips, type Clip } from '../src/client/camera';
import type { ExtractorClient } from '../src/client/bridge';

const frame = () => ({ mag: new Uint16Array(1), phase: new Int16Array(1), ms: 1 });
const ext = { extract: vi.fn(async () => frame()) } as unknown as ExtractorClient;
const video = {} as HTMLVideoElement;

describe('captureClip following a clip', () => {
  beforeEach(() => {
    vi.useFakeTimers({ toFake: ['setTimeout', 'performance'] });
    vi.stubGlobal('createImageBitmap', async () => ({}));
  });
  afterEach(() => {
    vi.useRealTimers();
    vi.unstubAllGlobals();
  });

  async function follow(lateMs: number): Promise<{ first: Clip; rest: Clip }> {
    const now = performance.now();
    const first: Clip = {
      frames: Array.from({ length: 10 }, frame),
      fps: 10,
      startMs: now - 900 - lateMs,
      endMs: now - lateMs,
    };
    const p = captureClip(video, ext, 20, 100, () => false, first);
    await vi.runAllTimersAsync();
    return { first, rest: await p };
  }

  it('on time: the 20 frames continue the grid, and the joined 3 s clip is 10 fps', async () => {
    const { first, rest } = await follow(0);
    expect(rest.frames).toHaveLength(20);
    expect(rest.startMs - first.endMs).toBeCloseTo(100, 0);
    expect(joinClips(first, rest).fps).toBeCloseTo(10, 3);
  });

  it('late by 450 ms: the frames still come 100 ms apart (no burst), the delay spread over the clip', async () => {
    const { first, rest } = await follow(450);
    expect(rest.frames).toHaveLength(20);
    expect(rest.endMs - rest.startMs).toBeCloseTo(1900, 0); // 19 intervals, not 19 frames at once
    const joined = joinClips(first, rest);
    expect(joined.frames).toHaveLength(30);
    expect(joined.fps).toBeGreaterThan(8.5); // 29 intervals over 3.25 s
    expect(joined.fps).toBeLessThan(10);
  });

  it('stopped: the clip holds the frames grabbed so far', async () => {
    const now = performance.now();
    const first: Clip = { frames: [frame()], fps: 10, startMs: now, endMs: now };
    let n = 0;
    const p = captureClip(video, ext, 20, 100, () => ++n > 5, first);
    await vi.runAllTimersAsync();
    expect((await p).frames).toHaveLength(5);
  });
});
