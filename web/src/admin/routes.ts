/** The admin page's hash routes: `#/venues` and `#/v/<id>/<screen>[?query]`. */

/** The venue's screens, in the order of the work (and of the nav). */
export const SCREEN_IDS = [
  'floor',
  'places',
  'lenses',
  'videos',
  'walk-path',
  'modelling',
  'quality',
  'evaluation',
] as const;

export type ScreenId = (typeof SCREEN_IDS)[number];

/** Screens under their name of the last release, so that a kept bookmark still opens them. */
const RENAMED: Readonly<Record<string, ScreenId>> = { track: 'walk-path' };

export type Route = { kind: 'venues' } | { kind: 'venue'; id: string; screen: ScreenId; params: URLSearchParams };

/** '#/v/lab/places?floor=1' -> the route; an unknown screen is the floor, anything else the venue list. */
export function parseRoute(hash: string): Route {
  const h = hash.replace(/^#/, '');
  const q = h.indexOf('?');
  const path = q < 0 ? h : h.slice(0, q);
  const query = q < 0 ? '' : h.slice(q + 1);
  const parts = path.split('/').filter(Boolean);
  if (parts[0] === 'v' && parts[1]) {
    const named = RENAMED[parts[2]] ?? parts[2];
    const screen = (SCREEN_IDS as readonly string[]).includes(named) ? (named as ScreenId) : 'floor';
    return { kind: 'venue', id: decodeURIComponent(parts[1]), screen, params: new URLSearchParams(query) };
  }
  return { kind: 'venues' };
}

/** The hash of a venue's screen. */
export function venueHash(id: string, screen: ScreenId, params?: URLSearchParams): string {
  const qs = params?.toString();
  return `#/v/${encodeURIComponent(id)}/${screen}${qs ? `?${qs}` : ''}`;
}
