/**
 * The public API's types, one interface per schema of backend/omninav/server/openapi.yaml (same
 * name, same properties, optional exactly where the schema does not require them, `| null` exactly
 * where it allows null). web/tests/api-types.test.ts compares them with the schemas.
 */
import type { Lens } from './lens';
import type { VenueFeatures } from './settings';

export interface Place {
  id: string;
  floor: string;
  name: string;
  x: number;
  y: number;
  /** A region one can be in, [x0, y0, x1, y1] in metres. */
  area?: [number, number, number, number];
  /** What it is (docs/formats.md); a lift or stairs of one name on two floors joins them. */
  kind?: 'room' | 'door' | 'lift' | 'stairs' | 'exit' | 'toilet' | 'desk' | 'other';
  /** A sentence to speak on arrival. */
  say?: string;
}

export interface Floor {
  id: string;
  name: string;
  plan_url: string | null;
  plan_size_px: [number, number] | null;
  px_per_m: number | null;
}

export interface Venue {
  id: string;
  name: string;
  revision: number;
  modelled: boolean;
  frames: number;
  floors: Floor[];
  places: Place[];
  lenses: Record<string, Lens>;
  features: VenueFeatures;
}

/** The nearest point place: how far, and its bearing clockwise from the heading, in (-180, 180]. */
export interface Nearest {
  name: string;
  distance_m: number;
  bearing_deg: number;
}

/** A localisation answer (docs/formats.md) with the words the server adds. */
export interface Answer {
  clip: string;
  x: number;
  y: number;
  heading_deg: number;
  confidence: number;
  floor: string;
  place: string | null;
  frame: number;
  area: string | null;
  nearest: Nearest | null;
  facing: string | null;
  /** The sentence in the default style, for API clients; the app makes its own (directions.ts). */
  sentence: string;
  low_confidence: boolean;
  accuracy_m: number | null;
  frames: number;
  sent: 'features' | 'frames';
  plan_png?: string | null;
}
