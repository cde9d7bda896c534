/**
 * Step 9, the quality map: the engine locates each modelling stretch against the venue without
 * that stretch (leave-one-segment-out) and the plan is coloured by the result: green within 2 m,
 * amber right but ambiguous, red wrong, grey a corridor no video covers. A red or amber stretch,
 * clicked on the plan or chosen from the list, shows the two look-alike panoramas side by side.
 * Everything on the plan is also in the lists below it (the text alternative).
 */
import { AdminError, venuePath } from '../api';
import type { AdminContext } from '../context';
import { dataTable, el, enable, statusLine } from '../dom';
import '../analysis.css';
import { JobProgress } from '../jobprogress';
import {
  VERDICT_COLOUR,
  VERDICT_MEANING,
  at,
  clock,
  corridorText,
  mapLabel,
  outsideAreas,
  percent,
  problemStretches,
  stretchReason,
  stretchTitle,
  type CorridorVerdict,
} from '../quality-view';
import type { AdminVenue, Job, Quality, QualitySegment } from '../types';

export function mount(root: HTMLElement, ctx: AdminContext): () => void {
  const abort = new AbortController();
  const urls: string[] = [];
  const venueId = ctx.venue().id;
  const floor = ctx.floor();

  const heading = el('h2', { id: 'quality-title', textContent: 'Quality map' });
  const intro = el('p', {
    textContent:
      'Where the venue would answer within 2 m (green), answer right but with a look-alike place close ' +
      '(amber) or answer the wrong place (red), found by locating each second of the modelling walks ' +
      'against the venue without that stretch; corridors no video covers are grey.',
  });
  const compute = el('button', { type: 'button', textContent: 'Compute the quality map' });
  const status = el('p', { className: 'status', id: 'quality-status' });
  const progress = new JobProgress(ctx.api, 'Quality map progress');
  const result = el('section', { className: 'quality-result' });
  result.setAttribute('aria-labelledby', 'quality-title');
  root.replaceChildren(heading, intro, el('p', {}, compute), progress.el, status, result);

  const { say, fail } = statusLine(ctx, status, abort.signal);

  let map: ReturnType<AdminContext['planMap']> | null = null;
  const dropMap = () => {
    map?.remove();
    map = null;
  };

  const show = (q: Quality) => {
    dropMap();
    const sentence = el('p', { id: 'quality-sentence', className: 'summary', textContent: q.sentence });
    const share = el(
      'p',
      { id: 'quality-share' },
      'Share of green: ',
      el('strong', { textContent: percent(q.summary.share_green) }),
      ` (${q.generation === null ? '' : `generation ${q.generation}, `}${q.frames} frames, radius ${q.radius_m} m)`,
    );
    const legend = el('ul', { className: 'legend' });
    legend.setAttribute('aria-label', 'Legend');
    for (const v of ['green', 'amber', 'red', 'grey'] as CorridorVerdict[]) {
      const swatch = el('span', { className: 'swatch' });
      swatch.style.background = VERDICT_COLOUR[v];
      swatch.setAttribute('aria-hidden', 'true');
      legend.append(el('li', {}, swatch, ` ${v}: ${VERDICT_MEANING[v]}`));
    }
    const planEl = el('div', { className: 'plan', id: 'quality-plan' });
    const compare = el('section', { className: 'compare', id: 'quality-compare', hidden: true });
    compare.setAttribute('aria-label', 'Look-alike panoramas');

    // the problem stretches, keyboard reachable: each opens the comparison
    const problems = problemStretches(q, floor);
    const list = el('ul', { id: 'quality-problems' });
    const problemsTitle = el('h3', {
      id: 'quality-problems-title',
      textContent: problems.length ? `Stretches to check (${problems.length})` : 'No red or amber stretch',
    });
    list.setAttribute('aria-labelledby', 'quality-problems-title');
    for (const s of problems) {
      const b = el('button', { type: 'button', className: `stretch ${s.verdict}`, textContent: stretchTitle(s) });
      b.addEventListener('click', () => void compareStretch(s, compare));
      list.append(el('li', {}, b));
    }

    // the corridors and every stretch, in words
    const corridors = el('ul', { id: 'quality-corridors' });
    for (const c of q.corridors.filter((c) => c.floor === floor))
      corridors.append(el('li', { className: `corridor ${c.verdict}`, textContent: corridorText(c) }));
    const { table, body } = dataTable(
      'Every stretch of the modelling walks',
      ['Video', 'From', 'To', 'Where', 'Verdict', 'Why'],
      { id: 'quality-stretches' },
    );
    for (const s of q.segments.filter((s) => s.floor === floor)) {
      const mid = s.points[Math.floor((s.points.length - 1) / 2)] ?? [s.match.x, s.match.y];
      body.append(
        el(
          'tr',
          { className: s.verdict },
          ...[s.video, clock(s.t0), clock(s.t1), at(mid[0], mid[1]), s.verdict, stretchReason(s)].map((t) =>
            el('td', { textContent: t }),
          ),
        ),
      );
    }
    const all = el('details', {}, el('summary', { textContent: 'Every stretch, as a table' }), table);

    result.replaceChildren(
      sentence,
      share,
      legend,
      planEl,
      compare,
      problemsTitle,
      list,
      el('h3', { textContent: 'Corridors' }),
      q.corridors.length ? corridors : el('p', { textContent: 'No place has an area: draw the corridors as areas.' }),
      ...outsideLine(q, floor),
      all,
    );

    map = ctx.planMap(planEl);
    planEl.setAttribute('aria-label', mapLabel(q, floor));
    for (const c of q.corridors.filter((c) => c.floor === floor)) {
      const grey = c.verdict === 'grey';
      map
        .addRectangle(c.area, {
          color: VERDICT_COLOUR[c.verdict],
          weight: grey ? 1 : 2,
          dashArray: grey ? undefined : '4 4',
          fillColor: VERDICT_COLOUR[c.verdict],
          fillOpacity: grey ? 0.45 : 0.08,
          interactive: false,
          className: `corridor corridor-${c.verdict}`,
        })
        .bindTooltip(corridorText(c));
    }
    for (const s of q.segments.filter((s) => s.floor === floor)) {
      const pts = s.points.length === 1 ? [s.points[0], s.points[0]] : s.points;
      const line = map.addPolyline(pts, {
        color: VERDICT_COLOUR[s.verdict],
        weight: s.verdict === 'green' ? 5 : 7,
        opacity: 0.9,
        className: `stretch stretch-${s.verdict}`,
        interactive: s.verdict !== 'green',
      });
      if (s.verdict !== 'green') {
        line.bindTooltip(stretchTitle(s));
        line.on('click', () => void compareStretch(s, compare));
      }
    }
    ctx.announce(q.sentence);
  };

  const compareStretch = async (s: QualitySegment, box: HTMLElement) => {
    // focus goes back where the admin was (the list's button) when the comparison closes
    const opener = document.activeElement instanceof HTMLElement ? document.activeElement : null;
    const [x, y] = s.points[Math.floor((s.points.length - 1) / 2)] ?? [s.match.x, s.match.y];
    const title = el('h3', {
      id: 'quality-compare-title',
      tabIndex: -1,
      textContent: `Look-alikes: ${stretchTitle(s)}`,
    });
    const close = el('button', { type: 'button', textContent: 'Close the comparison' });
    close.addEventListener('click', () => {
      box.hidden = true;
      box.replaceChildren();
      if (opener?.isConnected) opener.focus();
    });
    const figure = (caption: string, alt: string, video: string, t: number) => {
      const img = el('img', { alt, width: 720, height: 144, className: 'panorama' });
      const f = el('figure', {}, img, el('figcaption', { textContent: caption }));
      ctx.api
        .blobUrl(
          venuePath(venueId, `/videos/${encodeURIComponent(video)}/frame?t=${t.toFixed(3)}&view=panorama`),
          abort.signal,
        )
        .then((u) => {
          urls.push(u);
          img.src = u;
        })
        .catch((e: unknown) => {
          if (!abort.signal.aborted)
            f.append(el('p', { textContent: `No panorama: ${e instanceof Error ? e.message : String(e)}` }));
        });
      return f;
    };
    const here = `This stretch: ${s.query.video} at ${clock(s.query.t)}, where the walk was at ${at(x, y)}`;
    const there = `The look-alike it was taken for: ${s.match.video} at ${clock(s.match.t)}, at ${at(s.match.x, s.match.y)}`;
    box.replaceChildren(
      title,
      el('p', { textContent: `${s.verdict}: ${stretchReason(s)}.` }),
      el(
        'div',
        { className: 'side-by-side' },
        figure(here, `Panorama of ${here}`, s.query.video, s.query.t),
        figure(there, `Panorama of ${there}`, s.match.video, s.match.t),
      ),
      close,
    );
    box.hidden = false;
    title.focus();
    ctx.announce(`Showing the two look-alike panoramas of the ${s.verdict} stretch.`);
  };

  const load = async () => {
    try {
      show(await ctx.api.get<Quality>(venuePath(venueId, '/quality'), abort.signal));
    } catch (e) {
      if (e instanceof AdminError && e.status === 404) {
        const live = (ctx.venue() as Partial<AdminVenue>).generation;
        result.replaceChildren(
          el('p', {
            id: 'quality-none',
            textContent:
              live === null
                ? 'No quality map yet: model the venue first (Modelling), then compute it here.'
                : 'No quality map yet: compute it (a few seconds for a walk of a few minutes).',
          }),
        );
        return;
      }
      fail(e);
    }
  };

  const run = async (job: Job) => {
    compute.disabled = true;
    try {
      const end = await progress.follow(job, abort.signal);
      if (abort.signal.aborted) return;
      if (end.state === 'done') {
        say('The quality map is ready.');
        await load();
        ctx.recheck();
      } else if (end.state === 'failed') say(`The quality map failed: ${end.error ?? 'no reason given'}`, true);
      else say('The quality map was cancelled.');
    } finally {
      enable(compute);
    }
  };

  compute.addEventListener('click', async () => {
    try {
      say('Computing the quality map…');
      await run(await ctx.api.post<Job>(venuePath(venueId, '/quality')));
    } catch (e) {
      fail(e, 'Computing the quality map');
    }
  });

  // a quality job already running (another tab, a reload): follow it
  void (async () => {
    await load();
    try {
      const { jobs } = await ctx.api.get<{ jobs: Job[] }>(venuePath(venueId, '/jobs'), abort.signal);
      const running = jobs.find((j) => j.kind === 'quality' && (j.state === 'queued' || j.state === 'running'));
      if (running) await run(running);
    } catch (e) {
      fail(e);
    }
  })();

  return () => {
    abort.abort();
    dropMap();
    for (const u of urls) URL.revokeObjectURL(u);
  };
}

/** The line that says which seconds of walk no corridor verdict counts (none: no line). */
function outsideLine(q: Quality, floor: string): HTMLElement[] {
  const { outside, all } = outsideAreas(q, floor);
  if (!outside || !q.corridors.length) return [];
  return [
    el('p', {
      id: 'quality-outside',
      textContent: `${outside} of the walk's ${all} seconds on this floor are in no drawn area, so no corridor's verdict counts them: draw the corridors there as areas on the Places screen.`,
    }),
  ];
}
