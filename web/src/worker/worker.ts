/// <reference lib="webworker" />
/**
 * The feature worker: owns opencv.js (WebAssembly) and turns camera frames into spectra, off the
 * main thread so that the page, speech and the screen reader never wait on image work. It also
 * checks the lens: finds the donut's ring in a few frames and corrects the profile it extracts with.
 */
import cvModule from '@techstark/opencv-js';
import { Extractor, readyCv, type Cv } from './extract';
import { findRingFrame, fitLens, lookOf, medianRing, type RingCv } from './ring';
import { LocalDetector, type LocalCv } from './local';
import type { Lens } from '../shared/lens';
import type { FeatureSettings } from '../shared/settings';
import type { FromWorker, LensCheck, ToWorker } from '../shared/protocol';

declare const self: DedicatedWorkerGlobalScope;

// opencv.js compiles its WebAssembly once, on the first lens: one memoised promise
let cvReady: Promise<Cv> | null = null;
const loadCv = (): Promise<Cv> => (cvReady ??= readyCv(cvModule));
let cv: Cv | null = null;
let ext: Extractor | null = null;
/** The profile as the page gave it; the extractor's may be its correction for a re-clipped lens. */
let base: { lens: Lens; settings: FeatureSettings } | null = null;
let canvas: OffscreenCanvas | null = null;
let ctx: OffscreenCanvasRenderingContext2D | null = null;
/**
 * Local features (worker/local.ts), once the page asked for them (`prepare`): the ORB keypoints
 * wanted (0: none, and no frame is kept), the detector for the profile in use, and the pixels of
 * the last KEPT_FRAMES frames extracted by their request's id: the standby ring's last frame may be
 * followed by the frames still in flight when it was taken (standby.ts's IN_FLIGHT, 2).
 */
let wanted = 0;
let detector: LocalDetector | null = null;
const recent = new Map<number, Uint8ClampedArray>();
const KEPT_FRAMES = 3;

/** How far profile `b` is from `a`, in pixels: the centre or a radius, whichever moved most (Infinity: another model). */
function profileMoved(a: Lens, b: Lens): number {
  if (a.model !== 'catadioptric' || b.model !== 'catadioptric') return a.model === b.model ? 0 : Infinity;
  const centre = Math.hypot(a.center[0] - b.center[0], a.center[1] - b.center[1]);
  return Math.max(centre, Math.abs(a.r_inner - b.r_inner), Math.abs(a.r_outer - b.r_outer));
}

function post(m: FromWorker, transfer: Transferable[] = []): void {
  self.postMessage(m, transfer);
}

async function init(m: Extract<ToWorker, { type: 'init' }>): Promise<void> {
  const t0 = performance.now();
  cv = await loadCv();
  ext?.delete();
  ext = new Extractor(cv, m.lens, m.settings);
  base = { lens: m.lens, settings: m.settings };
  recent.clear();
  if (wanted) tryDetector(); // keypoints through the new profile too
  const [w, h] = m.lens.image_size;
  canvas = new OffscreenCanvas(w, h);
  // willReadFrequently keeps the canvas in CPU memory: getImageData every frame is then cheap
  ctx = canvas.getContext('2d', { willReadFrequently: true, alpha: false });
  post({ type: 'ready', id: m.id, loadMs: performance.now() - t0 });
}

/** A frame's pixels at the lens's calibrated size (a camera at another resolution of the same shape is scaled). */
function pixels(bitmap: ImageBitmap): Uint8ClampedArray {
  if (!ext || !ctx || !canvas) throw new Error('the feature worker was not initialised with a lens');
  ctx.drawImage(bitmap, 0, 0, canvas.width, canvas.height);
  bitmap.close();
  return ctx.getImageData(0, 0, canvas.width, canvas.height).data;
}

function frame(m: Extract<ToWorker, { type: 'frame' }>): void {
  const start = performance.now();
  try {
    const px = pixels(m.bitmap);
    const out = ext!.extract(px, m.keep);
    if (wanted) {
      recent.set(m.id, px); // the canvas's fresh copy: nothing is copied to keep it
      if (recent.size > KEPT_FRAMES) recent.delete(recent.keys().next().value!);
    }
    const look = lookOf(px, canvas!.width, canvas!.height, ext!.lens);
    const { mag, phase } = out.spectrum;
    const transfer: Transferable[] = [mag.buffer, phase.buffer];
    if (out.pano) transfer.push(out.pano.buffer);
    if (out.curves) transfer.push(out.curves.buffer);
    post(
      {
        type: 'features',
        id: m.id,
        mag,
        phase,
        ms: performance.now() - start,
        look,
        pano: out.pano,
        curves: out.curves,
      },
      transfer,
    );
  } catch (e) {
    post({ type: 'error', id: m.id, message: e instanceof Error ? e.message : String(e) });
  }
}

