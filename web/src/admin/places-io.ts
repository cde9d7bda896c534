/**
 * Place lists in and out (docs/formats.md, "Places"): a file's list checked before anything is sent,
 * with the same rules as the server (catalog/places.py), so that a bad file is refused with the
 * place it is about; and the export, which the import reads back.
 */
import type { Place } from '../shared/api-types';

/** What the place kinds are (optional; a corridor or a room is usually also an area). */
export const PLACE_KINDS = ['room', 'door', 'lift', 'stairs', 'exit', 'toilet', 'desk', 'other'] as const; // docs/formats.md

/** A place as sent to the server (no id). */
export interface PlaceInput {
  name: string;
  floor: string;
  x: number;
  y: number;
  area?: [number, number, number, number];
  /** The sentence to speak on arrival (optional). */
  say?: string;
  kind?: string;
}

/** A place as the server answers it, with the optional fields the page also edits. */
export type EditablePlace = Place & { say?: string; kind?: string };

const finite = (v: unknown): v is number => typeof v === 'number' && Number.isFinite(v);

/** One place of a file -> a PlaceInput, or an Error naming it ("place 3 (the lifts): ..."). */
export function checkPlace(p: unknown, i: number, floors: readonly string[]): PlaceInput {
  const where = `place ${i + 1}`;
  if (!p || typeof p !== 'object' || Array.isArray(p)) throw new Error(`${where} is not an object`);
  const o = p as Record<string, unknown>;
  if (typeof o.name !== 'string' || !o.name.trim() || o.name.length > 200)
    throw new Error(`${where}: "name" must be a non-empty text of at most 200 characters`);
  const name = o.name.trim();
  const floor = o.floor === undefined ? (floors.length === 1 ? floors[0] : '1') : String(o.floor);
  if (!floors.includes(floor)) throw new Error(`${where} (${name}): the venue has no floor "${floor}"`);
  if (!finite(o.x) || !finite(o.y)) throw new Error(`${where} (${name}): "x" and "y" must be numbers (metres)`);
  const out: PlaceInput = { name, floor, x: o.x, y: o.y };
  if (o.area !== undefined && o.area !== null) {
    const a = o.area;
    if (!Array.isArray(a) || a.length !== 4 || !a.every(finite))
      throw new Error(`${where} (${name}): "area" must be [x0, y0, x1, y1] in metres`);
    if (a[2] <= a[0] || a[3] <= a[1]) throw new Error(`${where} (${name}): "area" needs x0 < x1 and y0 < y1`);
    out.area = [a[0], a[1], a[2], a[3]];
  }
  if (o.say !== undefined && o.say !== null && o.say !== '') {
    if (typeof o.say !== 'string' || o.say.length > 500)
      throw new Error(`${where} (${name}): "say" must be a text of at most 500 characters`);
    out.say = o.say.trim();
  }
  if (o.kind !== undefined && o.kind !== null && o.kind !== '') {
    if (typeof o.kind !== 'string' || !(PLACE_KINDS as readonly string[]).includes(o.kind))
      throw new Error(`${where} (${name}): "kind" must be one of ${PLACE_KINDS.join(', ')}`);
    out.kind = o.kind;
  }
  return out;
}

/**
 * A place file's text -> its places, all checked (the first problem throws). Takes the list of
 * docs/formats.md or the API's `{"places": [...]}`.
 */
export function parsePlaces(text: string, floors: readonly string[]): PlaceInput[] {
  let data: unknown;
  try {
    data = JSON.parse(text);
  } catch (e) {
    throw new Error(`the file is not JSON (${e instanceof Error ? e.message : String(e)})`);
  }
  if (data && typeof data === 'object' && !Array.isArray(data) && 'places' in data)
    data = (data as { places: unknown }).places;
  if (!Array.isArray(data)) throw new Error('the file must hold a JSON list of places: [{"name", "x", "y"}, …]');
  return data.map((p, i) => checkPlace(p, i, floors));
}

/** A venue's places as a place file (no ids; the fields docs/formats.md names, plus say and kind). */
export function exportPlaces(places: readonly EditablePlace[]): string {
  const list = places.map((p) => toInput(p));
  return `${JSON.stringify(list, null, 1)}\n`;
}

/** A stored place -> what a PUT of the list sends back for it. */
export function toInput(p: EditablePlace): PlaceInput {
  const out: PlaceInput = { name: p.name, floor: p.floor, x: p.x, y: p.y };
  if (p.area) out.area = [p.area[0], p.area[1], p.area[2], p.area[3]];
  if (p.say) out.say = p.say;
  if (p.kind) out.kind = p.kind;
  return out;
}
