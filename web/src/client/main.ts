/**
 * The app: one big "Where am I?" control; the answer spoken, in the live region, as text and on
 * the floor plan. Image work happens in the feature worker; this thread stays free for speech and
 * the screen reader.
 */
import './style.css';
import {
  ApiProblem,
  UNREACHABLE,
  Unreachable,
  locate,
  venue as fetchVenue,
  venues as fetchVenues,
  type Venue,
} from './api';
import { CameraProblem, captureClip, lensMismatch, openCamera } from './camera';
import { describe, gist, type Answer, type Style } from './directions';
import { ExtractorClient } from './bridge';
import { lensProblem, type Lens } from '../shared/lens';
import { encodeRecord, HEADER_BYTES } from '../shared/record';
import { askMotion, onShake, onTwoFingerDoubleTap } from './gestures';
import { drawPlan } from './plan';
import { loadPrefs, savePrefs, type Prefs } from './prefs';
import { Speaker } from './speech';

const CLIP_FRAMES = 10; // ~1 s at 10 fps: enough for the clip to outvote a single wrong frame
const CLIP_INTERVAL_MS = 100;
const NO_FRAMES =
  'This venue has no modelled frames yet, so omninav cannot tell where you are here. Ask the venue’s administrator to upload and model a video of it.';
const NO_LENS = 'This venue has no lens profile yet. Ask the venue’s administrator to add the lens it was filmed with.';

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
const ui = {
  where: $<HTMLButtonElement>('where'),
  repeat: $<HTMLButtonElement>('repeat'),
  continuous: $<HTMLButtonElement>('continuous'),
  venueLine: $('venue-line'),
  answerText: $('answer-text'),
  answerFacts: $('answer-facts'),
  plan: $<HTMLCanvasElement>('plan'),
  debugFacts: $('debug-facts'),
  video: $<HTMLVideoElement>('camera'),
  venue: $<HTMLSelectElement>('venue'),
  lens: $<HTMLSelectElement>('lens'),
  rate: $<HTMLInputElement>('rate'),
  rateValue: $<HTMLOutputElement>('rate-value'),
  voice: $<HTMLSelectElement>('voice'),
  vibrate: $<HTMLInputElement>('vibrate'),
  interval: $<HTMLSelectElement>('interval'),
  appStatus: $('app-status'),
};

const prefs: Prefs = loadPrefs();
const speaker = new Speaker($('live'), $('alert'));
let ext: ExtractorClient | null = null;
let current: Venue | null = null;
let stream: MediaStream | null = null;
let busy = false;
let continuous: number | null = null;
let lastGist = '';
let lastAnswer: Answer | null = null;

function facts(dl: HTMLElement, rows: [string, string][]): void {
  dl.replaceChildren(
    ...rows.flatMap(([k, v]) => {
      const dt = document.createElement('dt');
      dt.textContent = k;
      const dd = document.createElement('dd');
      dd.textContent = v;
      return [dt, dd];
    }),
  );
}

const MY_LENS = 'my lens';

/** The venue's lens profiles, and the user's own one when they loaded it. */
function lensesOf(v: Venue): Record<string, Lens> {
  return prefs.myLens ? { ...v.lenses, [MY_LENS]: prefs.myLens } : v.lenses;
}

function chosenLens(v: Venue): [string, Lens] | null {
  const all = lensesOf(v);
  const names = Object.keys(all);
  const name = names.includes(prefs.lens) ? prefs.lens : names[0];
  return name ? [name, all[name]] : null;
}

async function loadMyLens(file: File): Promise<void> {
  let lens: unknown;
  try {
    lens = JSON.parse(await file.text());
  } catch {
    speaker.say(`${file.name} is not a lens profile: it is not JSON.`, 'error', true);
    return;
  }
  const bad = lensProblem(lens);
  if (bad) {
    speaker.say(`${file.name} is not a usable lens profile: ${bad}.`, 'error', true);
    return;
  }
  prefs.myLens = lens as Lens;
  prefs.lens = MY_LENS;
  savePrefs(prefs);
  if (current)
    fillSelect(
      ui.lens,
      Object.keys(lensesOf(current)).map((n) => [n, n]),
      MY_LENS,
    );
  speaker.say(`Loaded your lens profile from ${file.name}; it is now the lens in use.`, 'ok');
}

