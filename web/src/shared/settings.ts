/** The venue's feature settings (GET /api/venues/{id} -> features.settings): what a record must be made with. */
export interface FeatureSettings {
  pano_width: number;
  oversample: number;
  row_step_deg: number;
  bands: [number, number][];
  channels: string[];
  gray_world: boolean;
  n_harmonics: number;
  /** each normalised curve becomes sd * tanh(curve / sd), normalised again; absent or null: off */
  soft_clip_sd?: number | null;
  /** per band, its own channels (presets.py `band_channels`); absent or null: every band has `channels` */
  band_channels?: string[][] | null;
  /** passes of levelling (the lens's tilt from the picture's upright edges, worker/level.ts); absent, null or 0: off */
  level_iters?: number | null;
  /**
   * ORB keypoints a modelled frame keeps (the `verified` preset's 900): the venue verifies clips
   * that bring their last frame's (worker/local.ts); absent or null: it does not. Not a feature
   * key: the curves do not depend on it.
   */
  local_features?: number | null;
}

/**
 * The feature settings this app knows how to apply (presets.py `FEATURE_KEYS`; tests/server/test_server.py
 * holds the two lists together). A venue whose records depend on another key was modelled by a
 * newer server than this app was built for: its records would carry the venue's settings id but
 * other curves, and be answered wrongly without anyone knowing (record.ts's recordMismatch).
 */
export const KNOWN_FEATURE_KEYS: readonly (keyof FeatureSettings)[] = [
  'pano_width',
  'oversample',
  'row_step_deg',
  'bands',
  'channels',
  'gray_world',
  'n_harmonics',
  'soft_clip_sd',
  'band_channels',
  'level_iters',
];

export interface VenueFeatures {
  settings: FeatureSettings;
  settings_id: number;
  /** the settings a record for this venue depends on (absent from servers before it was added) */
  feature_keys?: string[];
  n_curves: number;
  n_harmonics: number;
  record_header_bytes: number;
  record_bytes_per_frame: number;
}

/** Each band's channels, in the record's order (presets.py `band_channels`). */
export const bandChannels = (s: FeatureSettings): string[][] => s.band_channels ?? s.bands.map(() => s.channels);

export const nCurves = (s: FeatureSettings): number => bandChannels(s).reduce((n, c) => n + c.length, 0);
