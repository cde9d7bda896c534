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
}

export interface VenueFeatures {
  settings: FeatureSettings;
  settings_id: number;
  n_curves: number;
  n_harmonics: number;
  record_header_bytes: number;
  record_bytes_per_frame: number;
}

export const nCurves = (s: FeatureSettings): number => s.bands.length * s.channels.length;
