/// <reference lib="webworker" />
/**
 * The feature worker: owns opencv.js (WebAssembly) and turns camera frames into spectra, off the
 * main thread so that the page, speech and the screen reader never wait on image work.
 */
import cvModule from '@techstark/opencv-js';
import { Extractor, readyCv, type Cv } from './extract';
import type { FromWorker, ToWorker } from '../shared/protocol';

declare const self: DedicatedWorkerGlobalScope;

// opencv.js compiles its WebAssembly once, on the first lens: one memoised promise
let cvReady: Promise<Cv> | null = null;
const loadCv = (): Promise<Cv> => (cvReady ??= readyCv(cvModule));
let ext: Extractor | null = null;
let canvas: OffscreenCanvas | null = null;
let ctx: OffscreenCanvasRenderingContext2D | null = null;

function post(m: FromWorker, transfer: Transferable[] = []): void {
  self.postMessage(m, transfer);
}

async function init(m: Extract<ToWorker, { type: 'init' }>): Promise<void> {
  const t0 = performance.now();
  const cv = await loadCv();
  ext?.delete();
  ext = new Extractor(cv, m.lens, m.settings);
  const [w, h] = m.lens.image_size;
  canvas = new OffscreenCanvas(w, h);
  // willReadFrequently keeps the canvas in CPU memory: getImageData every frame is then cheap
  ctx = canvas.getContext('2d', { willReadFrequently: true, alpha: false });
  post({ type: 'ready', id: m.id, loadMs: performance.now() - t0 });
}

function frame(m: Extract<ToWorker, { type: 'frame' }>): void {
  const start = performance.now();
  try {
    if (!ext || !ctx || !canvas) throw new Error('the feature worker was not initialised with a lens');
    // a camera at another resolution of the same shape is scaled to the lens's calibrated size
    ctx.drawImage(m.bitmap, 0, 0, canvas.width, canvas.height);
    m.bitmap.close();
    const px = ctx.getImageData(0, 0, canvas.width, canvas.height).data;
    const out = ext.extract(px, m.keep);
    const { mag, phase } = out.spectrum;
    const transfer: Transferable[] = [mag.buffer, phase.buffer];
    if (out.pano) transfer.push(out.pano.buffer);
    if (out.curves) transfer.push(out.curves.buffer);
    post(
      { type: 'features', id: m.id, mag, phase, ms: performance.now() - start, pano: out.pano, curves: out.curves },
      transfer,
    );
  } catch (e) {
    post({ type: 'error', id: m.id, message: e instanceof Error ? e.message : String(e) });
  }
}

self.onmessage = (ev: MessageEvent<ToWorker>) => {
  const m = ev.data;
  if (m.type === 'init')
    init(m).catch((e) => post({ type: 'error', id: m.id, message: `the feature extractor did not start: ${e}` }));
  else if (m.type === 'frame') frame(m);
};
