/**
 * A chosen video file checked here, before any byte is sent: its frame size and duration, so that a
 * file the lens cannot read is refused at once instead of after a long upload. The browser's own
 * <video> element is asked first; where it cannot decode the codec (HEVC from a phone on Linux,
 * MPEG-4 Part 2 from OpenCV), the MP4/QuickTime header is read instead (its boxes name the size and
 * duration without decoding anything; only the header's few kilobytes are read, wherever they are).
 */

export interface VideoProbe {
  width: number;
  height: number;
  /** Seconds, when known. */
  duration: number | null;
  /** How it was found: the browser decoded it, or the container header says so. */
  via: 'video' | 'mp4';
}

/** Reads bytes [start, end) of the file. */
export type ReadRange = (start: number, end: number) => Promise<Uint8Array>;

const MAX_MOOV = 32 * 1024 * 1024;

const u32 = (b: Uint8Array, o: number): number => ((b[o] << 24) | (b[o + 1] << 16) | (b[o + 2] << 8) | b[o + 3]) >>> 0;
const u64 = (b: Uint8Array, o: number): number => u32(b, o) * 2 ** 32 + u32(b, o + 4);
const u16 = (b: Uint8Array, o: number): number => (b[o] << 8) | b[o + 1];
const type4 = (b: Uint8Array, o: number): string => String.fromCharCode(b[o], b[o + 1], b[o + 2], b[o + 3]);

interface Box {
  type: string;
  /** Payload start and end (after the header), within the buffer. */
  start: number;
  end: number;
}

/** The child boxes of b[start, end). */
function boxes(b: Uint8Array, start: number, end: number): Box[] {
  const out: Box[] = [];
  let o = start;
  while (o + 8 <= end) {
    let size = u32(b, o);
    let head = 8;
    if (size === 1) {
      if (o + 16 > end) break;
      size = u64(b, o + 8);
      head = 16;
    } else if (size === 0) size = end - o;
    if (size < head || o + size > end) break;
    out.push({ type: type4(b, o + 4), start: o + head, end: o + size });
    o += size;
  }
  return out;
}

const child = (b: Uint8Array, box: Box, type: string): Box | undefined =>
  boxes(b, box.start, box.end).find((c) => c.type === type);

/** Width, height and duration from a `moov` box's payload (the first video track). */
export function parseMoov(b: Uint8Array, start = 0, end = b.length): Omit<VideoProbe, 'via'> | null {
  const top = boxes(b, start, end);
  let duration: number | null = null;
  const mvhd = top.find((x) => x.type === 'mvhd');
  if (mvhd) {
    const v = b[mvhd.start];
    const scale = v === 1 ? u32(b, mvhd.start + 20) : u32(b, mvhd.start + 12);
    const dur = v === 1 ? u64(b, mvhd.start + 24) : u32(b, mvhd.start + 16);
    if (scale > 0) duration = dur / scale;
  }
  for (const trak of top.filter((x) => x.type === 'trak')) {
    const mdia = child(b, trak, 'mdia');
    const hdlr = mdia && child(b, mdia, 'hdlr');
    if (!hdlr || type4(b, hdlr.start + 8) !== 'vide') continue;
    const tkhd = child(b, trak, 'tkhd');
    let width = 0;
    let height = 0;
    let quarterTurn = false;
    if (tkhd) {
      const v = b[tkhd.start];
      const m = tkhd.start + (v === 1 ? 52 : 40); // the matrix, after the times, ids and volume
      width = u32(b, m + 36) / 65536;
      height = u32(b, m + 40) / 65536;
      quarterTurn = u32(b, m) === 0 && u32(b, m + 4) !== 0; // a = 0, b = ±1: rotated 90° or 270°
    }
    // the sample entry's coded size is what a decoder delivers; tkhd is the display size
    const minf = mdia && child(b, mdia, 'minf');
    const stbl = minf && child(b, minf, 'stbl');
    const sd = stbl && child(b, stbl, 'stsd');
    if (sd && sd.start + 8 + 36 <= sd.end) {
      const entry = sd.start + 8; // after version, flags and the entry count
      const w = u16(b, entry + 8 + 24);
      const h = u16(b, entry + 8 + 26);
      if (w > 0 && h > 0) {
        width = quarterTurn ? h : w;
        height = quarterTurn ? w : h;
      }
    }
    if (width > 0 && height > 0) return { width: Math.round(width), height: Math.round(height), duration };
  }
  return null;
}

/** The size and duration an MP4/MOV file's header states, reading only its boxes' headers and `moov`. */
export async function probeMp4(read: ReadRange, size: number): Promise<VideoProbe | null> {
  let o = 0;
  for (let n = 0; o + 8 <= size && n < 1000; n++) {
    const h = await read(o, Math.min(size, o + 16));
    if (h.length < 8) return null;
    let len = u32(h, 0);
    let head = 8;
    if (len === 1) {
      if (h.length < 16) return null;
      len = u64(h, 8);
      head = 16;
    } else if (len === 0) len = size - o;
    const type = type4(h, 4);
    if (!/^[\x20-\x7e]{4}$/.test(type) || len < head) return null; // not an ISO media file
    if (type === 'moov') {
      if (len > MAX_MOOV) return null;
      const moov = await read(o + head, Math.min(size, o + len));
      const got = parseMoov(moov);
      return got && { ...got, via: 'mp4' };
    }
    o += len;
  }
  return null;
}

/** The browser's <video> reading the file's metadata (null when it cannot, or within `timeoutMs`). */
export function probeVideoElement(file: Blob, timeoutMs = 4000): Promise<VideoProbe | null> {
  return new Promise((resolve) => {
    const url = URL.createObjectURL(file);
    const v = document.createElement('video');
    v.preload = 'metadata';
    v.muted = true;
    const done = (r: VideoProbe | null): void => {
      clearTimeout(timer);
      v.removeAttribute('src');
      v.load();
      URL.revokeObjectURL(url);
      resolve(r);
    };
    const timer = setTimeout(() => done(null), timeoutMs);
    v.addEventListener('loadedmetadata', () =>
      done(
        v.videoWidth > 0
          ? {
              width: v.videoWidth,
              height: v.videoHeight,
              duration: Number.isFinite(v.duration) ? v.duration : null,
              via: 'video',
            }
          : null,
      ),
    );
    v.addEventListener('error', () => done(null));
    v.src = url;
  });
}

/** The file's frame size and duration as far as this browser can tell; null when it cannot. */
export async function probeFile(file: File): Promise<VideoProbe | null> {
  const fromVideo = await probeVideoElement(file);
  if (fromVideo) return fromVideo;
  try {
    return await probeMp4(async (a, b) => new Uint8Array(await file.slice(a, b).arrayBuffer()), file.size);
  } catch {
    return null;
  }
}
