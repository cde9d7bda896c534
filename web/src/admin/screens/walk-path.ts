/**
 * Step 7, the walk path tagged on the plan: a video's frame and its unwrapped panorama at the scrubber's
 * time (rendered by the server with the engine's unwarp; the walking direction marked), the plan
 * beside. Clicking the plan drops a waypoint at the current time; waypoints are dragged, typed,
 * deleted, and snap to the corridors' centre lines when asked. The turns and stops the server found
 * are offered in order, so that each corner takes one click: choose (or accept) a suggestion, the
 * video jumps there, click where it happened, and the next one comes up. Saved as the video's
 * walk_path.json (PUT .../walk-path, If-Match: a stale venue is refused and said so); downloadable.
 */
import type * as L from 'leaflet';
import { AdminError, venuePath } from '../api';
import type { AdminContext } from '../context';
import { button, dataTable, el, enable, field, uid } from '../dom';
import { formatTime } from '../format';
import '../media.css';
import type { PlanMap } from '../planmap';
import {
  acceptSuggestion,
  addAt,
  corridorLines,
  fromWalkPath,
  isTagged,
  landmarkLine,
  nextUntagged,
  positionAt,
  putPoint,
  snapToLines,
  snapWords,
  suggestionText,
  toWalkPath,
  walkPathProblem,
  walkColumn,
  type Point,
} from '../walk-path-edit';
import type { Suggestion, Video } from '../types';

/** Frames kept as object URLs (both views), so scrubbing back and forth is instant. */
const CACHE = 48;
/** Wait after the last scrubber move before asking the server for frames (ms). */
const DEBOUNCE_MS = 70;

