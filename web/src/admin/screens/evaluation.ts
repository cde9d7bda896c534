/**
 * Step 10, the evaluation walk: a second walk, tagged with a few waypoints and marked as
 * evaluation, is cut into 1 s clips that the venue locates (`omninav evaluate`, as a job); the
 * plan draws each answer as an arrow from the truth to the answer, with the within-1 m and
 * within-2 m shares, the heading error and the answers that were spoken as "not sure". The table
 * below the plan says every clip in words.
 */
import { AdminError, venuePath } from '../api';
import type { AdminContext } from '../context';
import { dataTable, el, statusLine } from '../dom';
import '../analysis.css';
import {
  CLIP_COLOUR,
  CLIP_COLUMNS,
  arrow,
  degrees,
  metres,
  clipRow,
  clipVerdict,
  evaluationVideos,
  notReady,
  saidCounts,
  summaryText,
} from '../evaluation-view';
import { JobProgress } from '../jobprogress';
import { percent } from '../quality-view';
import type { Evaluation, Job, Video } from '../types';

export function mount(root: HTMLElement, ctx: AdminContext): () => void {
  const abort = new AbortController();
  const venueId = ctx.venue().id;
  let videos: Video[] = [];

  const heading = el('h2', { id: 'evaluation-title', textContent: 'Evaluation walk' });
  const intro = el('p', {
    textContent:
      'Film a second walk, upload it on the Videos screen as an evaluation walk and tag a few of its ' +
      'waypoints on the Walk path screen; here the venue locates each second of it, as a phone would, and ' +
      'the plan shows each answer as an arrow from where the walker was to where the venue said. ' +
      'Each second of the walk is one clip, scored against where the walk path puts the walker at the ' +
      "clip's last frame: tag a waypoint at each turn and stop, and at the walk's start and end, so " +
      'that the walk path is where the walker was at every moment (the last part-second is scored too).',
  });
  const pick = el('select', { id: 'evaluation-video' });
  const pickLabel = el('label', { htmlFor: 'evaluation-video', textContent: 'Evaluation video' });
  const run = el('button', { type: 'button', textContent: 'Run the evaluation' });
  const upload = el('button', { type: 'button', textContent: 'Upload an evaluation walk' });
  upload.addEventListener('click', () => ctx.go('videos', { role: 'evaluation' }));
  const tag = el('button', { type: 'button', textContent: 'Tag its walk path' });
  tag.addEventListener('click', () => ctx.go('walk-path', { video: pick.value }));
  const why = el('p', { id: 'evaluation-why' });
  const status = el('p', { className: 'status', id: 'evaluation-status' });
  const progress = new JobProgress(ctx.api, 'Evaluation progress');
  const result = el('section', { className: 'evaluation-result' });
  result.setAttribute('aria-labelledby', 'evaluation-title');
  root.replaceChildren(
    heading,
    intro,
    el('p', {}, pickLabel, ' ', pick, ' ', run, ' ', tag),
    why,
    el('p', {}, upload),
    progress.el,
    status,
    result,
  );

  const { say, fail } = statusLine(ctx, status, abort.signal);

  let map: ReturnType<AdminContext['planMap']> | null = null;
  const dropMap = () => {
    map?.remove();
    map = null;
  };

  const chosen = (): Video | undefined => videos.find((v) => v.name === pick.value);
  const refreshButtons = () => {
    const v = chosen();
    const reason = v ? notReady(v) : 'there is no evaluation walk; upload one first';
    run.disabled = reason !== null || progress.busy;
    tag.disabled = !v || !!v.error || v.status === 'uploading';
    why.textContent = reason ? `Cannot run it yet: ${reason}.` : '';
  };

  const show = (e: Evaluation, name: string) => {
    dropMap();
    // (focusable: the keyboard's place once a run ends, see `follow`)
    const summary = el('p', {
      id: 'evaluation-summary',
      className: 'summary',
      textContent: summaryText(e),
      tabIndex: -1,
    });
    const s = { ...e.summary, ...saidCounts(e) };
    const figures = el('dl', { className: 'figures', id: 'evaluation-figures' });
    const fig = (dt: string, dd: string, id: string) =>
      figures.append(el('dt', { textContent: dt }), el('dd', { id, textContent: dd }));
    fig('Within 1 m', percent(s.within_1m), 'evaluation-within-1m');
    fig('Within 2 m', percent(s.within_2m), 'evaluation-within-2m');
    fig('Median error', metres(s.median_error_m), 'evaluation-median');
    fig('Median heading error', degrees(s.median_heading_error_deg), 'evaluation-heading');
    fig('Spoken as "not sure"', `${s.not_sure} of ${s.clips}`, 'evaluation-not-sure');
    fig('Spoken as "probably"', `${s.probably} of ${s.clips}`, 'evaluation-probably');
    fig('Said as sure, further than 2 m', `${s.sure_over_2m} of ${s.clips}`, 'evaluation-sure-over-2m');

    const legend = el('ul', { className: 'legend' });
    legend.setAttribute('aria-label', 'Legend');
    for (const [k, c] of Object.entries(CLIP_COLOUR)) {
      const sw = el('span', { className: 'swatch' });
      sw.style.background = c;
      sw.setAttribute('aria-hidden', 'true');
      legend.append(el('li', {}, sw, ` ${k}`));
    }
    legend.append(el('li', { textContent: 'each arrow runs from where the walker was to where the venue said' }));

    const planEl = el('div', { className: 'plan', id: 'evaluation-plan' });

    const { table, body } = dataTable(`Every 1 s clip of ${name}`, CLIP_COLUMNS, { id: 'evaluation-clips' });
    for (const c of e.clips)
      body.append(
        el(
          'tr',
          { className: clipVerdict(c).replace(/ /g, '-') },
          ...clipRow(c).map((t) => el('td', { textContent: t })),
        ),
      );

    result.replaceChildren(summary, figures, legend, planEl, table);
    map = ctx.planMap(planEl);
    planEl.setAttribute(
      'aria-label',
      `Answers of ${name} on the plan: ${summaryText(e)}. The table below lists every clip.`,
    );
    for (const c of e.clips) {
      const v = clipVerdict(c);
      // the truth a hollow dot, the answer a dot of its verdict's colour, an arrow between them
      map.addCircle(c.truth.x, c.truth.y, 0.15, { color: '#000', weight: 1, fillOpacity: 0, interactive: false });
      if (c.answer)
        map.addCircle(c.answer.x, c.answer.y, 0.12, {
          color: CLIP_COLOUR[v],
          weight: 1,
          fillColor: CLIP_COLOUR[v],
          fillOpacity: 0.9,
          interactive: false,
          className: `answer answer-${v.replace(/ /g, '-')}`,
        });
      const a = arrow(c);
      if (!a) continue;
      const style = {
        color: CLIP_COLOUR[v],
        weight: 2,
        dashArray: v === 'not sure' ? '3 3' : undefined,
        interactive: false,
      };
      map.addPolyline(a.shaft, style);
      if (a.barbs.length) map.addPolyline(a.barbs, style);
    }
    ctx.announce(summaryText(e));
  };

  const load = async () => {
    const v = chosen();
    dropMap();
    result.replaceChildren();
    refreshButtons();
    if (!v) return;
    try {
      show(
        await ctx.api.get<Evaluation>(
          venuePath(venueId, `/videos/${encodeURIComponent(v.name)}/evaluation`),
          abort.signal,
        ),
        v.name,
      );
    } catch (e) {
      if (e instanceof AdminError && e.status === 404)
        result.replaceChildren(
          el('p', { id: 'evaluation-none', textContent: `${v.name} has not been evaluated yet.` }),
        );
      else fail(e);
    }
  };

  const follow = async (job: Job) => {
    progress.busy = true;
    refreshButtons();
    try {
      const end = await progress.follow(job, abort.signal);
      if (abort.signal.aborted) return;
      if (end.state === 'done') {
        say('The evaluation is done.');
        if (job.target) pick.value = job.target;
        await load();
        ctx.recheck();
      } else if (end.state === 'failed') say(`The evaluation failed: ${end.error ?? 'no reason given'}`, true);
      else say('The evaluation was cancelled.');
    } finally {
      progress.busy = false;
      refreshButtons();
      // the button pressed was disabled while the run went on, which left the focus on the page:
      // keep the keyboard's place on what happened (the result, else the button), unless it moved
      if (!document.activeElement || document.activeElement === document.body)
        (document.getElementById('evaluation-summary') ?? run).focus();
    }
  };

  run.addEventListener('click', async () => {
    const v = chosen();
    if (!v) return;
    try {
      say(`Evaluating ${v.name}…`);
      await follow(await ctx.api.post<Job>(venuePath(venueId, `/videos/${encodeURIComponent(v.name)}/evaluate`)));
    } catch (e) {
      fail(e, `Evaluating ${v.name}`);
    }
  });
  pick.addEventListener('change', () => void load());

  void (async () => {
    try {
      const list = await ctx.api.get<{ videos: Video[] }>(venuePath(venueId, '/videos'), abort.signal);
      videos = evaluationVideos(list.videos);
      pick.replaceChildren(
        ...videos.map((v) =>
          el('option', { value: v.name, textContent: notReady(v) ? `${v.name} (${notReady(v)})` : v.name }),
        ),
      );
      pick.disabled = videos.length === 0;
      const want = ctx.params().get('video');
      const ready = videos.find((v) => !notReady(v));
      if (want && videos.some((v) => v.name === want)) pick.value = want;
      else if (ready) pick.value = ready.name;
      await load();
      const { jobs } = await ctx.api.get<{ jobs: Job[] }>(venuePath(venueId, '/jobs'), abort.signal);
      const running = jobs.find((j) => j.kind === 'evaluate' && (j.state === 'queued' || j.state === 'running'));
      if (running) {
        if (running.target) pick.value = running.target;
        await follow(running);
      }
    } catch (e) {
      fail(e);
    }
  })();

  return () => {
    abort.abort();
    dropMap();
  };
}
