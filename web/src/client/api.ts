/** The server's public API (backend/omninav/server/openapi.yaml), with errors a person can act on. */
import type { Answer, Destinations, Venue } from '../shared/api-types';
import type { Style } from './directions';

export type {
  Answer,
  Destination,
  DestinationFloor,
  Destinations,
  Floor,
  Guidance,
  Nearest,
  Place,
  Tracking,
  Venue,
} from '../shared/api-types';

/** The server could not be reached at all (offline, wrong network, server stopped). */
export class Unreachable extends Error {}

/** The server answered with an error; `message` is its own one-line explanation, `body` all of it. */
export class ApiProblem extends Error {
  constructor(
    readonly status: number,
    message: string,
    readonly body: Record<string, unknown> = {},
  ) {
    super(message);
  }
}

export const UNREACHABLE =
  'Cannot reach the omninav server. Check that the phone is on the building’s Wi-Fi, then press Where am I? again.';

async function call(path: string, init?: RequestInit, timeoutMs = 15000): Promise<unknown> {
  let res: Response;
  const ctl = new AbortController();
  const timer = setTimeout(() => ctl.abort(), timeoutMs);
  try {
    res = await fetch(path, { ...init, signal: ctl.signal, cache: 'no-store' });
  } catch {
    throw new Unreachable(UNREACHABLE);
  } finally {
    clearTimeout(timer);
  }
  let body: unknown = null;
  try {
    body = await res.json();
  } catch {
    // a proxy's HTML error page: report the status alone
  }
  if (!res.ok) {
    const msg = (body as { error?: string } | null)?.error ?? `the server answered ${res.status}`;
    const all = body !== null && typeof body === 'object' ? (body as Record<string, unknown>) : {};
    throw new ApiProblem(res.status, msg, all);
  }
  return body;
}

export async function venues(): Promise<{ id: string; name: string; modelled: boolean }[]> {
  return ((await call('/api/venues')) as { venues: { id: string; name: string; modelled: boolean }[] }).venues;
}

export async function venue(id: string): Promise<Venue> {
  return (await call(`/api/venues/${encodeURIComponent(id)}`)) as Venue;
}

/** The places one can be guided to in a venue, by floor, sorted by name. */
export async function destinations(venueId: string): Promise<Destinations> {
  return (await call(`/api/venues/${encodeURIComponent(venueId)}/destinations`)) as Destinations;
}

/**
 * A tracked request (issue 14): `session` continues the server's filter, `to` asks for guidance
 * to a place, `t` is the phone's clock (s) at the clip's last frame, `steps` and `turn_deg` the
 * phone's motion since the session's previous request (absent: unknown), `style` the words of
 * `guidance.sentence`.
 */
export interface Tracked {
  session: string;
  to?: string;
  t?: number;
  steps?: number | null;
  turn_deg?: number | null;
  style?: Style;
}

/**
 * A new tracking session's id (a guided walk, a run of "Keep telling me"), random and as the server
 * takes it, [A-Za-z0-9_-]{8,64}: a UUID without dashes, else 16 random bytes in base64url.
 */
export function newSessionId(): string {
  const c = globalThis.crypto;
  if (typeof c?.randomUUID === 'function') return c.randomUUID().replace(/-/g, '');
  const b = new Uint8Array(16);
  c.getRandomValues(b);
  return btoa(String.fromCharCode(...b))
    .replace(/\+/g, '-')
    .replace(/\//g, '_')
    .replace(/=+$/, '');
}

/** The query of a tracked request, each value within the server's bounds. */
export function trackedQuery(o: Tracked): Record<string, string> {
  const q: Record<string, string> = { session: o.session };
  if (o.to !== undefined) q.to = o.to;
  if (o.t !== undefined && Number.isFinite(o.t)) q.t = o.t.toFixed(3);
  if (o.steps !== undefined && o.steps !== null) q.steps = String(Math.min(Math.max(Math.round(o.steps), 0), 10000));
  if (o.turn_deg !== undefined && o.turn_deg !== null && Number.isFinite(o.turn_deg))
    q.turn_deg = (Math.round(Math.min(Math.max(o.turn_deg, -36000), 36000) * 10) / 10).toString();
  if (o.style) q.style = o.style;
  return q;
}

/**
 * POST a binary feature record; the server answers where the clip's last frame was taken (with
 * `tracked`: the filtered pose, and guidance when it names a place).
 */
export async function locate(
  venueId: string,
  record: Uint8Array,
  fps: number,
  clip: string,
  tracked?: Tracked,
): Promise<Answer> {
  const q = new URLSearchParams({ fps: fps.toFixed(2), clip, ...(tracked ? trackedQuery(tracked) : {}) });
  return (await call(`/api/venues/${encodeURIComponent(venueId)}/locate?${q}`, {
    method: 'POST',
    headers: { 'Content-Type': 'application/octet-stream' },
    body: record as BodyInit,
  })) as Answer;
}
