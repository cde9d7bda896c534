/**
 * The camera: the rear camera at the lens profile's resolution, and ~1 s clips of frames handed to
 * the feature worker as ImageBitmaps (frames never leave the phone: only their features do).
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
}

/** Grab `n` frames `intervalMs` apart and extract each as it comes (extraction overlaps capture). */
export async function captureClip(
  video: HTMLVideoElement,
  ext: ExtractorClient,
  n: number,
  intervalMs: number,
): Promise<Clip> {
  const jobs: Promise<FrameResult>[] = [];
  const times: number[] = [];
  for (let i = 0; i < n; i++) {
    if (i) await new Promise((r) => setTimeout(r, intervalMs - ((performance.now() - times[0]) % intervalMs)));
    times.push(performance.now());
    jobs.push(createImageBitmap(video).then((bm) => ext.extract(bm)));
  }
  const frames = await Promise.all(jobs);
  const span = (times[times.length - 1] - times[0]) / 1000;
  return { frames, fps: n > 1 && span > 0 ? (n - 1) / span : 10 };
}
