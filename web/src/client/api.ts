/** The server's public API (backend/omninav/server/openapi.yaml), with errors a person can act on. */
import type { Answer, Venue } from '../shared/api-types';

export type { Answer, Floor, Nearest, Place, Venue } from '../shared/api-types';

/** The server could not be reached at all (offline, wrong network, server stopped). */
export class Unreachable extends Error {}

/** The server answered with an error; `message` is its own one-line explanation. */
export class ApiProblem extends Error {
  constructor(
    readonly status: number,
    message: string,
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
    throw new ApiProblem(res.status, msg);
  }
  return body;
}

export async function venues(): Promise<{ id: string; name: string }[]> {
  return ((await call('/api/venues')) as { venues: { id: string; name: string }[] }).venues;
}

export async function venue(id: string): Promise<Venue> {
  return (await call(`/api/venues/${encodeURIComponent(id)}`)) as Venue;
}

/** POST a binary feature record; the server answers where the clip's last frame was taken. */
export async function locate(venueId: string, record: Uint8Array, fps: number, clip: string): Promise<Answer> {
  const q = new URLSearchParams({ fps: fps.toFixed(2), clip });
  return (await call(`/api/venues/${encodeURIComponent(venueId)}/locate?${q}`, {
    method: 'POST',
    headers: { 'Content-Type': 'application/octet-stream' },
    body: record as BodyInit,
  })) as Answer;
}
