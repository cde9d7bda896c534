/** The page's side of the feature worker: promises for frames, one worker per page. */
import type { Lens } from '../shared/lens';
import type { FeatureSettings } from '../shared/settings';
import type { FrameSpectrum } from '../shared/record';
import type { FromWorker, ToWorker } from '../shared/protocol';

export interface FrameResult extends FrameSpectrum {
  ms: number;
  pano?: Uint8Array;
  curves?: Float32Array;
}

export class ExtractorClient {
  private worker: Worker;
  private nextId = 1;
  private pending = new Map<number, { resolve: (r: FrameResult) => void; reject: (e: Error) => void }>();
  private readyWait: { resolve: (ms: number) => void; reject: (e: Error) => void } | null = null;
  configured: string | null = null;

  constructor() {
    this.worker = new Worker(new URL('../worker/worker.ts', import.meta.url), { type: 'module' });
    this.worker.onmessage = (ev: MessageEvent<FromWorker>) => this.receive(ev.data);
    this.worker.onerror = (ev) => this.failAll(new Error(`the feature worker failed: ${ev.message}`));
  }

  private receive(m: FromWorker): void {
    if (m.type === 'ready') {
      this.readyWait?.resolve(m.loadMs);
      this.readyWait = null;
    } else if (m.type === 'features') {
      const p = this.pending.get(m.id);
      this.pending.delete(m.id);
      p?.resolve({ mag: m.mag, phase: m.phase, ms: m.ms, pano: m.pano, curves: m.curves });
    } else if (m.id !== undefined) {
      const p = this.pending.get(m.id);
      this.pending.delete(m.id);
      p?.reject(new Error(m.message));
    } else {
      this.failAll(new Error(m.message));
    }
  }

  private failAll(e: Error): void {
    this.readyWait?.reject(e);
    this.readyWait = null;
    for (const p of this.pending.values()) p.reject(e);
    this.pending.clear();
  }

  /** Set the lens and settings (once per pair); resolves with the worker's load time in ms. */
  configure(lens: Lens, settings: FeatureSettings): Promise<number> {
    const key = JSON.stringify([lens, settings]);
    if (key === this.configured) return Promise.resolve(0);
    return new Promise<number>((resolve, reject) => {
      this.readyWait = {
        resolve: (ms) => {
          this.configured = key;
          resolve(ms);
        },
        reject,
      };
      this.post({ type: 'init', lens, settings });
    });
  }

  /** One frame (the bitmap is transferred, and closed by the worker). */
  extract(bitmap: ImageBitmap, keep = false): Promise<FrameResult> {
    const id = this.nextId++;
    return new Promise((resolve, reject) => {
      this.pending.set(id, { resolve, reject });
      this.post({ type: 'frame', id, bitmap, keep }, [bitmap]);
    });
  }

  private post(m: ToWorker, transfer: Transferable[] = []): void {
    this.worker.postMessage(m, transfer);
  }
}
