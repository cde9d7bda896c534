/**
 * The admin page's shell: the sign-in gate, the hash routes (`#/venues`, `#/v/<id>/<screen>`), the
 * venue header (its name and revision), the nav of the venue's screens, the live regions, and the
 * AdminContext each screen is mounted with. One screen is mounted at a time; its clean-up runs
 * before the next one mounts.
 */
import 'leaflet/dist/leaflet.css';
import './admin.css';
import type { Floor, Venue } from '../shared/api-types';
import { AdminApi, AdminError, venuePath } from './api';
import type { AdminContext, Mount } from './context';
import { el } from './dom';
import { placeGaps, stepsLeft, type Progress, type Step } from './checklist';
import { PlanMap } from './planmap';
import * as evaluation from './screens/evaluation';
import * as floorScreen from './screens/floor';
import * as lenses from './screens/lenses';
import * as modelling from './screens/modelling';
import * as places from './screens/places';
import * as quality from './screens/quality';
import { clearToken, mountSignIn, savedToken } from './screens/signin';
import * as walkPath from './screens/walk-path';
import * as venues from './screens/venues';
import * as videos from './screens/videos';
import { SCREEN_IDS, parseRoute, venueHash, type Route } from './routes';
import type { AdminVenue, Job, Video } from './types';

/** The venue's screens, in the order of the work (and of the nav). */
const SCREENS: { id: (typeof SCREEN_IDS)[number]; title: string; mount: Mount }[] = [
  { id: 'floor', title: 'Floor plan', mount: floorScreen.mount },
  { id: 'places', title: 'Places', mount: places.mount },
  { id: 'lenses', title: 'Lenses', mount: lenses.mount },
  { id: 'videos', title: 'Videos', mount: videos.mount },
  { id: 'walk-path', title: 'Walk path', mount: walkPath.mount },
  { id: 'modelling', title: 'Modelling', mount: modelling.mount },
  { id: 'quality', title: 'Quality map', mount: quality.mount },
  { id: 'evaluation', title: 'Evaluation', mount: evaluation.mount },
];

const byId = <T extends HTMLElement = HTMLElement>(id: string): T => document.getElementById(id) as T;
const main = byId('main');
const head = byId('venue-head');
const nav = byId('screens');
const signout = byId<HTMLButtonElement>('signout');
const statusEl = byId('status');
const alertEl = byId('alert');
const stepsNews = byId('steps-news');
const banner = byId('banner');

let api: AdminApi | null = null;
let venue: AdminVenue | null = null;
let route: Route = parseRoute(location.hash);
let unmount: (() => void) | null = null;
let mounting = 0;

/** Put `message` in a live region; the same words twice are announced twice: emptied first. */
function sayIn(region: HTMLElement, message: string): void {
  region.textContent = '';
  setTimeout(() => {
    region.textContent = message;
  }, 30);
}

function announce(message: string, assertive = false): void {
  sayIn(assertive ? alertEl : statusEl, message);
  if (!assertive) alertEl.textContent = '';
}

function hideBanner(): void {
  banner.hidden = true;
  banner.replaceChildren();
}

function fail(e: unknown, doing?: string): void {
  if (e instanceof DOMException && e.name === 'AbortError') return;
  const msg = e instanceof Error ? e.message : String(e);
  const text = doing ? `${doing}: ${msg}` : msg;
  if (e instanceof AdminError && e.stale) {
    const reload = el('button', { type: 'button', textContent: 'Reload the venue' });
    reload.addEventListener('click', () => {
      hideBanner();
      void show(true);
    });
    banner.replaceChildren(
      el('p', { textContent: `Not saved: the venue changed since you opened it. ${e.message}` }),
      reload,
    );
    banner.hidden = false;
    announce(`Not saved: the venue changed since you opened it. Reload the venue to see the changes.`, true);
    reload.focus();
    return;
  }
  announce(text, true);
}

function requireVenue(): AdminVenue {
  if (!venue) throw new Error('no venue is open');
  return venue;
}

async function loadVenue(id: string): Promise<AdminVenue> {
  if (!api) throw new Error('not signed in');
  try {
    return await api.get<AdminVenue>(venuePath(id));
  } catch (e) {
    // a server without GET /api/admin/venues/{id}: the public document
    if (e instanceof AdminError && e.status === 405)
      return {
        ...(await api.get<Venue>(`/api/venues/${encodeURIComponent(id)}`)),
        generation: null,
        modelled_at: null,
        settings_current: null,
        preset_settings_id: 0,
      };
    throw e;
  }
}

function currentFloor(): Floor | undefined {
  const v = requireVenue();
  const want = route.kind === 'venue' ? route.params.get('floor') : null;
  return v.floors.find((f) => f.id === want) ?? v.floors[0];
}

