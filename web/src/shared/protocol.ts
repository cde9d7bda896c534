/** Messages between the page and the feature worker (src/worker.ts). */
import type { Lens } from './lens';
import type { FeatureSettings } from './settings';

export type ToWorker =
  | { type: 'init'; id: number; lens: Lens; settings: FeatureSettings }
  /** One camera frame; `keep` returns the panorama and curves too (self-test only). */
  | { type: 'frame'; id: number; bitmap: ImageBitmap; keep?: boolean };

export type FromWorker =
  | { type: 'ready'; id: number; loadMs: number }
  | {
      type: 'features';
      id: number;
      mag: Uint16Array;
      phase: Int16Array;
      ms: number;
      pano?: Uint8Array;
      curves?: Float32Array;
    }
  | { type: 'error'; id?: number; message: string };