function fillSelect(sel: HTMLSelectElement, items: [string, string][], value: string): void {
  sel.replaceChildren(...items.map(([v, label]) => new Option(label, v, false, v === value)));
}

/** Load the chosen venue (or the first); start the feature worker on its lens meanwhile. */
async function loadVenue(): Promise<Venue | null> {
  try {
    const list = await fetchVenues();
    if (!list.length) {
      ui.venueLine.textContent = 'This server has no venues yet.';
      return null;
    }
    const want = new URLSearchParams(location.search).get('venue') || prefs.venue;
    const id = list.some((v) => v.id === want) ? want : list[0].id;
    fillSelect(
      ui.venue,
      list.map((v) => [v.id, v.name]),
      id,
    );
    const v = await fetchVenue(id);
    current = v;
    prefs.venue = id;
    const lens = chosenLens(v);
    fillSelect(
      ui.lens,
      Object.keys(lensesOf(v)).map((n) => [n, n]),
      lens?.[0] ?? '',
    );
    const missing = want && want !== id ? `This server has no venue “${want}”; showing ${v.name} instead. ` : '';
    ui.venueLine.textContent =
      missing +
      (v.modelled ? `Venue: ${v.name}. Ready (${v.frames} modelled frames).` : `Venue: ${v.name}. Not modelled yet.`);
    if (lens) {
      ext ??= new ExtractorClient();
      ext.configure(lens[1], v.features.settings).catch(() => undefined); // warm up; errors surface on use
    }
    void drawPlan(ui.plan, v.floors[0], v.places, null).then((label) => ui.plan.setAttribute('aria-label', label));
    return v;
  } catch (e) {
    ui.venueLine.textContent =
      e instanceof Unreachable ? UNREACHABLE : `The venue did not load: ${(e as Error).message}`;
    return null;
  }
}

function problemText(e: unknown): string {
  if (e instanceof Unreachable || e instanceof CameraProblem) return e.message;
  if (e instanceof ApiProblem) {
    if (e.status === 409) return NO_FRAMES;
    if (e.status === 429) return 'Too many questions at once. Wait a moment, then press Where am I? again.';
    if (e.status === 404) return 'This venue is no longer on the server. Choose another venue in Settings.';
    return `The server could not answer: ${e.message}`;
  }
  return `Something went wrong: ${(e as Error).message ?? e}`;
}

/** Show an answer as text, facts and on the plan; returns the sentence to speak. */
function show(a: Answer, v: Venue): string {
  lastAnswer = a;
  const floor = v.floors.find((f) => f.id === a.floor);
  const text = describe(a, prefs.style as Style, floor?.name);
  ui.answerText.textContent = text;
  const rows: [string, string][] = [];
  if (!a.low_confidence) {
    if (a.area) rows.push(['In', a.area]);
    if (a.nearest) rows.push(['Nearest place', `${a.nearest.name}, ${a.nearest.distance_m.toFixed(0)} m`]);
    if (a.facing) rows.push(['Facing', a.facing]);
    rows.push(['Floor', floor?.name ?? a.floor]);
    if (a.accuracy_m) rows.push(['Accuracy', `about ${a.accuracy_m} m`]);
  }
  rows.push(['Confidence', `${Math.round(a.confidence * 100)} %`]);
  facts(ui.answerFacts, rows);
  ui.repeat.disabled = false;
  // the plan image may still be loading: speech must not wait for it
  void drawPlan(
    ui.plan,
    floor,
    v.places.filter((p) => p.floor === a.floor),
    a,
  ).then((label) => ui.plan.setAttribute('aria-label', label));
  return text;
}

