/**
 * The app: one big "Where am I?" control; the answer spoken, in the live region, as text and on
 * the floor plan; "Go to" guides the user to a chosen place. Image work happens in the feature
 * worker; this thread stays free for speech and the screen reader. This module only wires the
 * session and the guide to the screens.
 */
import './style.css';
import { byId } from './dom';
import { askMotion, onShake, onTwoFingerDoubleTap } from './gestures';
import { guidanceSentence, previewSentence } from './directions';
import { Guide } from './guide';
import { MotionFeed } from './motion';
import { loadPrefs, savePrefs } from './prefs';
import { routeTabs } from './router';
import { aboutScreen, type About } from './screens/about';
import { gotoScreen } from './screens/goto';
import { locateScreen } from './screens/locate';
import { settingsScreen } from './screens/settings';
import { Session } from './session';
import { Speaker } from './speech';
import { Posture } from './standby';
import { ScreenLock } from './wakelock';

const speaker = new Speaker(byId('live'), byId('alert'));
const posture = new Posture();
/** A screen that uses the camera is shown. */
const cameraScreen = (): boolean => ['screen-locate', 'screen-goto'].some((id) => byId(id).hidden === false);
const session = new Session({
  prefs: loadPrefs(),
  save: savePrefs,
  voice: speaker,
  video: byId<HTMLVideoElement>('camera'),
  askedVenue: new URLSearchParams(location.search).get('venue'),
  // "Keep telling me" is a walk too: its own feed, so that the guide's counts stay its own
  motion: new MotionFeed(),
  askMotion,
  guiding: (): boolean => guide.state === 'guiding', // (the guide is made next; asked only on a press)
  standby: (): boolean => session.prefs.ready && !document.hidden && !posture.flat && cameraScreen(),
});
const guide = new Guide({
  voice: speaker,
  track: async (q, motion, seconds, stop) => (await session.track(q, motion, seconds, stop))?.answer ?? null,
  motion: new MotionFeed(),
  screen: new ScreenLock(),
  askMotion,
  style: () => session.prefs.style,
  // the words say the place's own sentence on arrival (the guidance's `to.say`): nothing is added
  words: { guidance: guidanceSentence, preview: (g) => previewSentence(g.preview!, g.to) },
});

/** Inside the first gesture: iOS speaks, and gives motion events, only after one. */
function firstGesture(): void {
  speaker.prime();
  void askMotion();
}

async function registerServiceWorker(about: About): Promise<void> {
  if (!('serviceWorker' in navigator)) return;
  try {
    const { registerSW } = await import('virtual:pwa-register');
    registerSW({ immediate: true });
  } catch {
    about.status('This browser did not install omninav for offline use.');
  }
}

document.addEventListener('pointerdown', firstGesture, { once: true, capture: true });
document.addEventListener('keydown', firstGesture, { once: true, capture: true });
locateScreen(session, speaker);
gotoScreen(session, speaker, guide);
routeTabs((name) => session.screenShown(name));
onShake(() => void session.whereAmI());
onTwoFingerDoubleTap(document.body, () => void session.whereAmI());
settingsScreen(session, speaker);
const about = aboutScreen(speaker.available);
void registerServiceWorker(about);
void session.loadVenue();
