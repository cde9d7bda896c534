// Reading a video's frame size and duration from its MP4 header, as the admin page does before an
// upload: on real files written by OpenCV (MPEG-4 Part 2, which Chromium cannot decode), moov last.
import { execFileSync } from 'node:child_process';
import { mkdtempSync, readFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, resolve } from 'node:path';
import { describe, expect, it } from 'vitest';
import { probeMp4 } from '../src/admin/probe';
import { ROOT } from './global-setup';

/** An MP4 of `frames` frames of w x h at `fps`, written by the engine's OpenCV. */
function mp4(w: number, h: number, frames: number, fps: number): Uint8Array {
  const out = join(mkdtempSync(join(tmpdir(), 'probe-')), 'v.mp4');
  const py = `
import cv2, numpy as np, sys
vw = cv2.VideoWriter(sys.argv[1], cv2.VideoWriter.fourcc(*"mp4v"), ${fps}, (${w}, ${h}))
for i in range(${frames}):
    vw.write(np.full((${h}, ${w}, 3), i * 10 % 255, np.uint8))
vw.release()
`;
  execFileSync(resolve(ROOT, '.venv/bin/python'), ['-c', py, out]);
  return new Uint8Array(readFileSync(out));
}

const reader = (b: Uint8Array) => {
  const reads: [number, number][] = [];
  const read = async (a: number, e: number) => {
    reads.push([a, e]);
    return b.slice(a, e);
  };
  return { read, reads };
};

describe('the MP4 header', () => {
  it('names the frame size and duration of a file OpenCV wrote', async () => {
    const b = mp4(320, 240, 25, 10);
    const { read, reads } = reader(b);
    const p = await probeMp4(read, b.length);
    expect(p).not.toBeNull();
    expect([p?.width, p?.height, p?.via]).toEqual([320, 240, 'mp4']);
    expect(p?.duration).toBeCloseTo(2.5, 1);
    // only box headers and the moov box were read, not the frames
    const bytes = reads.reduce((n, [a, e]) => n + (e - a), 0);
    expect(bytes).toBeLessThan(b.length);
  });
  it('a non-square frame keeps its orientation', async () => {
    const b = mp4(96, 160, 5, 5);
    const p = await probeMp4(reader(b).read, b.length);
    expect([p?.width, p?.height]).toEqual([96, 160]);
  });
  it('a file that is not an MP4 is not guessed at', async () => {
    const junk = new Uint8Array(4096).map((_, i) => (i * 7919) % 251);
    expect(await probeMp4(reader(junk).read, junk.length)).toBeNull();
    const text = new TextEncoder().encode('YUV4MPEG2 W64 H48 F10:1\nFRAME\n');
    expect(await probeMp4(reader(text).read, text.length)).toBeNull();
  });
  it('a truncated upload source (moov missing) gives no answer', async () => {
    const b = mp4(64, 48, 10, 10);
    const cut = b.slice(0, Math.floor(b.length / 2));
    expect(await probeMp4(reader(cut).read, cut.length)).toBeNull();
  });
});
