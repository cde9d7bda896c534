// Which videos the modelling button takes: tagged modelling walks that are uploaded and not modelled.
import { describe, expect, it } from 'vitest';
import { modelVerdict } from '../src/admin/screens/modelling';
import type { Video } from '../src/admin/types';
import { videoDoc } from './admin-video';

/** An uploaded, tagged modelling walk, unless `over` says otherwise. */
const video = (over: Partial<Video>): Video =>
  videoDoc({
    received: 1000,
    status: 'ready',
    tracked: true,
    track: { waypoints: [] },
    duration_s: 20,
    fps: 10,
    width: 480,
    height: 360,
    ...over,
  });

describe('the next modelling', () => {
  it('takes a tagged, uploaded modelling walk', () => {
    expect(modelVerdict(video({}))).toEqual({ goes: true, why: 'will be modelled' });
  });
  it('leaves out the others, saying why', () => {
    expect(modelVerdict(video({ tracked: false })).why).toBe('no track yet: tag it first');
    expect(modelVerdict(video({ status: 'uploading' })).why).toBe('still uploading');
    expect(modelVerdict(video({ status: 'modelled', frames: 188 })).why).toBe('already modelled (188 frames)');
    expect(modelVerdict(video({ role: 'evaluation' })).goes).toBe(false);
  });
});
