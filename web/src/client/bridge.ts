/** The page's side of the feature worker: promises for frames, one worker per page. */
import type { Lens } from '../shared/lens';
import type { FeatureSettings } from '../shared/settings';
import type { FrameSpectrum, LocalBlock } from '../shared/record';
import type { FromWorker, LensCheck, Look, ToWorker } from '../shared/protocol';

export interface FrameResult extends FrameSpectrum {
  ms: number;
  /** Its request's id in the worker (absent from fakes): what `local()` names a frame by. */
  id?: number;
  /** The frame's look (mean grey, step across the ring's edge): tells an abrupt change. */
  look?: Look;
  pano?: Uint8Array;
  curves?: Float32Array;
}

type Reply = Exclude<FromWorker, { type: 'error' }>;

export class ExtractorClient {
  private worker: Worker;
  private nextId = 1;
  // inits, frames and lens checks share one id space: each reply settles exactly the request it answers
  private pending = new Map<number, { resolve: (r: Reply) => void; reject: (e: Error) => void }>();
  private key: string | null = null;
  private ready: Promise<number> | null = null;

  constructor() {
    this.worker = new Worker(new URL('../worker/worker.ts', import.meta.url), { type: 'module' });
    this.worker.onmessage = (ev: MessageEvent<FromWorker>) => this.receive(ev.data);
    this.worker.onerror = (ev) => this.failAll(new Error(`the feature worker failed: ${ev.message}`));
  }

  /** The lens and settings the worker was last asked to use (a new one drops any lens correction). */
  get configured(): string | null {
    return this.key;
  }

  private receive(m: FromWorker): void {
    if (m.type !== 'error') {
      const p = this.pending.get(m.id);
      this.pending.delete(m.id);
      p?.resolve(m);
    } else if (m.id !== undefined) {
      const p = this.pending.get(m.id);
      this.pending.delete(m.id);
      p?.reject(new Error(m.message));
    } else this.failAll(new Error(m.message));
  }

  private failAll(e: Error): void {
    for (const p of this.pending.values()) p.reject(e);
    this.pending.clear();
    this.key = null;
    this.ready = null;
  }

  private request<T extends Reply['type']>(
    m: ToWorker,
    want: T,
    transfer: Transferable[] = [],
  ): Promise<Extract<Reply, { type: T }>> {
    return new Promise((resolve, reject) => {
      this.pending.set(m.id, {
        resolve: (r) =>
          r.type === want
            ? resolve(r as Extract<Reply, { type: T }>)
            : reject(new Error(`the feature worker answered ${r.type} to ${m.type}`)),
        reject,
      });
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
    const ready = this.request({ type: 'init', id: this.nextId++, lens, settings }, 'ready').then((r) => r.loadMs);
    ready.catch(() => {
      if (this.ready === ready) [this.key, this.ready] = [null, null]; // a later call tries again
    });
    this.ready = ready;
    return ready;
  }

  /** One frame (the bitmap is transferred, and closed by the worker). */
  async extract(bitmap: ImageBitmap, keep = false): Promise<FrameResult> {
    const m = await this.request({ type: 'frame', id: this.nextId++, bitmap, keep }, 'features', [bitmap]);
    return { id: m.id, mag: m.mag, phase: m.phase, ms: m.ms, look: m.look, pano: m.pano, curves: m.curves };
  }

  /**
   * Local features wanted from now on, `n` ORB keypoints a frame (0: none): the worker keeps the
   * last few frames for them and makes its detector ready now (not on a press's path); its time.
   * Keeps the lens and any correction of it: only `configure` changes those.
   */
  async prepareLocal(n: number): Promise<number> {
    return (await this.request({ type: 'prepare', id: this.nextId++, n }, 'prepared')).ms;
  }

  /**
   * The local features of a frame extracted lately (`frame`: its FrameResult's id, one of the last
   * three extracted; prepareLocal first): its keypoints (none where the lens sees too few rows all
   * round) and the worker's time for them.
   */
  async local(frame: number): Promise<LocalBlock & { ms: number }> {
    const m = await this.request({ type: 'local', id: this.nextId++, frame }, 'local');
    return { az: m.az, el: m.el, desc: m.desc, ms: m.ms };
  }

  /**
   * The lens check on a few frames (transferred, closed by the worker): the ring, the verdict, and
   * from now on the worker extracts with the corrected profile when the verdict is "corrected".
   */
  async checkLens(bitmaps: ImageBitmap[]): Promise<LensCheck> {
    return (await this.request({ type: 'lens', id: this.nextId++, bitmaps }, 'lens', bitmaps)).check;
  }
}
