// The arithmetic of the admin page's resumable upload and of its speed and time left.
import { afterEach, describe, expect, it, vi } from 'vitest';
import { formatBytes, formatDuration, formatTime } from '../src/admin/format';
import type { Video } from '../src/admin/types';
import { videoDoc } from './admin-video';
import {
  MAX_PIECE,
  MIN_PIECE,
  MIN_PIECE_OVERRIDE,
  RateMeter,
  contentRange,
  lensMismatch,
  matchUpload,
  nextPiece,
  pieceOverride,
  pieceSize,
  rangeStart,
  videoName,
} from '../src/admin/upload';

const MB = 1024 * 1024;

/** Every piece an upload sends from `received` on, as the server's `received` moves. */
function plan(received: number, size: number): [number, number][] {
  const out: [number, number][] = [];
  const piece = pieceSize(size);
  for (let p = nextPiece(received, size, piece); p; p = nextPiece(p.end, size, piece)) out.push([p.start, p.end]);
  return out;
}

const video = videoDoc;

describe('pieces', () => {
  it('cover the file once, in order, each within 1 MiB..64 MiB', () => {
    for (const size of [1, 1000, MIN_PIECE, 3 * MB + 17, 100 * MB, 3000 * MB]) {
      const ps = plan(0, size);
      expect(ps[0][0]).toBe(0);
      expect(ps[ps.length - 1][1]).toBe(size);
      for (let i = 1; i < ps.length; i++) expect(ps[i][0]).toBe(ps[i - 1][1]);
      for (const [a, b] of ps.slice(0, -1)) expect(b - a).toBeGreaterThanOrEqual(MIN_PIECE);
      for (const [a, b] of ps) expect(b - a).toBeLessThanOrEqual(MAX_PIECE);
      for (const [a, b] of ps.slice(0, -1)) expect((b - a) % (64 * 1024)).toBe(0);
    }
  });
  it('are about 4 for a middling file, 64 MiB for a big one, 1 MiB for a small one', () => {
    expect(MIN_PIECE).toBe(MB);
    expect(MAX_PIECE).toBe(64 * MB);
    expect(plan(0, 64 * MB).length).toBe(4);
    expect(plan(0, 95_252_897).length).toBe(4); // the benchmark's walk (docs/benchlog.md)
    expect(plan(0, 256 * MB).length).toBe(4);
    expect(plan(0, 1000 * MB).length).toBe(16);
    expect(pieceSize(4000 * MB)).toBe(MAX_PIECE);
    expect(pieceSize(10 * 1024)).toBe(MIN_PIECE);
    expect(plan(0, 2_250_000).length).toBe(3); // the e2e walk: cut after two pieces, one is left
  });
  it('may be set by ?piece=BYTES (tests and benchmarks), within 64 KiB..64 MiB', () => {
    expect(pieceOverride('')).toBeNull();
    expect(pieceOverride('?other=1')).toBeNull();
    expect(pieceOverride('?piece=')).toBeNull();
    expect(pieceOverride('?piece=lots')).toBeNull();
    expect(pieceOverride('?piece=-5')).toBeNull();
    expect(pieceOverride('?piece=5963776')).toBe(5963776);
    expect(pieceOverride('?x=1&piece=300000')).toBe(300000);
    expect(pieceOverride('?piece=1')).toBe(MIN_PIECE_OVERRIDE);
    expect(pieceOverride(`?piece=${2 ** 40}`)).toBe(MAX_PIECE);
  });
  it("resume at the server's `received`: no byte before it is sent again, none is skipped", () => {
    const size = 10 * MB + 3;
    const received = 3 * MB + 12345; // a piece cut in the middle: the server kept what arrived
    const ps = plan(received, size);
    expect(ps[0][0]).toBe(received);
    expect(ps[ps.length - 1][1]).toBe(size);
    const sent = ps.reduce((n, [a, b]) => n + (b - a), 0);
    expect(sent).toBe(size - received);
  });
  it('nothing to send once all bytes are in', () => {
    expect(nextPiece(500, 500, MIN_PIECE)).toBeNull();
  });
  it('name their bytes as HTTP counts them (last byte inclusive)', () => {
    expect(contentRange({ start: 0, end: 262144 }, 1000000)).toBe('bytes 0-262143/1000000');
    expect(contentRange({ start: 999999, end: 1000000 }, 1000000)).toBe('bytes 999999-999999/1000000');
    expect(rangeStart('bytes 262144-524287/1000000')).toBe(262144);
    expect(rangeStart('nonsense')).toBeNull();
  });
});

describe('a re-selected file', () => {
  it('gets the name the server allows, the same every time', () => {
    expect(videoName('Walk 1 (north).MP4')).toBe('Walk-1-north.MP4');
    expect(videoName('walk.mp4')).toBe('walk.mp4');
    expect(videoName('Café été.mov')).toBe('Cafe-ete.mov');
    expect(videoName('.hidden..mp4')).toBe('hidden.mp4');
    expect(videoName('x.part')).toBe('x.part.video');
    expect(videoName('???')).toBe('video');
    expect(videoName('a'.repeat(300) + '.mp4').length).toBeLessThanOrEqual(128);
    expect(videoName('_walk.mp4')).toBe('walk.mp4');
  });
  it('finds its unfinished upload by name and size, not a finished one or another size', () => {
    const vids = [
      video({ name: 'walk.mp4', size: 999, received: 10 }),
      video({ name: 'walk.mp4', size: 1000, received: 400 }),
      video({ name: 'other.mp4', size: 1000, status: 'ready', received: 1000 }),
    ];
    expect(matchUpload({ name: 'walk.mp4', size: 1000 }, vids)?.received).toBe(400);
    expect(matchUpload({ name: 'other.mp4', size: 1000 }, vids)).toBeUndefined();
    expect(matchUpload({ name: 'walk.mp4', size: 5 }, vids)).toBeUndefined();
  });
});