export function mount(root: HTMLElement, ctx: AdminContext): () => void {
  const abort = new AbortController();
  const venueId = ctx.venue().id;
  const wanted = ctx.params().get('video');
  let map: PlanMap | null = null;
  let cleanup: (() => void)[] = [];

  const chooser = el('select');
  const status = el('p', { className: 'status', id: 'walk-path-status' });
  const body = el('div', { className: 'walk-path-body' });
  root.replaceChildren(
    el('h2', { textContent: 'Walk path' }),
    el('p', {
      textContent:
        'Where the walker was while filming: scrub the video, and at each turn or stop click the plan ' +
        'where it happened. The suggested waypoints are the moments the server found the walker turning or ' +
        'standing still; accept them in order and each corner takes one click.',
    }),
    el('div', { className: 'row' }, field('Video', chooser).wrap),
    status,
    body,
  );

  const say = (text: string, assertive = false) => {
    status.textContent = text;
    ctx.announce(text, assertive);
  };

  (async () => {
    let videos: Video[];
    try {
      videos = (await ctx.api.get<{ videos: Video[] }>(venuePath(venueId, '/videos'), abort.signal)).videos;
    } catch (e) {
      ctx.fail(e, 'Reading the videos');
      return;
    }
    const usable = videos.filter((v) => v.status !== 'uploading');
    if (!usable.length) {
      chooser.disabled = true;
      chooser.append(new Option('No uploaded video yet', ''));
      body.replaceChildren(
        el(
          'p',
          {},
          'Upload a walk video first (',
          el('a', { href: `#/v/${encodeURIComponent(venueId)}/videos`, textContent: 'Videos' }),
          ').',
        ),
      );
      return;
    }
    chooser.append(new Option('Choose a video…', ''));
    for (const v of usable)
      chooser.append(new Option(`${v.name} (${v.has_walk_path ? 'tagged' : 'not tagged'}, floor ${v.floor})`, v.name));
    chooser.addEventListener('change', () => {
      if (chooser.value) ctx.go('walk-path', { video: chooser.value });
    });
    // without ?video=, the first modelling walk still to tag (or the first video) is opened
    const v = wanted
      ? usable.find((x) => x.name === wanted)
      : (usable.find((x) => !x.has_walk_path && x.role === 'model') ?? usable[0]);
    if (!v) {
      body.replaceChildren(el('p', { textContent: 'Choose the video whose walk path to tag.' }));
      return;
    }
    chooser.value = v.name;
    // the list's document may be older than the video's own: read it
    try {
      editor(await ctx.api.get<Video>(venuePath(venueId, `/videos/${encodeURIComponent(v.name)}`), abort.signal));
    } catch (e) {
      ctx.fail(e, `Reading ${v.name}`);
    }
  })();

  // ---- the editor of one video's walk path ---------------------------------------------------------
  function editor(video: Video): void {
    const name = video.name;
    const videoPath = venuePath(venueId, `/videos/${encodeURIComponent(name)}`);
    const sugg = video.suggestions;
    const fps = video.fps ?? sugg?.fps ?? video.walk_path?.fps ?? 30;
    const duration =
      video.duration_s ??
      sugg?.duration_s ??
      (video.frames > 0 ? video.frames / fps : null) ??
      (video.walk_path ? Math.max(...fromWalkPath(video.walk_path, fps).map((p) => p.t)) : null);
    const suggestions: Suggestion[] = sugg?.suggestions ?? [];
    let points: Point[] = fromWalkPath(video.walk_path, fps);
    let offset = video.walk_path?.heading_offset_deg ?? 0;
    let t = 0;
    let saved = JSON.stringify(toWalkPath(points, offset));
    let modelled = video.status === 'modelled';
    /** The suggestion a plan click accepts (the video stands at its time). */
    let current = -1;
    const lines = corridorLines(ctx.venue().places, video.floor);
    // the admin's own landmarks, to tag the walk by: named on the plan, and listed in words
    const landmarks = ctx.venue().places.filter((p) => p.floor === video.floor && !p.area);

    // the frame views
    const rawImg = el('img', { alt: 'Camera frame', width: 480, height: 480 });
    const panoImg = el('img', { alt: 'Unwrapped panorama', width: 1440, height: 288 });
    const rawBox = el('div', { className: 'frame-box' }, rawImg);
    const mark = el('div', { className: 'walk-mark' }, el('span', { textContent: 'walking direction' }));
    mark.setAttribute('aria-hidden', 'true');
    const panoBox = el('div', { className: 'frame-box' }, panoImg, mark);
    const rawCap = el('figcaption', { textContent: 'The camera frame' });
    const panoCap = el('figcaption', {
      textContent: 'Unwrapped panorama (all around; the yellow line is the walking direction)',
    });

    // the scrubber
    const step = 1 / fps;
    const scrub = el('input', { type: 'range', min: '0', step: String(step), value: '0' });
    scrub.max = String(duration ?? 600);
    scrub.setAttribute('aria-label', `Time in ${name}`);
    const clock = el('output', { textContent: formatTime(0) });
    clock.setAttribute('aria-hidden', 'true');
    const play = button('Play', () => (playing ? stopPlay() : startPlay()));
    const back = button('Back 1 s', () => seek(t - 1), 'secondary');
    const fwd = button('Forward 1 s', () => seek(t + 1), 'secondary');
    const prevFrame = button('Previous frame', () => seek(t - step), 'secondary');
    const nextFrame = button('Next frame', () => seek(t + step), 'secondary');

    // the walking direction
    const offsetIn = el('input', { type: 'number', step: '1', min: '-180', max: '360', value: String(offset) });
    offsetIn.addEventListener('change', () => {
      const v = Number(offsetIn.value);
      if (!Number.isFinite(v)) return;
      offset = v;
      drawMark();
      drawState();
    });
    const drawMark = () => {
      mark.style.left = `${(walkColumn(offset) * 100).toFixed(2)}%`;
    };
    drawMark();

    // the suggestions
    const suggList = el('ul', { className: 'suggestions', id: 'suggestions' });
    const suggTitle = el('h3', {
      id: uid('sugg'),
      textContent: suggestions.length ? `Suggested waypoints (${suggestions.length})` : 'Suggested waypoints',
    });
    suggList.setAttribute('aria-labelledby', suggTitle.id);
    const acceptAll = button('Tag the suggestions in order', () => {
      const i = nextUntagged(suggestions, points);
      if (i < 0) say('Every suggestion has a waypoint.');
      else choose(i);
    });
    const suggHint = el('p', { className: 'hint', id: 'suggestion-next' });

    // the plan and the waypoints
    const planEl = el('div', { className: 'plan', id: 'walk-path-plan' });
    const snap = el('input', { type: 'checkbox', checked: lines.length > 0 });
    snap.disabled = lines.length === 0;
    const snapField = el(
      'div',
      { className: 'field inline' },
      snap,
      ' ',
      el('label', {
        htmlFor: (snap.id = uid('snap')),
        textContent: lines.length
          ? 'Snap to the corridor lines (the middle of each area; to the crossing near a corner)'
          : 'Snap to the corridor lines (no place has an area on this floor)',
      }),
    );
    const { table: wpTable, body: wpBody } = dataTable('Waypoints', ['#', 'Time (s)', 'x (m)', 'y (m)', 'Actions'], {
      id: 'waypoints',
      className: 'waypoints',
    });
    const addHere = button(
      'Add a waypoint at the current time',
      () => {
        const added = addAt(points, t);
        points = added.points;
        changed(added.said);
        wpBody.querySelector<HTMLInputElement>(`tr[data-t="${added.at.toFixed(3)}"] input.wp-x`)?.focus();
      },
      'secondary',
    );
    const problem = el('p', { className: 'problem', id: 'walk-path-problem', hidden: true });
    const save = button('Save the walk path', () => void doSave());
    const download = el('a', { textContent: `Download ${name}.walk_path.json`, href: '#', id: 'walk-path-download' });
    download.addEventListener('click', (e) => {
      const blob = new Blob([JSON.stringify(toWalkPath(points, offset), null, 1)], { type: 'application/json' });
      const url = URL.createObjectURL(blob);
      download.href = url;
      download.download = `${name}.walk_path.json`;
      setTimeout(() => URL.revokeObjectURL(url), 10_000);
      if (!points.length) e.preventDefault();
    });
    const dirty = el('span', { className: 'hint', id: 'walk-path-dirty' });

    body.replaceChildren(
      el('div', { className: 'walk-path-views' }, el('figure', {}, rawBox, rawCap), el('figure', {}, panoBox, panoCap)),
      el(
        'div',
        { className: 'scrub' },
        el('label', { htmlFor: (scrub.id = uid('scrub')), textContent: 'Time' }),
        scrub,
        clock,
        play,
        prevFrame,
        nextFrame,
        back,
        fwd,
      ),
      el(
        'div',
        { className: 'row' },
        field('Heading offset (°): the lens looks this far clockwise of the walking direction', offsetIn).wrap,
      ),
      el(
        'div',
        { className: 'work' },
        el(
          'div',
          {},
          planEl,
          snapField,
          el('p', {
            className: 'hint',
            id: 'walk-path-landmarks',
            textContent: landmarkLine(ctx.venue().places, video.floor),
          }),
        ),
        el(
          'div',
          { className: 'panel' },
          suggTitle,
          suggestions.length
            ? el('div', {}, acceptAll, suggHint)
            : el('p', {
                textContent:
                  'No suggestions for this video (they appear when the server has looked for its turns and stops): ' +
                  'tag it by hand.',
              }),
          suggList,
          wpTable,
          el('div', { className: 'row' }, addHere),
          problem,
          el('div', { className: 'row' }, save, download, dirty),
        ),
      ),
    );

    // ---- frames ------------------------------------------------------------------------------
    const cache = new Map<string, string>();
    let inflight: AbortController | null = null;
    let timer: ReturnType<typeof setTimeout> | null = null;
    let shownT = -1;

    const frameUrl = async (view: 'raw' | 'panorama', at: number, signal: AbortSignal): Promise<string> => {
      const key = `${view}:${at.toFixed(3)}`;
      const hit = cache.get(key);
      if (hit) {
        cache.delete(key);
        cache.set(key, hit);
        return hit;
      }
      const width = view === 'raw' ? 480 : 1440;
      const url = await ctx.api.blobUrl(`${videoPath}/frame?t=${at.toFixed(3)}&view=${view}&width=${width}`, signal);
      cache.set(key, url);
      while (cache.size > CACHE) {
        const [k, u] = cache.entries().next().value as [string, string];
        cache.delete(k);
        URL.revokeObjectURL(u);
      }
      return url;
    };

    const loadFrames = async (at: number): Promise<void> => {
      inflight?.abort();
      const mine = new AbortController();
      inflight = mine;
      abort.signal.addEventListener('abort', () => mine.abort(), { once: true });
      rawBox.classList.add('loading');
      panoBox.classList.add('loading');
      try {
        const [raw, pano] = await Promise.all([
          frameUrl('raw', at, mine.signal),
          frameUrl('panorama', at, mine.signal),
        ]);
        if (mine.signal.aborted) return;
        await Promise.all([setSrc(rawImg, raw), setSrc(panoImg, pano)]);
        rawImg.alt = `Camera frame of ${name} at ${formatTime(at)}`;
        panoImg.alt = `Unwrapped panorama of ${name} at ${formatTime(at)}; the marked line is the walking direction`;
        shownT = at;
      } catch (e) {
        if (mine.signal.aborted || (e instanceof DOMException && e.name === 'AbortError')) return;
        if (e instanceof AdminError && e.status === 422) say(`No frame at ${formatTime(at)}: ${e.message}`);
        else ctx.fail(e, `Showing the frame at ${formatTime(at)}`);
      } finally {
        if (inflight === mine) {
          inflight = null;
          rawBox.classList.remove('loading');
          panoBox.classList.remove('loading');
        }
      }
    };

    const requestFrames = (now = false) => {
      if (timer) clearTimeout(timer);
      timer = setTimeout(
        () => {
          timer = null;
          if (Math.abs(shownT - t) > 1e-6) void loadFrames(t);
        },
        now ? 0 : DEBOUNCE_MS,
      );
    };

    const seek = (to: number, announce = false) => {
      const max = Number(scrub.max);
      // frames: the scrubber's steps
      t = Math.min(max, Math.max(0, Math.round(to * fps) / fps));
      scrub.value = String(t);
      syncClock();
      if (current >= 0 && Math.abs(suggestions[current].t - t) > step / 2) current = -1;
      drawHere();
      drawSuggestions();
      requestFrames();
      if (announce) ctx.announce(`At ${formatTime(t)}.`);
    };
    const syncClock = () => {
      clock.textContent = `${formatTime(t)}${duration ? ` / ${formatTime(duration)}` : ''}`;
      scrub.setAttribute('aria-valuetext', formatTime(t));
    };
    scrub.addEventListener('input', () => seek(Number(scrub.value)));

    // play: the video moves at its own pace, each frame shown once the server has rendered it
    let playing = false;
    const startPlay = () => {
      playing = true;
      play.textContent = 'Pause';
      void (async () => {
        let last = performance.now();
        while (playing && !abort.signal.aborted) {
          const now = performance.now();
          const next = t + Math.max(step, (now - last) / 1000);
          last = now;
          if (next >= Number(scrub.max)) {
            seek(Number(scrub.max));
            break;
          }
          seek(next);
          if (timer) clearTimeout(timer);
          timer = null;
          await loadFrames(t);
          await new Promise((r) => setTimeout(r, 30));
        }
        stopPlay();
      })();
    };
    const stopPlay = () => {
      if (!playing) return;
      playing = false;
      play.textContent = 'Play';
    };

    // ---- the plan ----------------------------------------------------------------------------
    map = ctx.planMap(planEl);
    map.el.classList.add('picking');
    let drawn: L.Layer[] = [];
    let here: L.Circle | null = null;

    const place = (m: { x: number; y: number }): { x: number; y: number; line: string | null } =>
      snap.checked ? snapToLines(m, lines) : { ...m, line: null };

    const drawPlan = () => {
      if (!map) return;
      for (const l of drawn) l.remove();
      drawn = [];
      if (snap.checked)
        for (const l of lines)
          drawn.push(
            map.addPolyline(
              [
                [l.x0, l.y0],
                [l.x1, l.y1],
              ],
              { color: '#005a00', weight: 1, dashArray: '6 6', interactive: false },
            ),
          );
      for (const lm of landmarks)
        drawn.push(
          map.addMarker(lm.x, lm.y, {
            label: `Place: ${lm.name}`,
            className: 'pm-landmark',
            text: lm.name,
            passive: true,
          }),
        );
      if (points.length > 1)
        drawn.push(
          map.addPolyline(
            points.map((p) => [p.x, p.y] as [number, number]),
            { interactive: false },
          ),
        );
      points.forEach((p, i) => {
        const m = map!.addMarker(p.x, p.y, {
          label: `Waypoint ${i + 1} at ${formatTime(p.t)}: x ${p.x.toFixed(2)} m, y ${p.y.toFixed(2)} m`,
          className: 'pm-waypoint',
          text: String(i + 1),
          draggable: true,
          onMove: (to) => {
            const s = place(to);
            points = points.map((q) => (q === p ? { ...q, x: s.x, y: s.y } : q));
            changed(`Waypoint ${i + 1} moved to x ${s.x.toFixed(2)}, y ${s.y.toFixed(2)} m${snapWords(to, s)}.`);
          },
          onSelect: () => seek(p.t, true),
        });
        drawn.push(m);
      });
      drawHere();
    };

    const drawHere = () => {
      if (!map) return;
      here?.remove();
      here = null;
      const at = positionAt(points, t);
      if (at)
        here = map.addCircle(at.x, at.y, 0.6, {
          color: '#000',
          fillColor: '#ffbf00',
          fillOpacity: 0.9,
          weight: 2,
          interactive: false,
        });
    };

    cleanup.push(
      map.onClick((m) => {
        const s = place(m);
        const where = `x ${s.x.toFixed(2)}, y ${s.y.toFixed(2)} m${snapWords(m, s)}`;
        if (current >= 0 && Math.abs(suggestions[current].t - t) <= step / 2) {
          const sg = suggestions[current];
          points = acceptSuggestion(points, sg, s);
          const nxt = nextUntagged(suggestions, points, current + 1);
          // said once, with what comes next (the next suggestion, or that every one is tagged)
          changed(`${suggestionText(sg)} tagged at ${where}.`, false);
          if (nxt >= 0) choose(nxt, true);
          else {
            current = -1;
            drawSuggestions();
            say(
              `${suggestionText(sg)} tagged at ${where}. Every suggestion has a waypoint now: check the walk path and save it.`,
            );
          }
          return;
        }
        points = putPoint(points, { t, x: s.x, y: s.y });
        changed(`Waypoint at ${formatTime(t)}, ${where}.`);
      }),
    );
    snap.addEventListener('change', () => drawPlan());

    // ---- suggestions -------------------------------------------------------------------------
    const choose = (i: number, after = false) => {
      current = i;
      const s = suggestions[i];
      seek(s.t);
      current = i;
      drawSuggestions();
      requestFrames(true);
      // the next one's frames, fetched while the admin looks at this one
      const nxt = suggestions[nextUntagged(suggestions, points, i + 1)];
      if (nxt) {
        const at = Math.round(nxt.t * fps) / fps;
        void Promise.all([frameUrl('raw', at, abort.signal), frameUrl('panorama', at, abort.signal)]).catch(() => {});
      }
      const msg = `${after ? 'Next: ' : ''}${suggestionText(s)}. Click the plan where it happened.`;
      suggHint.textContent = msg;
      if (after) status.textContent = `${status.textContent} ${msg}`;
      ctx.announce(after ? (status.textContent ?? msg) : msg);
    };

    const suggButtons: HTMLButtonElement[] = [];
    suggestions.forEach((s, i) => {
      const b = button(suggestionText(s), () => choose(i));
      b.dataset.t = String(s.t);
      suggButtons.push(b);
      suggList.append(el('li', {}, b));
    });
    const drawSuggestions = () => {
      suggestions.forEach((s, i) => {
        const b = suggButtons[i];
        const tagged = isTagged(s, points);
        b.parentElement?.classList.toggle('tagged', tagged);
        b.setAttribute('aria-current', String(i === current));
        b.replaceChildren(suggestionText(s), tagged ? el('span', { className: 'tag', textContent: ', tagged ✓' }) : '');
      });
      if (current < 0) suggHint.textContent = '';
    };

    // ---- the waypoint table ------------------------------------------------------------------
    // each row's waypoint: a redraw puts the focus back on the same field of the same waypoint
    // (Tab out of a changed x lands on its y, which the redraw replaces)
    const rowPoint = new WeakMap<Element, Point>();
    const drawTable = () => {
      wpBody.replaceChildren(
        ...points.map((p, i) => {
          const n = i + 1;
          const tIn = el('input', { type: 'number', step: String(step), min: '0', value: String(+p.t.toFixed(3)) });
          tIn.className = 'wp-t';
          tIn.setAttribute('aria-label', `Waypoint ${n} time in seconds`);
          const xIn = el('input', { type: 'number', step: '0.01', value: String(+p.x.toFixed(2)), className: 'wp-x' });
          xIn.setAttribute('aria-label', `Waypoint ${n} x in metres`);
          const yIn = el('input', { type: 'number', step: '0.01', value: String(+p.y.toFixed(2)), className: 'wp-y' });
          yIn.setAttribute('aria-label', `Waypoint ${n} y in metres`);
          const typed = () => {
            const nt = Number(tIn.value);
            const nx = Number(xIn.value);
            const ny = Number(yIn.value);
            if (![nt, nx, ny].every(Number.isFinite) || tIn.value === '' || xIn.value === '' || yIn.value === '') {
              for (const i2 of [tIn, xIn, yIn])
                i2.setAttribute('aria-invalid', String(i2.value === '' || !Number.isFinite(Number(i2.value))));
              return;
            }
            // the row's waypoint as it stands: a second change before the redraw replaces the first
            const was = rowPoint.get(tr) ?? p;
            const np = { t: nt, x: nx, y: ny };
            points = [...points.filter((q) => q !== was), np].sort((a, b) => a.t - b.t);
            rowPoint.set(tr, np);
            // redrawn once the focus has moved (a change fires on Tab before the next field has it)
            setTimeout(() => {
              const active = document.activeElement;
              const row = active && wpBody.contains(active) ? active.closest('tr') : null;
              const control = row ? [...row.querySelectorAll('input, button')].indexOf(active!) : -1;
              // a value typed into the focused field since (a busy page brought this redraw late)
              // is committed first, by the change its blur fires; removed by the redraw, the field
              // would fire that change after the table was drawn from the points without it
              const mine = rowPoint.get(tr);
              if (row && active instanceof HTMLInputElement) active.blur();
              const of = row ? rowPoint.get(row) : undefined;
              // said by the redraw of the change the blur fired, where that was this row's
              const now = rowPoint.get(tr) ?? np;
              changed(`Waypoint ${n} set to ${formatTime(now.t)}, x ${now.x} m, y ${now.y} m.`, now === mine);
              const k = of ? points.indexOf(of) : -1;
              if (k >= 0 && control >= 0)
                wpBody.rows[k]?.querySelectorAll<HTMLElement>('input, button')[control]?.focus();
            }, 0);
          };
          for (const i2 of [tIn, xIn, yIn]) i2.addEventListener('change', typed);
          const go = button('Go to', () => seek(p.t, true), 'secondary');
          go.setAttribute('aria-label', `Go to waypoint ${n} (${formatTime(p.t)})`);
          const del = button(
            'Delete',
            () => {
              points = points.filter((q) => q !== p);
              changed(`Waypoint ${n} deleted.`);
              (
                wpBody.querySelectorAll<HTMLButtonElement>('button.danger')[Math.min(i, points.length - 1)] ?? addHere
              ).focus();
            },
            'danger',
          );
          del.setAttribute('aria-label', `Delete waypoint ${n}`);
          const tr = el(
            'tr',
            { dataset: { t: p.t.toFixed(3) } },
            el('th', { scope: 'row', textContent: String(n) }),
            el('td', {}, tIn),
            el('td', {}, xIn),
            el('td', {}, yIn),
            el('td', {}, go, ' ', del),
          );
          rowPoint.set(tr, p);
          return tr;
        }),
      );
    };

    const drawState = () => {
      const p = walkPathProblem(points, duration);
      problem.hidden = !p || points.length === 0;
      problem.textContent = p ?? '';
      save.disabled = !!p;
      const isDirty = JSON.stringify(toWalkPath(points, offset)) !== saved;
      dirty.textContent = isDirty ? 'Unsaved changes.' : points.length ? 'Saved.' : '';
    };

    /** Redraw after a change of the points, and say `msg` (`aloud` false: only show it, for a caller that says more). */
    const changed = (msg: string, aloud = true) => {
      const keep = document.activeElement;
      drawPlan();
      drawTable();
      drawSuggestions();
      drawState();
      if (keep instanceof HTMLElement && keep.isConnected) keep.focus();
      if (aloud) say(msg);
      else status.textContent = msg;
    };

    const doSave = async () => {
      const p = walkPathProblem(points, duration);
      if (p) {
        say(p, true);
        return;
      }
      const walkPath = toWalkPath(points, offset);
      save.disabled = true;
      try {
        const v = await ctx.api.put<Video>(`${videoPath}/walk-path`, walkPath);
        saved = JSON.stringify(walkPath);
        // a modelled video whose walk path changed is modelled again by the next modelling
        const again = modelled && v.status === 'ready' ? '; the next modelling models it again with it' : '';
        modelled = v.status === 'modelled';
        say(`Walk path of ${name} saved: ${points.length} waypoints${again}.`);
        ctx.recheck();
      } catch (e) {
        if (e instanceof AdminError) status.textContent = `Not saved: ${e.message}`;
        ctx.fail(e, 'Saving the walk path');
      } finally {
        drawState();
        if (!save.disabled) enable(save);
      }
    };

    const onKey = (e: KeyboardEvent) => {
      // the space bar plays and pauses when the focus is on the frames or the scrubber
      if (e.key === ' ' && (e.target === scrub || e.target === body)) {
        e.preventDefault();
        if (playing) stopPlay();
        else startPlay();
      }
    };
    scrub.addEventListener('keydown', onKey);

    cleanup.push(() => {
      stopPlay();
      if (timer) clearTimeout(timer);
      inflight?.abort();
      for (const u of cache.values()) URL.revokeObjectURL(u);
      cache.clear();
    });

    syncClock();
    drawPlan();
    drawTable();
    drawSuggestions();
    drawState();
    const first = nextUntagged(suggestions, points);
    if (first >= 0 && points.length === 0) {
      suggHint.textContent = 'Start with "Tag the suggestions in order", or scrub and click the plan.';
    }
    requestFrames(true);
  }

  return () => {
    abort.abort();
    for (const c of cleanup) c();
    cleanup = [];
    map?.remove();
    map = null;
  };
}

/** Show an object URL in an image; resolves when it is decoded (or failed), so playing waits for it. */
function setSrc(img: HTMLImageElement, url: string): Promise<void> {
  if (img.src === url) return Promise.resolve();
  img.src = url;
  return img.decode().catch(() => {});
}
