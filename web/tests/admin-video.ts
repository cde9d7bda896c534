// A video document as the admin API gives it, for the admin page's unit tests: by default one just
// registered (nothing received, no walk path); a test overrides what it is about.
import type { Video } from '../src/admin/types';

export const videoDoc = (over: Partial<Video> = {}): Video => ({
  name: 'walk.mp4',
  floor: '1',
  lens: 'donut',
  role: 'model',
  size: 1000,
  received: 0,
  status: 'uploading',
  frames: 0,
  has_walk_path: false,
  walk_path: null,
  duration_s: null,
  fps: null,
  width: null,
  height: null,
  error: null,
  suggestions: null,
  upload_url: '',
  ...over,
});
