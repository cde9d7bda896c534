/**
 * The settings screen: venue, lens profile (or the user's own), direction style, who reads the
 * answers aloud (the app or the user's screen reader), the app's speech rate and voice, vibration,
 * interval, the last second kept ready, and whether keypoints may be sent. Each control edits one preference through one table; the session keeps them and
 * tells every screen.
 */
import { byId, fillSelect } from '../dom';
import { lensProblem, type Lens } from '../../shared/lens';
import type { Prefs } from '../prefs';
import type { Session } from '../session';
import type { Speaker } from '../speech';

/** The part of a form control the binding uses: an input or a select (a fake in tests). */
export interface Control {
  value: string;
  checked?: boolean;
  disabled?: boolean;
  addEventListener(type: 'input' | 'change', fn: () => void): void;
}

/** Where the controls are found: the document, or a fake in tests. */
export interface Controls {
  querySelectorAll(selector: string): Iterable<Control>;
}

/** One control (or radio group) and the preference it edits. */
export interface Setting<K extends keyof Prefs> {
  selector: string;
  key: K;
  /** The event that means "changed": `input` follows a slider while it moves. */
  event: 'input' | 'change';
  read(c: Control): Prefs[K];
  /** Show the preference in the control; absent where the control's options come from elsewhere. */
  show?(c: Control, v: Prefs[K]): void;
}

const setting = <K extends keyof Prefs>(s: Setting<K>): Setting<keyof Prefs> => s;
const text = (c: Control) => c.value;
const num = (c: Control) => Number(c.value);
const showNum = (c: Control, v: number) => (c.value = String(v));
/** A radio group named `name`: its checked button's value is the preference. */
const radios = <K extends 'style' | 'readBy'>(name: string, key: K) =>
  setting<K>({
    selector: `input[name=${name}]`,
    key,
    event: 'change',
    read: (c) => c.value as Prefs[K],
    show: (c, v) => (c.checked = c.value === v),
  });

/** A checkbox: checked is the preference. */
const checkbox = <K extends 'vibrate' | 'ready' | 'keypoints'>(selector: string, key: K) =>
  setting<K>({
    selector,
    key,
    event: 'change',
    read: (c) => (c.checked === true) as Prefs[K],
    show: (c, v) => (c.checked = v),
  });

export const SETTINGS: Setting<keyof Prefs>[] = [
  // venue, lens and voice lists are filled by the session and the speech engine, their choice with them
  setting({ selector: '#venue', key: 'venue', event: 'change', read: text }),
  setting({ selector: '#lens', key: 'lens', event: 'change', read: text }),
  radios('style', 'style'),
  radios('read-by', 'readBy'),
  setting({ selector: '#rate', key: 'rate', event: 'input', read: num, show: showNum }),
  setting({ selector: '#voice', key: 'voice', event: 'change', read: text }),
  checkbox('#vibrate', 'vibrate'),
  setting({ selector: '#interval', key: 'interval', event: 'change', read: num, show: showNum }),
  checkbox('#ready', 'ready'),
  checkbox('#keypoints', 'keypoints'),
];

/** The controls that tune only the app's own voice: off while the screen reader reads instead. */
export const APP_VOICE_CONTROLS = ['#rate', '#voice'];

export function showAppVoiceControls(root: Controls, prefs: Prefs): void {
  const off = prefs.readBy === 'screen-reader';
  for (const sel of APP_VOICE_CONTROLS) for (const c of root.querySelectorAll(sel)) c.disabled = off;
}

/**
 * Wire each control to its preference: a change is `set`; returns a function that shows the
 * preferences in the controls.
 */
export function bindSettings(
  root: Controls,
  prefs: Prefs,
  set: <K extends keyof Prefs>(key: K, value: Prefs[K]) => void,
  table: Setting<keyof Prefs>[] = SETTINGS,
): () => void {
  for (const s of table)
    for (const c of root.querySelectorAll(s.selector)) c.addEventListener(s.event, () => set(s.key, s.read(c)));
  return () => {
    for (const s of table) if (s.show) for (const c of root.querySelectorAll(s.selector)) s.show(c, prefs[s.key]);
  };
}

export function settingsScreen(session: Session, speaker: Speaker): void {
  const { prefs } = session;
  const venue = byId<HTMLSelectElement>('venue');
  const lens = byId<HTMLSelectElement>('lens');
  const voice = byId<HTMLSelectElement>('voice');
  // the rate shown beside its label, and said by the slider itself: an <output> is a status
  // region, which a screen reader announced at every step of the slider, over the slider's own value
  const rateValue = byId('rate-value');
  const rate = byId<HTMLInputElement>('rate');
  const controls: Controls = {
    querySelectorAll: (sel) => document.querySelectorAll<HTMLInputElement | HTMLSelectElement>(sel),
  };
  const showControls = bindSettings(controls, prefs, (k, v) => session.set(k, v));

  /** The preferences into the speaker and onto the controls. */
  function apply(): void {
    speaker.screenReader = prefs.readBy === 'screen-reader';
    speaker.rate = prefs.rate;
    speaker.voiceName = prefs.voice;
    speaker.cues = prefs.vibrate;
    showControls();
    showAppVoiceControls(controls, prefs);
    rateValue.textContent = prefs.rate.toFixed(1);
    rate.setAttribute('aria-valuetext', `${prefs.rate.toFixed(1)} times`);
  }

  function fillVoices(): void {
    const voices = speaker.voices().filter((v) => v.lang.startsWith('en') || v.default);
    fillSelect(
      voice,
      [['', 'The phone’s default voice'], ...voices.map((v): [string, string] => [v.name, `${v.name} (${v.lang})`])],
      prefs.voice,
    );
  }

  async function loadMyLens(file: File): Promise<void> {
    let mine: unknown;
    try {
      mine = JSON.parse(await file.text());
    } catch {
      speaker.say(`${file.name} is not a lens profile: it is not JSON.`, 'error', true);
      return;
    }
    const bad = lensProblem(mine);
    if (bad) {
      speaker.say(`${file.name} is not a usable lens profile: ${bad}.`, 'error', true);
      return;
    }
    session.useMyLens(mine as Lens);
    speaker.say(`Loaded your lens profile from ${file.name}; it is now the lens in use.`, 'ok');
  }

  session.on('venues', ({ list, chosen }) =>
    fillSelect(
      venue,
      list.map((v) => [v.id, v.name]),
      chosen,
    ),
  );
  session.on('lenses', ({ names, chosen }) =>
    fillSelect(
      lens,
      names.map((n) => [n, n]),
      chosen,
    ),
  );
  session.on('pref', apply);
  byId<HTMLInputElement>('lens-file').addEventListener('change', (e) => {
    const f = (e.target as HTMLInputElement).files?.[0];
    if (f) void loadMyLens(f);
  });
  byId('test-speech').addEventListener('click', () =>
    speaker.say('This is how omninav sounds. The lifts at 3 o’clock, 4 metres.'),
  );
  if (speaker.available) {
    fillVoices();
    speechSynthesis.addEventListener?.('voiceschanged', fillVoices);
  }
  apply();
}