/** One "Where am I?": capture ~1 s, extract in the worker, send features only, say the answer. */
async function whereAmI(quietIfSame = false): Promise<void> {
  if (busy) return;
  busy = true;
  ui.where.setAttribute('aria-busy', 'true');
  ui.where.textContent = 'Locating…';
  try {
    // a venue not modelled yet may have been since: ask the server again rather than the cache
    const v = current?.modelled ? current : await loadVenue();
    if (!v) throw new Unreachable(ui.venueLine.textContent || UNREACHABLE);
    if (!v.modelled) throw new ApiProblem(409, NO_FRAMES);
    const lens = chosenLens(v);
    if (!lens) throw new ApiProblem(422, NO_LENS);
    ext ??= new ExtractorClient();
    const ready = ext.configure(lens[1], v.features.settings);
    // a stream ends when the phone locks or another app takes the camera: open it again
    if (stream?.getVideoTracks().every((t) => t.readyState === 'ended')) stream = null;
    stream ??= await openCamera(ui.video, lens[1]);
    const bad = lensMismatch(ui.video.videoWidth, ui.video.videoHeight, lens[1], lens[0]);
    if (bad) throw new CameraProblem('lens', bad);
    await ready;
    if (!quietIfSame) speaker.cue('start');
    const clip = await captureClip(ui.video, ext, CLIP_FRAMES, CLIP_INTERVAL_MS);
    const record = encodeRecord(clip.frames, v.features.settings, v.features.settings_id);
    const t0 = performance.now();
    const a = await locate(v.id, record, clip.fps, `web-${Date.now()}`);
    const rtt = performance.now() - t0;
    const sentence = show(a, v);
    const ms = clip.frames.map((f) => f.ms).sort((x, y) => x - y);
    facts(ui.debugFacts, [
      ['Sent', `features only: ${record.length} bytes for ${clip.frames.length} frames`],
      ['Bytes per frame', String((record.length - HEADER_BYTES) / clip.frames.length)],
      ['Camera', `${ui.video.videoWidth} x ${ui.video.videoHeight}, lens ${lens[0]}, ${clip.fps.toFixed(1)} frames/s`],
      ['Extraction', `${ms[ms.length >> 1].toFixed(1)} ms per frame (median)`],
      ['Server round trip', `${rtt.toFixed(0)} ms`],
      ['Position', `x ${a.x.toFixed(2)} m, y ${a.y.toFixed(2)} m, heading ${a.heading_deg.toFixed(1)}°`],
      ['Confidence', a.confidence.toFixed(3)],
    ]);
    const g = gist(a, prefs.style as Style);
    if (!quietIfSame || g !== lastGist) speaker.say(sentence, a.low_confidence ? 'unsure' : 'ok');
    lastGist = g;
  } catch (e) {
    // the venue changed under us (re-modelled with other settings, emptied): reload it next time
    if (e instanceof ApiProblem && (e.status === 400 || e.status === 409)) current = null;
    const text = problemText(e);
    if (!quietIfSame || lastGist !== text) speaker.say(text, 'error', true);
    lastGist = text;
    if (e instanceof CameraProblem && e.kind !== 'lens') stopContinuous();
  } finally {
    busy = false;
    ui.where.removeAttribute('aria-busy');
    ui.where.textContent = 'Where am I?';
  }
}

function stopContinuous(): void {
  if (continuous !== null) clearTimeout(continuous);
  continuous = null;
  ui.continuous.setAttribute('aria-pressed', 'false');
}

function toggleContinuous(): void {
  if (continuous !== null) {
    stopContinuous();
    speaker.say('Stopped telling you.', null);
    return;
  }
  ui.continuous.setAttribute('aria-pressed', 'true');
  lastGist = '';
  const tick = async () => {
    // never talk over itself: wait while a sentence is still being spoken
    if (!speaker.busy) await whereAmI(true);
    if (continuous !== null) continuous = window.setTimeout(tick, prefs.interval * 1000);
  };
  continuous = window.setTimeout(tick, 0);
}

function firstGesture(): void {
  speaker.prime();
  void askMotion();
}

