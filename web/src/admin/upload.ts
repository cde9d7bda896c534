/**
 * The arithmetic of a resumable video upload (admin API: POST .../videos, then PUT .../content in
 * pieces with Content-Range). Where an upload stands is always the server's `received`: the page
 * never counts bytes on its own, so a reload, a dropped connection or a second tab resumes exactly
 * where the server's file ends, never from zero and never sending a byte twice.
 */
import type { Video } from './types';

export const MIN_PIECE = 1024 * 1024;
export const MAX_PIECE = 64 * 1024 * 1024;
/** The smallest piece size `?piece=` may ask for. */
export const MIN_PIECE_OVERRIDE = 64 * 1024;

/**
 * Bytes per piece for a file of `size`: about 4 pieces, never under 1 MiB nor over 64 MiB, a
 * multiple of 64 KiB. Few pieces because each one costs a request (a few milliseconds of the
 * server's bookkeeping, the browser's setting up of a new upload, the pipe from the browser to the
 * workers drained and refilled): 16 pieces made the page's upload half as fast as curl's one PUT
 * on loopback (docs/benchlog.md, issue 11). Large pieces lose nothing: the server keeps every
 * byte of a piece that arrived, even when its request is cut off (pause, a dropped connection),
 * and the upload resumes from there; progress within a piece comes from the request's own upload
 * events. Over 64 MiB the pieces get more numerous (a 1 GB walk: 16), which costs little at that
 * size and keeps the server's `received` (what a reload or another tab sees) moving.
 */
export function pieceSize(size: number): number {
  const step = 64 * 1024;
  const want = Math.ceil(size / 4 / step) * step;
  return Math.min(MAX_PIECE, Math.max(MIN_PIECE, want));
}

/**
 * The piece size the page's address asks for with `?piece=BYTES` (before the '#'), for tests and
 * benchmarks only: to cut a small file into many pieces, or to compare piece sizes on one build.
 * Kept within 64 KiB..64 MiB; null (use pieceSize) when absent or not a number.
 */
export function pieceOverride(search: string): number | null {
  const v = new URLSearchParams(search).get('piece');
  if (v === null || !/^\d+$/.test(v.trim())) return null;
  return Math.min(MAX_PIECE, Math.max(MIN_PIECE_OVERRIDE, Number(v)));
}

/** Bytes [start, end) of the file. */
export interface Piece {
  start: number;
  end: number;
}

/** The next piece to send when the server has `received` bytes of `size`; null when all are in. */
export function nextPiece(received: number, size: number, piece: number): Piece | null {
  if (!(received >= 0) || !(size > 0) || !(piece > 0)) throw new RangeError('received, size and piece must be >= 0');
  if (received >= size) return null;
  return { start: received, end: Math.min(size, received + piece) };
}

/** The Content-Range header of a piece (last byte inclusive, as HTTP counts). */
export function contentRange(p: Piece, size: number): string {
  return `bytes ${p.start}-${p.end - 1}/${size}`;
}

/** The first byte a Content-Range header names (what the server was asked to take from). */
export function rangeStart(header: string): number | null {
  const m = /^bytes (\d+)-(\d+)\/(\d+)$/.exec(header.trim());
  return m ? Number(m[1]) : null;
}

/**
 * The server's name for a file: what its video names allow (letters, digits, '-', '_', dots between
 * them), so "Walk 1 (north).MP4" becomes "Walk-1-north.MP4". The same file always gets the same
 * name, which is how a re-selected file finds its unfinished upload.
 */
export function videoName(fileName: string): string {
  const parts = fileName
    .normalize('NFKD')
    .replace(/[\u0300-\u036f]/g, '')
    .split('.')
    .map((p) =>
      p
        .replace(/[^A-Za-z0-9_-]+/g, '-')
        .replace(/^-+|-+$/g, '')
        .replace(/-{2,}/g, '-'),
    )
    .filter((p) => p.length > 0);
  let name = parts.join('.').replace(/^[-_]+/, '');
  if (!name) name = 'video';
  if (name.endsWith('.part')) name += '.video';
  return name.slice(0, 128).replace(/[.]+$/, '');
}

/**
 * The server's unfinished upload that a chosen file continues: same name and same size, still
 * uploading. (The page keeps which File belongs to which upload in memory only; after a reload
 * the admin chooses the file again and this finds where it stands.)
 */
export function matchUpload(file: { name: string; size: number }, videos: readonly Video[]): Video | undefined {
  const name = videoName(file.name);
  return videos.find((v) => v.name === name && v.size === file.size && v.status === 'uploading');
}

/**
 * Upload speed over a sliding window (default 5 s) of (time, bytes sent so far) samples: steady
 * enough to read, quick to follow a change of network. Times in milliseconds.
 */
export class RateMeter {
  private samples: [number, number][] = [];
  constructor(private windowMs = 5000) {}

  /** `total`: bytes of this upload the server holds or is being sent, at time `now`. */
  add(total: number, now: number): void {
    const last = this.samples[this.samples.length - 1];
    if (last && (total < last[1] || now < last[0])) this.samples = []; // went back: start over
    this.samples.push([now, total]);
    while (this.samples.length > 2 && now - this.samples[1][0] >= this.windowMs) this.samples.shift();
  }

  /** Bytes per second; null before there is a second of data to go on. */
  speed(): number | null {
    if (this.samples.length < 2) return null;
    const [t0, b0] = this.samples[0];
    const [t1, b1] = this.samples[this.samples.length - 1];
    if (t1 - t0 < 1000) return null;
    return ((b1 - b0) * 1000) / (t1 - t0);
  }

  /** Seconds left for `remaining` bytes at the current speed; null when unknown or stalled. */
  eta(remaining: number): number | null {
    const v = this.speed();
    if (v === null || v <= 0) return remaining <= 0 ? 0 : null;
    return Math.max(0, remaining) / v;
  }

  reset(): void {
    this.samples = [];
  }
}

/** Why a chosen file cannot go to a lens, or null when it fits (or could not be checked here). */
export function lensMismatch(
  probe: { width: number; height: number } | null,
  imageSize: readonly [number, number] | undefined,
  lensName: string,
): string | null {
  if (!probe || !imageSize) return null;
  if (probe.width === imageSize[0] && probe.height === imageSize[1]) return null;
  return `its frames are ${probe.width}x${probe.height} but lens ${lensName} is for ${imageSize[0]}x${imageSize[1]}`;
}
