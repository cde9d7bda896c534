/**
 * The locate screen: "Where am I?", Repeat, "Keep telling me", the venue line, the last answer as
 * text and facts, the floor plan, and the details for helpers. It shows what the session reports.
 */
import type { Venue } from '../api';
import type { Answer } from '../directions';
import { byId, facts } from '../dom';
import { HEADER_BYTES, keptKeypoints, localBlockBytes } from '../../shared/record';
import type { Session } from '../session';
import type { Speaker } from '../speech';
import { PlanView } from '../views/plan';

/** What the server's check by keypoints made of the answer (Answer.verified), in words. */
const CHECKED: Record<NonNullable<Answer['verified']> | 'none', string> = {
  moved: 'moved: the keypoints fit another place better, and the answer is there',
  confirmed: 'confirmed: the keypoints fit the answer',
  unconfirmed: 'not confirmed: the keypoints did not confirm this place, so the answer is not sure',
  none: 'not used by the server',
};

export function locateScreen(session: Session, speaker: Speaker): void {
  const where = byId<HTMLButtonElement>('where');
  const repeat = byId<HTMLButtonElement>('repeat');
  const continuous = byId<HTMLButtonElement>('continuous');
  const venueLine = byId('venue-line');
  const answerText = byId('answer-text');
  const answerFacts = byId('answer-facts');
  const debugFacts = byId('debug-facts');
  const plan = new PlanView(byId<HTMLCanvasElement>('plan'));

  /** An answer as text, facts and on the plan (the sentence the session speaks). */
  function show(a: Answer, v: Venue): void {
    const floor = v.floors.find((f) => f.id === a.floor);
    answerText.textContent = session.sentence(a, v);
    const rows: [string, string][] = [];
    if (!a.low_confidence) {
      if (a.area) rows.push(['In', a.area]);
      if (a.nearest) rows.push(['Nearest place', `${a.nearest.name}, ${a.nearest.distance_m.toFixed(0)} m`]);
      if (a.facing) rows.push(['Facing', a.facing]);
      rows.push(['Floor', floor?.name ?? a.floor]);
      if (a.accuracy_m) rows.push(['Accuracy', `about ${a.accuracy_m} m`]);
    }
    rows.push(['Confidence', `${Math.round(a.confidence * 100)} %`]);
    facts(answerFacts, rows);
    repeat.disabled = false;
    // the plan image may still be loading: speech must not wait for it
    void plan.show(
      floor,
      v.places.filter((p) => p.floor === a.floor),
      a,
    );
  }

  // while the phone films on after an unsure first second, the same button stops it
  where.addEventListener('click', () => (session.asking ? session.stop() : void session.whereAmI()));
  repeat.addEventListener('click', () => speaker.repeat());
  continuous.addEventListener('click', () => session.toggleContinuous());

  session.on('line', (text) => (venueLine.textContent = text));
  session.on('venue', (v) => void plan.show(v.floors[0], v.places, null));
  function label(busy: boolean, asking: boolean): void {
    if (busy && !asking) where.setAttribute('aria-busy', 'true');
    else where.removeAttribute('aria-busy');
    where.textContent = asking ? 'Stop' : busy ? 'Locating…' : 'Where am I?';
  }
  let busyNow = false;
  session.on('busy', (busy) => label((busyNow = busy), session.asking));
  session.on('asking', (asking) => label(busyNow, asking));
  session.on('continuous', (on) => continuous.setAttribute('aria-pressed', String(on)));
  session.on('said', (text) => (answerText.textContent = text));
  session.on('answer', (r) => {
    show(r.answer, r.venue);
    const a = r.answer;
    const c = r.lensCheck;
    // what the phone's lens check found (the ring in the camera's frames against the profile)
    const lensRow: [string, string][] = c ? [['Lens check', `${c.message} (${c.ms.toFixed(0)} ms per frame)`]] : [];
    // the keypoints of the last frame, where sent (record.ts's local block), are not the curves'
    const k = keptKeypoints(r.keypoints ?? 0);
    const localBytes = r.keypoints != null ? localBlockBytes(k) : 0;
    const keypointRow: [string, string][] =
      r.keypoints != null
        ? [
            ['Keypoints', `${k} of the last frame, ${localBytes} bytes, ${(r.keypointMs ?? 0).toFixed(0)} ms`],
            ['Checked by keypoints', CHECKED[a.verified ?? 'none']],
          ]
        : [];
    facts(debugFacts, [
      ['Sent', `features only: ${r.recordBytes} bytes for ${r.frames} frames`],
      ['Bytes per frame', String((r.recordBytes - HEADER_BYTES - localBytes) / r.frames)],
      ...keypointRow,
      ['Camera', `${r.camera[0]} x ${r.camera[1]}, lens ${r.lens}, ${r.fps.toFixed(1)} frames/s`],
      ['Extraction', `${r.medianMs.toFixed(1)} ms per frame (median)`],
      ['Server round trip', `${r.rttMs.toFixed(0)} ms`],
      ['First second', r.kept ? 'kept before the press' : 'filmed after the press'],
      ...(r.duty === null
        ? []
        : [['Standing by', `the worker busy ${(r.duty * 100).toFixed(0)} % of the time`] as [string, string]]),
      ['Position', `x ${a.x.toFixed(2)} m, y ${a.y.toFixed(2)} m, heading ${a.heading_deg.toFixed(1)}°`],
      ['Confidence', a.confidence.toFixed(3)],
      ...lensRow,
    ]);
  });
  // another direction style rephrases the last answer on screen (it is not spoken again)
  session.on('pref', (key) => {
    if (key === 'style' && session.lastAnswer && session.venue) show(session.lastAnswer, session.venue);
  });
}