describe('speed and time left', () => {
  it('are unknown for the first second, then bytes over the window', () => {
    const m = new RateMeter(5000);
    m.add(0, 0);
    m.add(500_000, 500);
    expect(m.speed()).toBeNull();
    expect(m.eta(1000)).toBeNull();
    m.add(2_000_000, 2000);
    expect(m.speed()).toBe(1_000_000);
    expect(m.eta(3_000_000)).toBe(3);
  });
  it('follow a change of speed within the window', () => {
    const m = new RateMeter(5000);
    for (let t = 0; t <= 10_000; t += 500) m.add(t * 1000, t); // 1 MB/s for 10 s
    for (let t = 10_500; t <= 20_000; t += 500) m.add(10_000_000 + (t - 10_000) * 100, t); // then 100 kB/s
    expect(m.speed()).toBeCloseTo(100_000, -3);
  });
  it('start again when the count goes back (a refused file starts from 0)', () => {
    const m = new RateMeter(5000);
    m.add(0, 0);
    m.add(5_000_000, 2000);
    m.add(0, 2500);
    expect(m.speed()).toBeNull();
  });
  it('a stalled upload has no time left to give; a finished one has none left', () => {
    const m = new RateMeter(5000);
    m.add(100, 0);
    m.add(100, 3000);
    expect(m.speed()).toBe(0);
    expect(m.eta(50)).toBeNull();
    expect(m.eta(0)).toBe(0);
  });
});

describe('words', () => {
  it('sizes, durations and video times', () => {
    expect(formatBytes(999)).toBe('999 B');
    expect(formatBytes(1_234_567)).toBe('1.2 MB');
    expect(formatBytes(250_000_000)).toBe('250 MB');
    expect(formatDuration(44.6)).toBe('45 s');
    expect(formatDuration(200)).toBe('3 min 20 s');
    expect(formatDuration(120)).toBe('2 min');
    expect(formatDuration(7500)).toBe('2 h 5 min');
    expect(formatTime(62.46)).toBe('1:02.5');
    expect(formatTime(0)).toBe('0:00.0');
    expect(formatTime(59.96)).toBe('1:00.0');
  });
  it('a file that does not fit the lens says both sizes; an unknown size is left to the server', () => {
    expect(lensMismatch({ width: 640, height: 480 }, [960, 960], 'donut')).toBe(
      'its frames are 640x480 but lens donut is for 960x960',
    );
    expect(lensMismatch({ width: 960, height: 960 }, [960, 960], 'donut')).toBeNull();
    expect(lensMismatch(null, [960, 960], 'donut')).toBeNull();
  });
});

describe('finding the turns and stops after an upload', () => {
  afterEach(() => vi.unstubAllGlobals());
  it('tells a finished job only with the video that carries what it found (never "0 found" before it)', async () => {
    vi.stubGlobal('addEventListener', () => undefined); // (the page's uploads listen for `online`)
    const { Upload } = await import('../src/admin/uploader');
    const found = { suggestions: [{ t: 1 }, { t: 2 }, { t: 3 }] } as unknown as Video['suggestions'];
    const job = (state: string) => ({ id: 'j1', kind: 'suggest', state, frames_done: 5, frames_total: 5 });
    const api = {
      post: async () => job('running'),
      get: async (path: string) => (path.startsWith('/api/admin/jobs/') ? job('done') : video({ suggestions: found })),
      stream: async (_path: string, on: (e: { event: string; data: string }) => void) =>
        on({ event: 'job', data: JSON.stringify(job('done')) }),
    };
    const seen: [string | undefined, number | undefined][] = [];
    const u = new Upload(
      new File([new Uint8Array(10)], 'walk.mp4'),
      { venue: 'v', floor: '1', lens: 'donut', role: 'model' } as never,
      api as never,
      (x) => seen.push([x.suggest?.state, x.video?.suggestions?.suggestions.length]),
    );
    await u.findTurns();
    expect(seen.filter(([state]) => state === 'done')).toEqual([['done', 3]]);
  });
});

describe("a video's state in the table", () => {
  afterEach(() => vi.unstubAllGlobals());
  it('an evaluation walk is never "not modelled yet": it is scored, not modelled', async () => {
    vi.stubGlobal('addEventListener', () => undefined);
    const { videoStatus } = await import('../src/admin/screens/videos');
    const ready = { status: 'ready', received: 1000, width: 960, height: 720, duration_s: 20 } as const;
    expect(videoStatus(video({ ...ready, role: 'model' }))).toBe('uploaded, not modelled yet; 960x720, 0:20.0 long');
    expect(videoStatus(video({ ...ready, role: 'evaluation' }))).toBe(
      'uploaded, to score the venue with (evaluation walks are not modelled); 960x720, 0:20.0 long',
    );
    expect(videoStatus(video({ ...ready, role: 'model', status: 'modelled', frames: 200 }))).toMatch(
      /^modelled \(200 frames\)/,
    );
  });
});
