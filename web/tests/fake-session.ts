// The fake venue, answers, clips and session shared by the Session tests (ask-more, track, session). The
// camera, the feature worker and the server are mocked by each test file itself (vi.mock is
// hoisted only there): this module is imported after those mocks, so its Session uses them.
import { vi } from 'vitest';
import type { Answer, Venue } from '../src/client/api';
import type { Clip } from '../src/client/camera';
import { DEFAULTS } from '../src/client/prefs';
import { Session, type SessionOptions } from '../src/client/session';

/** Curves x harmonics of the fake venue: small records. */
export const CK = 2;

export const VENUE: Venue = {
  id: 'lab',
  name: 'Lab',
  revision: 1,
  modelled: true,
  frames: 100,
  floors: [{ id: '1', name: 'Ground floor', plan_url: null, plan_size_px: null, px_per_m: null }],
  places: [],
  // a 360 camera: no donut ring to check first
  lenses: { pano: { model: 'equirectangular', image_size: [640, 320], forward_x: 320 } },
  features: {
    settings: {
      pano_width: 360,
      oversample: 4,
      row_step_deg: 1,
      bands: [[-20, 20]],
      channels: ['I'],
      gray_world: false,
      n_harmonics: CK,
    },
    settings_id: 7,
    n_curves: 1,
    n_harmonics: CK,
    record_header_bytes: 20,
    record_bytes_per_frame: 4 * CK,
  },
};

export function answer(lowConfidence: boolean): Answer {
  return {
    ...{ clip: 'c', x: 3, y: 4, heading_deg: 90, confidence: lowConfidence ? 0.3 : 0.9, floor: '1' },
    ...{ place: null, frame: 5, area: 'the Hall', nearest: null, facing: null, sentence: '' },
    ...{ low_confidence: lowConfidence, accuracy_m: lowConfidence ? null : 2, frames: 10, sent: 'features' },
  };
}

/** A clip of `n` fake frames, grabbed 100 ms apart from `at` ms. */
export function clip(n: number, at: number): Clip {
  const frames = Array.from({ length: n }, () => ({ mag: new Uint16Array(CK), phase: new Int16Array(CK), ms: 1 }));
  return { frames, fps: 10, startMs: at, endMs: at + 100 * (n - 1) };
}

/** A Session on a fake video with a fake voice (and `more` options); what it says, asks and answers, in order. */
export function session(more: Partial<SessionOptions> = {}) {
  const said: string[] = [];
  const voice = { busy: false, say: vi.fn((text: string) => said.push(text)), cue: vi.fn() };
  const s = new Session({
    prefs: { ...DEFAULTS },
    save: vi.fn(),
    voice,
    video: { videoWidth: 640, videoHeight: 320 } as HTMLVideoElement,
    askedVenue: null,
    ...more,
  });
  const asking: boolean[] = [];
  s.on('asking', (on) => asking.push(on));
  const answers: number[] = [];
  s.on('answer', (r) => answers.push(r.frames));
  return { s, said, asking, answers, voice };
}