function goto(screen: string, params?: Record<string, string>): void {
  const v = requireVenue();
  const q = new URLSearchParams(params ?? {});
  const floor = route.kind === 'venue' ? route.params.get('floor') : null;
  if (floor && !q.has('floor')) q.set('floor', floor);
  const qs = q.toString();
  location.hash = `#/v/${encodeURIComponent(v.id)}/${screen}${qs ? `?${qs}` : ''}`;
}

const ctx: AdminContext = {
  get api(): AdminApi {
    if (!api) throw new Error('not signed in');
    return api;
  },
  venue: () => requireVenue(),
  refresh: async () => {
    const v = await loadVenue(requireVenue().id);
    setVenue(v);
    return v;
  },
  recheck: () => void readProgress(requireVenue().id),
  setVenue: (v: Venue) => setVenue(v),
  floor: () => currentFloor()?.id ?? '1',
  planMap: (elm: HTMLElement) => {
    const f = currentFloor();
    const pm = new PlanMap(elm, `Floor plan of ${f?.name ?? 'the floor'}`);
    if (f) void pm.setFloor(f, requireVenue().revision);
    return pm;
  },
  announce,
  fail,
  go: goto,
  params: () => (route.kind === 'venue' ? new URLSearchParams(route.params) : new URLSearchParams()),
};

function setVenue(v: Venue): void {
  const prev = venue;
  venue = {
    generation: null,
    modelled_at: null,
    settings_current: null,
    preset_settings_id: 0,
    ...(prev && prev.id === v.id
      ? {
          generation: prev.generation,
          modelled_at: prev.modelled_at,
          settings_current: prev.settings_current,
          preset_settings_id: prev.preset_settings_id,
        }
      : {}),
    ...v,
  };
  void readProgress(v.id); // first: what was read before is stale now (drawn, not said)
  drawHead();
}

/**
 * The venue's videos and jobs as last read, for the checklist: read again whenever the venue is,
 * or a screen says they changed. `read` is the number of the read that gave them: the latest one
 * (`progressRead`) has come back when they are equal, and only then is a change of steps said.
 */
let progress: { id: string; p: Progress; read: number } | null = null;
let progressRead = 0;

async function readProgress(id: string): Promise<void> {
  if (!api) return;
  const mine = ++progressRead;
  try {
    const [vids, jobs] = await Promise.all([
      api.get<{ videos: Video[] }>(venuePath(id, '/videos')),
      api.get<{ jobs: Job[] }>(venuePath(id, '/jobs')),
    ]);
    if (mine !== progressRead) return;
    progress = { id, p: { videos: vids.videos, jobs: jobs.jobs }, read: mine };
    if (venue?.id === id) drawHead();
  } catch {
    // the checklist stays as the venue document alone shows it; the screens say what failed
  }
}

/** The venue and count of the checklist last drawn (announced when it changes). */
let lastSteps = '';

/**
 * A checklist step's link. On the screen it names already the hash would not change and nothing
 * would happen: the screen's heading takes the focus instead, as after any move to a screen.
 */
function stepLink(id: string, st: Step): HTMLAnchorElement {
  const a = el('a', { href: venueHash(id, st.screen, new URLSearchParams(st.params)), textContent: st.text });
  a.addEventListener('click', (e) => {
    const r = route;
    if (r.kind !== 'venue' || r.screen !== st.screen) return;
    if (st.params?.video && st.params.video !== r.params.get('video')) return;
    e.preventDefault();
    const section = main.querySelector<HTMLElement>('section');
    if (section) focusScreen(section);
  });
  return a;
}

function drawHead(): void {
  if (!venue || route.kind !== 'venue') {
    head.hidden = true;
    nav.hidden = true;
    return;
  }
  const v = venue;
  const model =
    v.generation !== null && v.generation !== undefined
      ? `generation ${v.generation} live, ${v.frames} frames`
      : v.modelled
        ? `modelled, ${v.frames} frames`
        : 'not modelled yet';
  const floorSel = el('select', { id: 'floor-select' });
  for (const f of v.floors) floorSel.append(new Option(f.name === f.id ? `Floor ${f.id}` : f.name, f.id));
  floorSel.value = currentFloor()?.id ?? '';
  floorSel.addEventListener('change', () => {
    if (route.kind !== 'venue') return;
    const q = new URLSearchParams(route.params);
    q.set('floor', floorSel.value);
    location.hash = `#/v/${encodeURIComponent(v.id)}/${route.screen}?${q}`;
  });
  head.replaceChildren(
    el('h1', { id: 'venue-title', textContent: v.name }),
    el('p', { className: 'venue-facts', textContent: `Venue ${v.id} · revision ${v.revision} · ${model}` }),
  );
  const gaps = placeGaps(v.places);
  if (gaps) head.append(el('p', { className: 'hint', id: 'venue-gaps', textContent: gaps }));
  // what the venue still lacks, each a link to the screen that does it; said when it changes
  const known = progress?.id === v.id ? progress.p : null;
  const left = stepsLeft(v, known);
  if (left.length) {
    const list = el('ul', { id: 'venue-checklist' }, ...left.map((st) => el('li', {}, stepLink(v.id, st))));
    list.setAttribute('aria-label', 'Still to do for this venue');
    head.append(el('p', { className: 'hint', id: 'venue-checklist-title', textContent: 'Still to do:' }), list);
  }
  // said only between two lists read with the videos and jobs (the first of them is no news)
  const fresh = !!known && progress?.read === progressRead;
  const key = fresh ? `${v.id}:${left.map((st) => st.text).join('|')}` : lastSteps;
  if (fresh && lastSteps && lastSteps !== key && lastSteps.startsWith(`${v.id}:`)) {
    const news = left.length
      ? `${left.length} step${left.length === 1 ? '' : 's'} left for this venue: ${left[0].text}.`
      : 'This venue has everything the phone needs.';
    // a region of its own: said after what the action itself says, which it neither cuts nor repeats
    sayIn(stepsNews, news);
  }
  lastSteps = key;
  if (v.floors.length > 1)
    head.append(
      el(
        'div',
        { className: 'field inline' },
        el('label', { htmlFor: 'floor-select', textContent: 'Floor' }),
        floorSel,
      ),
    );
  head.hidden = false;
  const screen = route.screen;
  const links = SCREENS.map((s) => {
    const a = el('a', { href: `#/v/${encodeURIComponent(v.id)}/${s.id}`, textContent: s.title });
    if (s.id === screen) a.setAttribute('aria-current', 'page');
    return el('li', {}, a);
  });
  nav.replaceChildren(el('ul', {}, ...links));
  nav.hidden = false;
}

