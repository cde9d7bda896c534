/**
 * The camera: the rear camera at the lens profile's resolution, and clips of frames (~1 s; 3 s when
 * a press's first second was not enough; 2 s a request of a guided walk or of "Keep telling me"
 * after their first, 1 s) handed to the feature worker as ImageBitmaps (frames never leave the
 * phone: only their features do).
 */
import type { Lens } from '../shared/lens';
import type { ExtractorClient, FrameResult } from './bridge';

export class CameraProblem extends Error {
  constructor(
    readonly kind: 'denied' | 'none' | 'insecure' | 'busy' | 'lens',
    message: string,
  ) {
    super(message);
  }
}

export const MESSAGES = {
  denied:
    'The camera is blocked for omninav. Allow the camera in the browser’s site settings, then press Where am I? again.',
  none: 'No camera was found. omninav needs the phone’s rear camera with the panoramic lens attached.',
  insecure: 'The camera works only on a secure page. Open omninav with its https address.',
  busy: 'The camera is in use by another app. Close it, then press Where am I? again.',
};

export async function openCamera(video: HTMLVideoElement, lens: Lens): Promise<MediaStream> {
  if (!navigator.mediaDevices?.getUserMedia) throw new CameraProblem('insecure', MESSAGES.insecure);
  const [w, h] = lens.image_size;
  let stream: MediaStream;
  try {
    stream = await navigator.mediaDevices.getUserMedia({
      audio: false,
      video: {
        facingMode: { ideal: 'environment' },
        width: { ideal: w },
        height: { ideal: h },
        frameRate: { ideal: 30 },
      },
    });
  } catch (e) {
    const name = (e as DOMException).name;
    if (name === 'NotAllowedError' || name === 'SecurityError') throw new CameraProblem('denied', MESSAGES.denied);
    if (name === 'NotFoundError' || name === 'OverconstrainedError') throw new CameraProblem('none', MESSAGES.none);
    if (name === 'NotReadableError' || name === 'AbortError') throw new CameraProblem('busy', MESSAGES.busy);
    throw new CameraProblem('none', `${MESSAGES.none} (${name})`);
  }
  video.srcObject = stream;
  await video.play();
  if (!video.videoWidth) await new Promise((r) => video.addEventListener('loadedmetadata', r, { once: true }));
  return stream;
}

/**
 * Why the camera's picture cannot be the lens profile's, or null. Another resolution of the same
 * shape is scaled; another shape means another camera mode or lens than the profile's.
 */
export function lensMismatch(width: number, height: number, lens: Lens, lensName: string): string | null {
  const [w, h] = lens.image_size;
  if (!width || !height) return 'The camera gives no picture. Press Where am I? again.';
  if (Math.abs(width / height - w / h) > 0.02)
    return `The camera picture is ${width} by ${height}, but the lens profile “${lensName}” is for ${w} by ${h} pictures. Attach the lens this venue was set up with, or choose the right lens profile in Settings.`;
  return null;
}

export interface Clip {
  frames: FrameResult[];
  fps: number;
  /** performance.now() at the first and the last frame grabbed. */
  startMs: number;
  endMs: number;
}

/** A clip's frame rate: its frames spread evenly from its first to its last (10 for one frame). */
export function clipFps(frames: number, startMs: number, endMs: number): number {
  const span = (endMs - startMs) / 1000;
  return frames > 1 && span > 0 ? (frames - 1) / span : 10;
}

/** One frame grabbed from the camera now and extracted in the worker (the bitmap goes to it). */
export function grabFrame(video: HTMLVideoElement, ext: ExtractorClient): Promise<FrameResult> {
  return createImageBitmap(video).then((bm) => ext.extract(bm));
}

/**
 * Grab `n` frames `intervalMs` apart and extract each as it comes (extraction overlaps capture).
 * `follow`: a clip these frames continue, the first of them one interval after its last. `stop()`
 * true ends the grabbing early: the clip then holds the frames grabbed so far.
 */
export async function captureClip(
  video: HTMLVideoElement,
  ext: ExtractorClient,
  n: number,
  intervalMs: number,
  stop: () => boolean = () => false,
  follow?: Clip,
): Promise<Clip> {
  const jobs: Promise<FrameResult>[] = [];
  const times: number[] = [];
  // following a clip: the next frame is due one interval after the last one grabbed; when the
  // phone was late (a slow extraction), the frames after it stay an interval apart rather than
  // being grabbed back to back to catch up (the clip's one fps then spreads the delay evenly)
  let due = follow ? follow.endMs + intervalMs : null;
  for (let i = 0; i < n; i++) {
    if (due !== null) {
      const wait = due - performance.now();
      if (wait > 0) await new Promise((r) => setTimeout(r, wait));
    } else if (i) await new Promise((r) => setTimeout(r, intervalMs - ((performance.now() - times[0]) % intervalMs)));
    if (stop()) break;
    times.push(performance.now());
    if (due !== null) due = Math.max(due, times[times.length - 1]) + intervalMs;
    jobs.push(grabFrame(video, ext));
  }
  const frames = await Promise.all(jobs);
  const [startMs, endMs] = [times[0] ?? performance.now(), times[times.length - 1] ?? performance.now()];
  return { frames, fps: clipFps(frames.length, startMs, endMs), startMs, endMs };
}

/** Two clips one after the other as one (the second one filmed to `follow` the first). */
export function joinClips(a: Clip, b: Clip): Clip {
  const frames = [...a.frames, ...b.frames];
  return { frames, fps: clipFps(frames.length, a.startMs, b.endMs), startMs: a.startMs, endMs: b.endMs };
}
