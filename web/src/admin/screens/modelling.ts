/**
 * Step 8, modelling: one button models every modelling video whose walk path is tagged and which is not
 * modelled yet (POST .../jobs); the job's progress (frames done, frames per second, time left) is
 * read from its event stream; it can be cancelled, and a failed job says why. The page says which
 * generation of frames is live: the venue keeps answering from it until the new one is complete.
 * A venue modelled before its preset improved (settings_current false) is offered a modelling
 * anew: every modelling video again, with the preset's current feature settings.
 */
import { AdminError, venuePath } from '../api';
import type { AdminContext } from '../context';
import { button, dataTable, el } from '../dom';
import { JobProgress } from '../jobprogress';
import '../media.css';
import type { AdminVenue, Job, Video } from '../types';

const ACTIVE = new Set<Job['state']>(['queued', 'running']);

/** Whether a video goes into the next modelling, and if not, why not. */
export function modelVerdict(v: Video): { goes: boolean; why: string } {
  if (v.role === 'evaluation')
    return { goes: false, why: 'an evaluation walk: it checks the map, it is not part of it' };
  if (v.status === 'uploading') return { goes: false, why: 'still uploading' };
  if (!v.has_walk_path) return { goes: false, why: 'no walk path yet: tag it first' };
  if (v.status === 'modelled') return { goes: false, why: `already modelled (${v.frames} frames)` };
  return { goes: true, why: 'will be modelled' };
}

/** The videos a modelling anew takes: every uploaded modelling walk with a walk path, modelled or not. */
export function anewVideos(videos: Video[]): string[] {
  return videos
    .filter((v) => v.role !== 'evaluation' && v.has_walk_path && (v.status === 'ready' || v.status === 'modelled'))
    .map((v) => v.name);
}

/** Why to model a venue anew, or null when its live frames already have the preset's settings. */
export function anewNotice(v: AdminVenue, videos: Video[]): string | null {
  if (v.settings_current !== false) return null;
  const names = anewVideos(videos);
  const what = names.length
    ? `Modelling anew models ${names.join(', ')} again with them`
    : 'Modelling anew needs the modelling videos with their walk paths, and no uploaded modelling video has a walk path yet';
  return (
    'This venue was modelled with older feature settings than its preset has now. ' +
    `${what}. Until that is complete the venue answers as it does now; phones take up the new ` +
    'settings by themselves.'
  );
}

const when = (epochS: number | null): string =>
  epochS ? new Date(epochS * 1000).toLocaleString('en-GB', { dateStyle: 'medium', timeStyle: 'short' }) : '';