function showScreen(name: string): void {
  for (const b of document.querySelectorAll<HTMLButtonElement>('.tab')) {
    if (b.dataset.screen === name) b.setAttribute('aria-current', 'page');
    else b.removeAttribute('aria-current');
  }
  for (const s of document.querySelectorAll<HTMLElement>('.screen')) s.hidden = s.id !== `screen-${name}`;
  document.querySelector<HTMLElement>(`#screen-${name} h2`)?.focus();
}

function applyPrefs(): void {
  speaker.rate = prefs.rate;
  speaker.voiceName = prefs.voice;
  speaker.cues = prefs.vibrate;
  ui.rate.value = String(prefs.rate);
  ui.rateValue.textContent = prefs.rate.toFixed(1);
  ui.vibrate.checked = prefs.vibrate;
  ui.interval.value = String(prefs.interval);
  for (const r of document.querySelectorAll<HTMLInputElement>('input[name=style]')) r.checked = r.value === prefs.style;
}

function fillVoices(): void {
  const voices = speaker.voices().filter((v) => v.lang.startsWith('en') || v.default);
  fillSelect(
    ui.voice,
    [['', 'The phone’s default voice'], ...voices.map((v): [string, string] => [v.name, `${v.name} (${v.lang})`])],
    prefs.voice,
  );
}

function wire(): void {
  document.addEventListener('pointerdown', firstGesture, { once: true, capture: true });
  document.addEventListener('keydown', firstGesture, { once: true, capture: true });
  ui.where.addEventListener('click', () => void whereAmI());
  ui.repeat.addEventListener('click', () => speaker.repeat());
  ui.continuous.addEventListener('click', toggleContinuous);
  for (const b of document.querySelectorAll<HTMLButtonElement>('.tab'))
    b.addEventListener('click', () => showScreen(b.dataset.screen!));
  for (const h of document.querySelectorAll<HTMLElement>('.screen h2')) h.tabIndex = -1;
  onShake(() => void whereAmI());
  onTwoFingerDoubleTap(document.body, () => void whereAmI());
  const save = () => savePrefs(prefs);
  ui.venue.addEventListener('change', () => {
    prefs.venue = ui.venue.value;
    save();
    current = null;
    void loadVenue();
  });
  ui.lens.addEventListener('change', () => {
    prefs.lens = ui.lens.value;
    save();
  });
  $<HTMLInputElement>('lens-file').addEventListener('change', (e) => {
    const f = (e.target as HTMLInputElement).files?.[0];
    if (f) void loadMyLens(f);
  });
  ui.rate.addEventListener('input', () => {
    prefs.rate = Number(ui.rate.value);
    applyPrefs();
    save();
  });
  ui.voice.addEventListener('change', () => {
    prefs.voice = ui.voice.value;
    applyPrefs();
    save();
  });
  ui.vibrate.addEventListener('change', () => {
    prefs.vibrate = ui.vibrate.checked;
    applyPrefs();
    save();
  });
  ui.interval.addEventListener('change', () => {
    prefs.interval = Number(ui.interval.value);
    save();
  });
  for (const r of document.querySelectorAll<HTMLInputElement>('input[name=style]'))
    r.addEventListener('change', () => {
      prefs.style = r.value as Style;
      save();
      if (lastAnswer && current) show(lastAnswer, current);
    });
  $('test-speech').addEventListener('click', () =>
    speaker.say('This is how omninav sounds. The lifts at 3 o’clock, 4 metres.'),
  );
  if (speaker.available) {
    fillVoices();
    speechSynthesis.addEventListener?.('voiceschanged', fillVoices);
  } else {
    ui.appStatus.textContent = 'This browser cannot speak; answers appear as text and your screen reader reads them.';
  }
}

async function registerServiceWorker(): Promise<void> {
  if (!('serviceWorker' in navigator)) return;
  try {
    const { registerSW } = await import('virtual:pwa-register');
    registerSW({ immediate: true });
  } catch {
    ui.appStatus.textContent = 'This browser did not install omninav for offline use.';
  }
}

wire();
applyPrefs();
void registerServiceWorker();
void loadVenue();
