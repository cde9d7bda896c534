/** The user's settings, kept on the phone (localStorage). */
import type { Style } from './directions';
import type { Lens } from '../shared/lens';

/**
 * Who reads the answers aloud: the app in its own voice (works for everyone), or the user's screen
 * reader from the live regions, the app silent (else both would speak at once).
 */
export type ReadBy = 'app' | 'screen-reader';

export interface Prefs {
  venue: string;
  lens: string;
  style: Style;
  readBy: ReadBy;
  rate: number;
  voice: string;
  vibrate: boolean;
  interval: number;
  /** A lens profile the user loaded (their phone's own calibration), offered beside the venue's. */
  myLens: Lens | null;
  /**
   * Keep the last second ready while the camera is open (standby.ts): "Where am I?" answers at
   * once, for about a tenth of a core the while.
   */
  ready: boolean;
  /**
   * Send the keypoints of a clip's last frame where the venue verifies answers with them (a
   * `verified` venue): surer answers, at the cost of a little more of the scene leaving the phone
   * (README, Privacy). Off until the user turns it on.
   */
  keypoints: boolean;
}

const KEY = 'omninav.prefs';
export const DEFAULTS: Prefs = {
  venue: '',
  lens: '',
  style: 'clock',
  readBy: 'app',
  rate: 1,
  voice: '',
  vibrate: true,
  interval: 3,
  myLens: null,
  ready: true,
  keypoints: false,
};

export function loadPrefs(): Prefs {
  try {
    const raw = JSON.parse(localStorage.getItem(KEY) ?? '{}');
    return { ...DEFAULTS, ...(typeof raw === 'object' && raw ? raw : {}) };
  } catch {
    return { ...DEFAULTS };
  }
}

export function savePrefs(p: Prefs): void {
  try {
    localStorage.setItem(KEY, JSON.stringify(p));
  } catch {
    // private browsing may refuse storage: the settings then last for this visit
  }
}
