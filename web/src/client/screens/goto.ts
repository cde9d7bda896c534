/**
 * The "Go to…" screen (issue 14): the venue's destinations as buttons under a heading per floor,
 * filtered by typing or by voice (where the browser has speech recognition); a chosen place's
 * route previewed in words, then Start, What next? and Stop guidance; the instruction, the
 * distances and the plan with the route and the way walked. The guide (guide.ts) does the work;
 * this screen shows what it reports. What is spoken goes through the Speaker and its live
 * regions, as on the locate screen; the filter's count has its own status line, read by screen
 * readers only (it is not worth speaking aloud on every key).
 */
import {
  ApiProblem,
  Unreachable,
  destinations as fetchDestinations,
  type Destination,
  type Destinations,
} from '../api';
import type { Venue } from '../api';
import { byId, facts } from '../dom';
import type { Guide, GuideState } from '../guide';
import { problemText } from '../problems';
import type { Session } from '../session';
import type { Speaker } from '../speech';
import { PlanView, type PlanRoute } from '../views/plan';

/** A floor's places that pass the filter. */
export interface Group {
  floor: { id: string; name: string };
  places: Destination[];
}

/** Lower case, no accents, punctuation as spaces: "Room 1.02 (Café)" -> "room 1 02 cafe". */
export function normalise(s: string): string {
  return s
    .normalize('NFD')
    .replace(/\p{M}/gu, '')
    .toLowerCase()
    .replace(/[^\p{L}\p{N}]+/gu, ' ')
    .trim();
}

const words = (s: string): string[] => normalise(s).split(' ').filter(Boolean);

/** The words a place is found by: its name, and its kind ("toilet", "lift", "exit"...). */
function placeWords(p: Destination): string[] {
  return [...words(p.name), ...(p.kind && p.kind !== 'other' ? [p.kind] : [])];
}

/**
 * Whether a place passes the filter: every word typed (or said) starts one of its words, or one of
 * its words starts the typed one ("lifts" finds "the lift", "1" finds "Room 102"). "the" and
 * "a" are left out of what is typed, as people say "the lifts" for "Lifts".
 */
export function matches(p: Destination, query: string): boolean {
  const want = words(query).filter((w) => !['the', 'a', 'an', 'to'].includes(w));
  if (!want.length) return true;
  const have = placeWords(p);
  return want.every((w) => have.some((h) => h.startsWith(w) || (h.length >= 3 && w.startsWith(h))));
}

/** The destinations by floor (the server's order: floors as the venue has them, places by name), filtered. */
export function groups(d: Destinations, query = ''): Group[] {
  return d.floors
    .map((f) => ({ floor: { id: f.id, name: f.name }, places: f.places.filter((p) => matches(p, query)) }))
    .filter((g) => g.places.length > 0);
}

/** The one place the filter lists, or null when it lists none or several (Enter in the filter chooses it). */
export function onlyPlace(d: Destinations, query: string): Destination | null {
  const found = groups(d, query).flatMap((g) => g.places);
  return found.length === 1 ? found[0] : null;
}

const count = (gs: Group[]): number => gs.reduce((n, g) => n + g.places.length, 0);
const placesWord = (n: number): string => (n === 1 ? '1 place' : `${n} places`);

/** How long the typing pauses before the filter's count is said. */
const COUNT_QUIET_MS = 600;
/** The filter's status line: how many places are listed. */
export function countLine(d: Destinations, query: string): string {
  const total = count(groups(d));
  if (!total) return 'No places to go to in this venue yet.';
  const shown = count(groups(d, query));
  if (!normalise(query)) return `${placesWord(total)} to go to.`;
  if (!shown) return `No place matches “${query.trim()}”.`;
  return `${shown} of ${placesWord(total)} match “${query.trim()}”.`;
}

/**
 * What a voice filter heard -> the filter text: the first of the recogniser's alternatives that
 * finds a place, else the first one (the list then says nothing matches).
 */
export function pickHeard(alternatives: string[], d: Destinations): string {
  const heard = alternatives.map((a) => a.trim()).filter(Boolean);
  return heard.find((a) => count(groups(d, a)) > 0) ?? heard[0] ?? '';
}