function clearScreen(): void {
  unmount?.();
  unmount = null;
  main.replaceChildren();
}

/** Focus the new screen's heading, so that keyboard and screen reader users start there. */
function focusScreen(section: HTMLElement): void {
  const h = section.querySelector<HTMLElement>('h1, h2');
  if (h) {
    h.tabIndex = -1;
    h.focus({ preventScroll: true });
  } else main.focus({ preventScroll: true });
}

/** Mount the screen the route names, with the venue re-read. */
async function show(reload = false): Promise<void> {
  // an error belongs to the screen it was met on: a new screen starts without it (the status line
  // keeps what a step just said, as "Created venue …" before its floor screen opens)
  alertEl.textContent = '';
  const mine = ++mounting;
  route = parseRoute(location.hash);
  hideBanner();
  if (!api) return signIn();
  signout.hidden = false;
  clearScreen();
  const section = el('section', { className: 'screen' });
  main.append(section);
  if (route.kind === 'venues') {
    venue = null;
    drawHead();
    document.title = 'Venues · omninav admin';
    unmount = venues.mount(section, ctx);
    focusScreen(section);
    return;
  }
  const r = route;
  // every screen starts from the venue as it is now: what it shows is what its writes' If-Match says
  {
    if (reload || !venue || venue.id !== r.id) section.append(el('p', { textContent: `Opening venue ${r.id}…` }));
    try {
      const v = await loadVenue(r.id);
      if (mine !== mounting) return;
      venue = null;
      setVenue(v);
    } catch (e) {
      if (mine !== mounting) return;
      section.replaceChildren(
        el('h2', { textContent: `Venue ${r.id}` }),
        el('p', { textContent: e instanceof Error ? e.message : String(e) }),
        el('p', {}, el('a', { href: '#/venues', textContent: 'Back to the venues' })),
      );
      fail(e, `Opening venue ${r.id}`);
      return;
    }
    section.replaceChildren();
  }
  drawHead();
  const s = SCREENS.find((x) => x.id === r.screen) ?? SCREENS[0];
  document.title = `${s.title} · ${requireVenue().name} · omninav admin`;
  unmount = s.mount(section, ctx);
  focusScreen(section);
}

function signIn(message?: string): void {
  clearScreen();
  venue = null;
  drawHead();
  signout.hidden = true;
  document.title = 'Sign in · omninav admin';
  const section = el('section', { className: 'screen' });
  main.append(section);
  unmount = mountSignIn(section, {
    message,
    announce,
    signedIn: (a) => {
      useApi(a);
      announce('Signed in.');
      void show();
    },
  });
  focusScreen(section);
}

function useApi(a: AdminApi): void {
  api = a;
  a.revisionOf = (id) => (venue && venue.id === id ? venue.revision : null);
  a.onRevision = (id, rev) => {
    if (venue && venue.id === id && rev !== venue.revision) {
      venue = { ...venue, revision: rev };
      drawHead();
    }
  };
  a.onUnauthorised = () => {
    // a token reset elsewhere, or a wrong one: sign in again
    clearToken();
    api = null;
    signIn('The server refused the admin token (it may have been reset). Sign in again.');
  };
}

signout.addEventListener('click', () => {
  clearToken();
  api = null;
  signIn();
  announce('Signed out. The token is forgotten in this tab.');
});

// a change of floor or screen within the open venue keeps the venue as read
window.addEventListener('hashchange', () => void show());

const token = savedToken();
if (token) useApi(new AdminApi(token));
void show();