/**
 * The lens check: the ring in each frame, their median against the page's profile, and the
 * extractor rebuilt on the corrected profile (or back on the page's when the ring is where it says).
 */
function lens(m: Extract<ToWorker, { type: 'lens' }>): void {
  try {
    const profile = base?.lens;
    const rings = [];
    const ms: number[] = [];
    let px: Uint8ClampedArray | null = null;
    for (const bm of m.bitmaps) {
      px = pixels(bm);
      const t0 = performance.now();
      if (profile?.model === 'catadioptric') rings.push(findRingFrame(cv as RingCv, px, canvas!.width, canvas!.height));
      ms.push(performance.now() - t0);
    }
    let check: Omit<LensCheck, 'look'>;
    let changed_px = 0;
    if (profile?.model !== 'catadioptric') {
      // a 360 camera has no ring to find, and nothing a clip-on could move
      const message = 'An equirectangular camera has no lens ring to check';
      check = { verdict: 'same', dx: 0, dy: 0, scale: 1, moved_px: 0, message, ring: null, ms, changed_px };
    } else {
      const ring = medianRing(rings);
      const { lens: corrected, ...fit } = fitLens(profile, ring);
      // corrected against the page's profile every time, never on top of an earlier correction; a
      // ring that cannot be used leaves the extractor as it is (nothing is sent until it can)
      const want = fit.verdict === 'corrected' ? corrected : fit.verdict === 'same' ? profile : null;
      if (want && JSON.stringify(want) !== JSON.stringify(ext!.lens)) {
        changed_px = profileMoved(ext!.lens, want);
        ext!.delete();
        ext = new Extractor(cv!, want, base!.settings);
      }
      check = { ...fit, ring, ms, changed_px };
    }
    const look = px ? lookOf(px, canvas!.width, canvas!.height, ext!.lens) : { mean: NaN, edge: NaN };
    post({ type: 'lens', id: m.id, check: { ...check, look } });
    // keypoints through the corrected profile too, after the page has its answer (the frames
    // kept are pixels: the same through either profile)
    if (wanted && changed_px) tryDetector();
  } catch (e) {
    post({ type: 'error', id: m.id, message: e instanceof Error ? e.message : String(e) });
  } finally {
    for (const bm of m.bitmaps) bm.close(); // those a failure left open (closing twice is harmless)
  }
}

/** The detector for the extractor's profile (a lens check may have corrected it) and `wanted` keypoints, made ready. */
function localDetector(): LocalDetector {
  if (!detector || detector.lens !== ext!.lens || detector.nFeatures !== wanted) {
    detector?.delete();
    detector = null;
    detector = new LocalDetector(cv as unknown as LocalCv, ext!.lens, wanted);
    detector.prepare();
  }
  return detector;
}

/** localDetector() where a failure must not stop the curves (an init, a lens check): the next `local` says it. */
function tryDetector(): void {
  try {
    localDetector();
  } catch {
    // the curves go on; the page's `local` request gets the error and sends the curves alone
  }
}

/** Keypoints wanted from now on (0: none): the detector made ready now, off a press's path. */
function prepare(m: Extract<ToWorker, { type: 'prepare' }>): void {
  const start = performance.now();
  try {
    wanted = m.n;
    if (!wanted) {
      detector?.delete();
      detector = null;
      recent.clear();
    } else if (ext && cv) localDetector();
    post({ type: 'prepared', id: m.id, ms: performance.now() - start });
  } catch (e) {
    post({ type: 'error', id: m.id, message: e instanceof Error ? e.message : String(e) });
  }
}

/**
 * The local features of frame `m.frame` (the id of its extraction request) if it is one of the last
 * KEPT_FRAMES extracted, through the profile in use; asked for with `wanted` set by `prepare`.
 */
function local(m: Extract<ToWorker, { type: 'local' }>): void {
  try {
    const px = recent.get(m.frame);
    if (!ext || !cv || !wanted) throw new Error('local features were not asked for (prepare) before this frame');
    if (!px) throw new Error(`frame ${m.frame} is not one of the last ${KEPT_FRAMES} extracted`);
    const start = performance.now();
    const { az, el, desc } = localDetector().detect(px);
    post({ type: 'local', id: m.id, az, el, desc, ms: performance.now() - start }, [az.buffer, el.buffer, desc.buffer]);
  } catch (e) {
    post({ type: 'error', id: m.id, message: e instanceof Error ? e.message : String(e) });
  }
}

self.onmessage = (ev: MessageEvent<ToWorker>) => {
  const m = ev.data;
  if (m.type === 'init')
    init(m).catch((e) => post({ type: 'error', id: m.id, message: `the feature extractor did not start: ${e}` }));
  else if (m.type === 'frame') frame(m);
  else if (m.type === 'lens') lens(m);
  else if (m.type === 'local') local(m);
  else if (m.type === 'prepare') prepare(m);
};