/** What is said after a voice filter: how many places match, and their names when they are few. */
export function heardLine(d: Destinations, heard: string): string {
  const gs = groups(d, heard);
  const n = count(gs);
  if (!n) return `No place matches “${heard}”. Press Say a place to try again, or type it.`;
  const names = gs.flatMap((g) => g.places.map((p) => (d.floors.length > 1 ? `${p.name}, ${g.floor.name}` : p.name)));
  if (n === 1) return `${names[0]}. Press it to hear the way.`;
  return `${n} places match “${heard}”${n <= 5 ? `: ${names.join('; ')}` : ''}.`;
}

/** The browser's speech recogniser class, where there is one (Chrome: webkit-prefixed). */
interface Recognition {
  lang: string;
  interimResults: boolean;
  maxAlternatives: number;
  onresult: ((e: { results: ArrayLike<ArrayLike<{ transcript: string }>> }) => void) | null;
  onerror: ((e: { error: string }) => void) | null;
  onend: (() => void) | null;
  start(): void;
  stop(): void;
}
type RecognitionClass = new () => Recognition;

export function recognitionClass(g: object = globalThis): RecognitionClass | null {
  const w = g as { SpeechRecognition?: RecognitionClass; webkitSpeechRecognition?: RecognitionClass };
  return w.SpeechRecognition ?? w.webkitSpeechRecognition ?? null;
}

const VOICE_PROBLEMS: Record<string, string> = {
  'not-allowed':
    'The microphone is blocked for omninav. Type the place instead, or allow the microphone in the browser’s site settings.',
  'service-not-allowed': 'This browser cannot listen here. Type the place instead.',
  'no-speech': 'I heard nothing. Press Say a place, then say the place’s name.',
  network: 'Listening needs the network here. Type the place instead.',
};

/** What the screen shows of the guide's state: which buttons work, and the line under the route's title. */
export function controls(state: GuideState, hasInstruction: boolean): { start: boolean; next: boolean; stop: boolean } {
  return {
    start: state === 'ready' || state === 'stopped' || state === 'arrived',
    next: hasInstruction && state !== 'idle' && state !== 'previewing',
    stop: state === 'previewing' || state === 'ready' || state === 'guiding',
  };
}

const STATE_LINES: Record<GuideState, string> = {
  idle: '',
  previewing: 'Finding the way…',
  ready: 'Press Start when you are ready to walk.',
  guiding: 'Guiding you. Hold the phone upright with the lens on top.',
  arrived: 'You have arrived.',
  stopped: 'Guidance stopped.',
};

