/** The about screen: what omninav is (static, in index.html), and what this browser cannot do. */
import { byId } from '../dom';

export interface About {
  /** Say what this browser cannot do for omninav (speak, install for offline use). */
  status(text: string): void;
}

export function aboutScreen(canSpeak: boolean): About {
  const el = byId('app-status');
  const status = (text: string) => {
    el.textContent = text;
  };
  if (!canSpeak) status('This browser cannot speak; answers appear as text and your screen reader reads them.');
  return { status };
}