export function mount(root: HTMLElement, ctx: AdminContext): () => void {
  const abort = new AbortController();
  const venueId = ctx.venue().id;
  let videos: Video[] = [];
  let running: Job | null = null;

  const live = el('p', { className: 'live-generation', id: 'live-generation' });
  const meanwhile = el('p', {
    className: 'hint',
    textContent:
      'While a modelling runs, the venue keeps answering from the live generation; the new generation ' +
      'goes live only when it is complete, so a cancelled or failed run changes nothing.',
  });
  const start = button('Model the venue', () => void startJob());
  start.id = 'model-start';
  const why = el('p', { className: 'hint', id: 'model-why' });
  const progress = new JobProgress(ctx.api, 'Modelling progress');
  progress.el.classList.add('job-bar');
  progress.el.id = 'model-progress';
  // focusable from code: a finished modelling anew hides the button that had the focus
  const outcome = el('p', { id: 'model-outcome', tabIndex: -1 });
  const anewWhy = el('p', { className: 'hint', id: 'model-anew-why' });
  const anew = button('Model anew with the current settings', () => void startJob(true));
  anew.id = 'model-anew';
  anew.setAttribute('aria-describedby', 'model-anew-why');
  const anewBox = el(
    'div',
    { id: 'model-anew-box' },
    el('h3', { textContent: 'Newer feature settings' }),
    anewWhy,
    el('div', { className: 'row' }, anew),
  );
  anewBox.hidden = true;
  const { table, body: tbody } = dataTable('What the next modelling takes', ['Video', 'Walk path', 'Next modelling'], {
    id: 'model-videos',
  });
  root.replaceChildren(
    el('h2', { textContent: 'Modelling' }),
    live,
    meanwhile,
    el('div', { className: 'row' }, start),
    why,
    anewBox,
    progress.el,
    outcome,
    table,
  );

  const drawLive = () => {
    const v = ctx.venue() as AdminVenue;
    if (v.generation !== null && v.generation !== undefined)
      live.textContent = `Live now: generation ${v.generation}${v.modelled_at ? `, modelled ${when(v.modelled_at)}` : ''}, ${v.frames} frames.`;
    else if (v.modelled) live.textContent = `Live now: the modelled frames (${v.frames}).`;
    else live.textContent = 'Not modelled yet: the venue answers nobody until its first modelling is complete.';
  };

  const drawVideos = () => {
    const goes = videos.filter((v) => modelVerdict(v).goes);
    tbody.replaceChildren(
      ...videos.map((v) => {
        const verdict = modelVerdict(v);
        const cell = el('td', { textContent: verdict.why });
        if (!v.has_walk_path && v.status !== 'uploading' && v.role === 'model')
          cell.append(
            ' (',
            el('a', {
              href: `#/v/${encodeURIComponent(venueId)}/walk-path?video=${encodeURIComponent(v.name)}`,
              textContent: `tag ${v.name}`,
            }),
            ')',
          );
        return el(
          'tr',
          { className: verdict.goes ? 'goes' : '' },
          el('th', { scope: 'row', textContent: v.name }),
          el('td', { textContent: v.has_walk_path ? `${v.walk_path?.waypoints.length ?? 0} waypoints` : 'none' }),
          cell,
        );
      }),
    );
    table.hidden = videos.length === 0;
    const busy = running !== null && ACTIVE.has(running.state);
    start.textContent = goes.length ? `Model ${goes.length} video${goes.length === 1 ? '' : 's'}` : 'Model the venue';
    start.disabled = busy || goes.length === 0;
    const notice = anewNotice(ctx.venue() as AdminVenue, videos);
    anewBox.hidden = notice === null;
    anewWhy.textContent = notice ?? '';
    anew.disabled = busy || anewVideos(videos).length === 0;
    why.textContent = busy
      ? 'A modelling is running.'
      : goes.length
        ? `Models ${goes.map((v) => v.name).join(', ')}.`
        : videos.length
          ? 'Nothing to model: every modelling video with a walk path is modelled already, or none has a walk path yet.'
          : 'Nothing to model: upload a walk video and tag its walk path first.';
  };

  const load = async () => {
    try {
      const [, vids, jobs] = await Promise.all([
        ctx.refresh(),
        ctx.api.get<{ videos: Video[] }>(venuePath(venueId, '/videos'), abort.signal),
        ctx.api.get<{ jobs: Job[] }>(venuePath(venueId, '/jobs'), abort.signal),
      ]);
      videos = vids.videos;
      drawLive();
      const model = jobs.jobs.filter((j) => (j.kind ?? 'model') === 'model').sort((a, b) => b.created - a.created);
      const active = model.find((j) => ACTIVE.has(j.state));
      if (active && !running) void follow(active);
      else if (!active && model[0] && !running) {
        const last = model[0];
        if (last.state === 'failed')
          outcome.textContent = `The last modelling (${when(last.finished)}) failed: ${last.error ?? 'no reason given'}.`;
        else if (last.state === 'cancelled')
          outcome.textContent = `The last modelling (${when(last.finished)}) was cancelled.`;
      }
      drawVideos();
    } catch (e) {
      if (!abort.signal.aborted) ctx.fail(e, 'Reading the venue');
    }
  };

  const follow = async (job: Job) => {
    running = job;
    outcome.textContent = '';
    drawVideos();
    let last = job;
    try {
      last = await progress.follow(job, abort.signal);
    } catch (e) {
      if (abort.signal.aborted) return;
      ctx.fail(e, 'Following the modelling');
    }
    if (abort.signal.aborted) return;
    running = last;
    await load();
    const v = ctx.venue() as AdminVenue;
    if (last.state === 'done') {
      const how = last.anew ? ', with the current feature settings' : '';
      const msg = `Modelling done: ${last.frames_total} frames; generation ${v.generation ?? '?'} is live now${how}.`;
      outcome.textContent = msg;
      ctx.announce(msg);
    } else if (last.state === 'failed') {
      const msg = `Modelling failed: ${last.error ?? 'no reason given'}. The venue still answers from what was live.`;
      outcome.textContent = msg;
      ctx.announce(msg, true);
    } else if (last.state === 'cancelled') {
      const msg = 'Modelling cancelled. The venue still answers from what was live.';
      outcome.textContent = msg;
      ctx.announce(msg);
    }
    running = null;
    drawVideos();
    // the button pressed was disabled while the job ran (or hid with its box), which left the
    // focus on the page: keep the keyboard's place on what happened, unless it moved elsewhere
    if (document.activeElement === document.body || !document.activeElement) outcome.focus();
  };

  const startJob = async (isAnew = false) => {
    start.disabled = true;
    anew.disabled = true;
    try {
      const job = await ctx.api.post<Job>(venuePath(venueId, '/jobs'), isAnew ? { anew: true } : undefined);
      ctx.announce(`Modelling ${isAnew ? 'anew ' : ''}started: ${job.videos.join(', ')}.`);
      await follow(job);
    } catch (e) {
      if (e instanceof AdminError && e.status === 409) outcome.textContent = e.message;
      ctx.fail(e, 'Starting the modelling');
      drawVideos();
    }
  };

  drawLive();
  drawVideos();
  void load();
  return () => abort.abort();
}
