// Which videos the modelling button takes: tagged modelling walks that are uploaded and not modelled;
// and when the page offers a modelling anew (the live frames' settings are not the preset's now).
import { describe, expect, it } from 'vitest';
import { anewNotice, anewVideos, modelVerdict } from '../src/admin/screens/modelling';
import type { AdminVenue, Video } from '../src/admin/types';
import { videoDoc } from './admin-video';

/** An uploaded, tagged modelling walk, unless `over` says otherwise. */
const video = (over: Partial<Video>): Video =>
  videoDoc({
    received: 1000,
    status: 'ready',
    has_walk_path: true,
    walk_path: { waypoints: [] },
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
    expect(modelVerdict(video({ has_walk_path: false })).why).toBe('no walk path yet: tag it first');
    expect(modelVerdict(video({ status: 'uploading' })).why).toBe('still uploading');
    expect(modelVerdict(video({ status: 'modelled', frames: 188 })).why).toBe('already modelled (188 frames)');
    expect(modelVerdict(video({ role: 'evaluation' })).goes).toBe(false);
  });
});

/** A modelled venue whose live frames have settings id `live`, its preset's now `preset`. */
const venue = (live: number, preset: number, current: boolean | null): AdminVenue =>
  ({
    id: 'lab',
    generation: current === null ? null : 3,
    modelled_at: null,
    settings_current: current,
    preset_settings_id: preset,
    features: { settings_id: live },
  }) as unknown as AdminVenue;

describe('a modelling anew', () => {
  const walks = [
    video({ name: 'walk.mp4', status: 'modelled', frames: 188 }),
    video({ name: 'new.mp4' }),
    video({ name: 'untagged.mp4', has_walk_path: false }),
    video({ name: 'eval.mp4', role: 'evaluation' }),
    video({ name: 'half.mp4', status: 'uploading' }),
  ];
  it('takes every uploaded modelling walk with a walk path, modelled or not', () => {
    expect(anewVideos(walks)).toEqual(['walk.mp4', 'new.mp4']);
  });
  it('is offered only when the live frames have older settings than the preset', () => {
    expect(anewNotice(venue(7, 7, true), walks)).toBeNull();
    expect(anewNotice(venue(0, 7, null), walks)).toBeNull(); // never modelled: the first modelling uses the preset
    expect(anewNotice(venue(5, 7, false), walks)).toBe(
      'This venue was modelled with older feature settings than its preset has now. ' +
        'Modelling anew models walk.mp4, new.mp4 again with them. Until that is complete the venue answers as ' +
        'it does now; phones take up the new settings by themselves.',
    );
  });
  it('says when there is nothing to model anew from', () => {
    expect(anewNotice(venue(5, 7, false), [video({ has_walk_path: false })])).toContain(
      'Modelling anew needs the modelling videos with their walk paths, and no uploaded modelling video has a walk path yet',
    );
  });
});
