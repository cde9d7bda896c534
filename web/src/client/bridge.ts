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
  // inits and frames share one id space: each reply settles exactly the request it answers
  private pending = new Map<
    number,
    { resolve: (r: FrameResult & { loadMs?: number }) => void; reject: (e: Error) => void }
  >();
  private key: string | null = null;
  private ready: Promise<number> | null = null;

  constructor() {
    this.worker = new Worker(new URL('../worker/worker.ts', import.meta.url), { type: 'module' });
    this.worker.onmessage = (ev: MessageEvent<FromWorker>) => this.receive(ev.data);
    this.worker.onerror = (ev) => this.failAll(new Error(`the feature worker failed: ${ev.message}`));
  }

  private settle(
    id: number | undefined,
  ): { resolve: (r: FrameResult & { loadMs?: number }) => void; reject: (e: Error) => void } | undefined {
    if (id === undefined) return undefined;
    const p = this.pending.get(id);
    this.pending.delete(id);
    return p;
  }

  private receive(m: FromWorker): void {
    if (m.type === 'ready')
      this.settle(m.id)?.resolve({ mag: new Uint16Array(), phase: new Int16Array(), ms: 0, loadMs: m.loadMs });
    else if (m.type === 'features')
      this.settle(m.id)?.resolve({ mag: m.mag, phase: m.phase, ms: m.ms, pano: m.pano, curves: m.curves });
    else if (m.id !== undefined) this.settle(m.id)?.reject(new Error(m.message));
    else this.failAll(new Error(m.message));
  }

  private failAll(e: Error): void {
    for (const p of this.pending.values()) p.reject(e);
    this.pending.clear();
    this.key = null;
    this.ready = null;
  }

  private request(m: ToWorker, transfer: Transferable[] = []): Promise<FrameResult & { loadMs?: number }> {
    return new Promise((resolve, reject) => {
      this.pending.set(m.id, { resolve, reject });
      this.worker.postMessage(m, transfer);
    });
  }

  /**
   * Set the lens and settings; resolves with the worker's load time in ms. Asking again for the
   * same pair (the warm-up at venue load, then the first press) waits on the same initialisation.
   */
  configure(lens: Lens, settings: FeatureSettings): Promise<number> {
    const key = JSON.stringify([lens, settings]);
    if (key === this.key && this.ready) return this.ready;
    this.key = key;
    const ready = this.request({ type: 'init', id: this.nextId++, lens, settings }).then((r) => r.loadMs ?? 0);
    ready.catch(() => {
      if (this.ready === ready) [this.key, this.ready] = [null, null]; // a later call tries again
    });
    this.ready = ready;
    return ready;
  }

  /** One frame (the bitmap is transferred, and closed by the worker). */
  extract(bitmap: ImageBitmap, keep = false): Promise<FrameResult> {
    return this.request({ type: 'frame', id: this.nextId++, bitmap, keep }, [bitmap]);
  }
}