export function gotoScreen(session: Session, speaker: Speaker, guide: Guide): void {
  const filter = byId<HTMLInputElement>('goto-filter');
  const voiceBtn = byId<HTMLButtonElement>('goto-voice');
  const status = byId('goto-status');
  const list = byId('goto-list');
  const route = byId('goto-route');
  const routeTitle = byId('goto-route-title');
  const preview = byId('goto-preview');
  const stateLine = byId('goto-state');
  const start = byId<HTMLButtonElement>('goto-start');
  const next = byId<HTMLButtonElement>('goto-next');
  const stop = byId<HTMLButtonElement>('goto-stop');
  const routeFacts = byId('goto-facts');
  const plan = new PlanView(byId<HTMLCanvasElement>('goto-plan'));
  routeTitle.tabIndex = -1; // it takes the focus when a place is chosen

  let dests: Destinations | null = null;
  const chosen = (id: string): boolean => guide.place?.id === id && guide.state !== 'idle';
  let loadedFor = '';
  /** The venue of the chosen place's route. */
  let guidedIn = '';
  let walked: [number, number][] = [];
  let walkedFloor = '';

  // what the list shows now: re-made only when it changes, so that a focused place keeps the focus
  let shown: { d: Destinations; q: string } | null = null;

  let typing = false;
  let countTimer: ReturnType<typeof setTimeout> | undefined;
  /** The list for the filter; when only the chosen place changed, only its mark moves. */
  function render(): void {
    if (!dests) return;
    const q = filter.value;
    if (shown && shown.d === dests && shown.q === q) {
      for (const b of list.querySelectorAll<HTMLButtonElement>('button.dest'))
        if (chosen(b.dataset.place!)) b.setAttribute('aria-current', 'true');
        else b.removeAttribute('aria-current');
      return;
    }
    shown = { d: dests, q };
    // said once the typing pauses: a screen reader reading the count after every letter talks
    // over the letters being echoed
    const line = countLine(dests, q);
    clearTimeout(countTimer);
    if (typing) countTimer = setTimeout(() => (status.textContent = line), COUNT_QUIET_MS);
    else status.textContent = line;
    const blocks = groups(dests, q).map((g, i) => {
      const h = document.createElement('h4');
      h.id = `goto-floor-${i}`;
      h.textContent = g.floor.name;
      const ul = document.createElement('ul');
      ul.className = 'places';
      ul.setAttribute('aria-labelledby', h.id);
      for (const p of g.places) {
        const li = document.createElement('li');
        const b = document.createElement('button');
        b.type = 'button';
        b.className = 'dest';
        b.dataset.place = p.id;
        b.textContent = p.name;
        if (chosen(p.id)) b.setAttribute('aria-current', 'true');
        b.addEventListener('click', () => choose(p));
        li.append(b);
        ul.append(li);
      }
      return [h, ul];
    });
    list.replaceChildren(...blocks.flat());
  }

  async function load(v: Venue): Promise<void> {
    loadedFor = v.id;
    dests = null;
    list.replaceChildren();
    if (!v.modelled) {
      status.textContent = 'This venue is not modelled yet, so there are no places to go to.';
      return;
    }
    status.textContent = 'Loading the places…';
    try {
      const d = await fetchDestinations(v.id);
      if (loadedFor !== v.id) return;
      dests = d;
      render();
    } catch (e) {
      if (loadedFor !== v.id) return;
      loadedFor = ''; // try again when the screen is shown next
      status.textContent =
        e instanceof ApiProblem && e.status === 409
          ? 'This venue is not modelled yet, so there are no places to go to.'
          : e instanceof Unreachable
            ? e.message
            : `The places did not load: ${problemText(e)}`;
    }
  }

  function choose(p: Destination): void {
    // "Keep telling me" and guidance both film: guidance takes over
    if (session.continuous) session.stopContinuous();
    walked = [];
    guidedIn = session.venue?.id ?? '';
    routeTitle.textContent = `Route to ${p.name}`;
    preview.textContent = '';
    routeFacts.replaceChildren();
    route.hidden = false;
    routeTitle.focus();
    void guide.choose({ id: p.id, name: p.name });
    render();
  }

  /** A button that is switched off while it has the focus hands the focus on, so it is not lost. */
  function enable(b: HTMLButtonElement, on: boolean, fallback: HTMLElement): void {
    const had = document.activeElement === b;
    b.disabled = !on;
    if (had && !on) fallback.focus();
  }

  function showState(state: GuideState): void {
    const c = controls(state, guide.latest !== null);
    enable(start, c.start, next.disabled ? routeTitle : next);
    enable(next, c.next, routeTitle);
    enable(stop, c.stop, start.disabled ? routeTitle : start);
    stateLine.textContent = STATE_LINES[state];
    // stopped: no "Now" left standing of a walk that is no longer guided
    if (state === 'stopped' || state === 'idle') routeFacts.replaceChildren();
    route.classList.toggle('guiding', state === 'guiding');
    render();
  }

  start.addEventListener('click', () => {
    if (session.continuous) session.stopContinuous();
    walked = [];
    guide.start(); // asks for the motion sensors: still inside this tap
    if (!next.disabled) next.focus();
  });
  next.addEventListener('click', () => guide.whatNext());
  stop.addEventListener('click', () => guide.stop());
  filter.addEventListener('input', () => {
    typing = true;
    render();
    typing = false;
  });
  // Enter: the one place listed is chosen; of several, the first takes the focus
  filter.addEventListener('keydown', (e) => {
    if (e.key !== 'Enter' || !dests) return;
    e.preventDefault();
    const one = onlyPlace(dests, filter.value);
    if (one) choose(one);
    else list.querySelector<HTMLButtonElement>('button.dest')?.focus();
  });

  guide.on('state', showState);
  guide.on('problem', (text) => {
    if (text) stateLine.textContent = text;
    else showState(guide.state);
  });
  guide.on('guidance', ({ guidance: g, answer: a }) => {
    if (guide.state === 'stopped' || guide.state === 'idle') return; // an answer still on its way
    const v = session.venue;
    preview.textContent = guide.previewText || (g.kind === 'unsure' ? 'Not sure where you are yet.' : '');
    const rows: [string, string][] = [['Now', g.kind === 'unsure' ? 'Not sure where you are yet.' : guide.words(g)]];
    if (g.remaining_m !== null) rows.push(['To go', `${Math.round(g.remaining_m)} m`]);
    if (g.next_turn_m !== null && g.kind !== 'arrived') rows.push(['Next turn', `in ${Math.round(g.next_turn_m)} m`]);
    if (g.floor_change) rows.push(['Floor change', `${g.floor_change.via} to ${g.floor_change.to_floor_name}`]);
    rows.push(['On the route', g.on_route ? 'yes' : 'no']);
    facts(routeFacts, rows);
    if (!v) return;
    // the way walked: the filtered positions of this guidance on the floor shown
    if (!a.low_confidence && guide.state === 'guiding') {
      if (walkedFloor !== a.floor) walked = [];
      walkedFloor = a.floor;
      walked.push([a.x, a.y]);
      if (walked.length > 600) walked.shift();
    }
    const floor = v.floors.find((f) => f.id === a.floor);
    const to = dests?.floors.find((f) => f.id === g.to.floor)?.places.find((p) => p.id === g.to.id);
    const r: PlanRoute = {
      ahead: g.route,
      walked: walkedFloor === a.floor ? walked : [],
      to: to && g.to.floor === a.floor ? { name: to.name, x: to.x, y: to.y } : null,
      remaining_m: g.remaining_m,
      toName: g.to.name,
    };
    void plan.show(
      floor,
      v.places.filter((p) => p.floor === a.floor),
      a,
      r,
    );
  });

  // the destinations follow the venue in use; a failed load is tried again when the screen is shown
  session.on('venue', (v) => {
    // another venue: a route in the one before means nothing here
    if (guidedIn && guidedIn !== v.id) {
      guide.stop();
      route.hidden = true;
      guidedIn = '';
    }
    void load(v);
  });
  // no venue at all (the server unreachable, none there): the reason, instead of "Loading"
  session.on('line', (text) => {
    if (!session.venue && !dests) status.textContent = text;
  });
  for (const tab of document.querySelectorAll<HTMLButtonElement>('.tab[data-screen=goto]'))
    tab.addEventListener('click', () => {
      if (session.venue && loadedFor !== session.venue.id) void load(session.venue);
    });

  const Rec = recognitionClass();
  voiceBtn.hidden = Rec === null;
  let listening: Recognition | null = null;
  voiceBtn.addEventListener('click', () => {
    if (!Rec) return;
    if (listening) {
      listening.stop();
      return;
    }
    const rec = new Rec();
    rec.lang = document.documentElement.lang || 'en';
    rec.interimResults = false;
    rec.maxAlternatives = 5;
    rec.onresult = (e) => {
      const alts = Array.from(e.results[0] ?? [], (r) => r.transcript);
      if (!dests) return;
      const heard = pickHeard(alts, dests);
      filter.value = heard;
      render();
      speaker.say(heardLine(dests, heard), null, false, false);
      // one place heard: its button takes the focus, one tap away
      const only = groups(dests, heard);
      if (count(only) === 1) list.querySelector<HTMLButtonElement>('button.dest')?.focus();
    };
    rec.onerror = (e) => {
      const text = VOICE_PROBLEMS[e.error];
      if (text) speaker.say(text, 'error', true, false);
    };
    rec.onend = () => {
      listening = null;
      voiceBtn.setAttribute('aria-pressed', 'false');
    };
    try {
      rec.start();
      listening = rec;
      voiceBtn.setAttribute('aria-pressed', 'true');
      speaker.cue('start');
    } catch {
      speaker.say(VOICE_PROBLEMS['service-not-allowed'], 'error', true, false);
    }
  });
}
