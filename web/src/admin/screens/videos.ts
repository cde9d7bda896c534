/**
 * Step 6, the walk videos: dropped or chosen (several at once), checked here against the lens's
 * frame size, then uploaded resumably in pieces with a progress bar, speed and time left, pause and
 * resume (uploader.ts). A reload or a dropped connection loses nothing: the server keeps what
 * arrived, and the same file chosen again continues from the server's `received`. When a video is
 * in, the server finds its turns and stops (a suggest job) for the walk path screen.
 */
import { venuePath } from '../api';
import type { AdminContext } from '../context';
import { button, dataTable, el, field, uid } from '../dom';
import { formatBytes, formatTime } from '../format';
import '../media.css';
import type { LensCheck, Video } from '../types';
import { uploads, type Upload, type UploadOptions } from '../uploader';
import { matchUpload } from '../upload';

const ROLE_TEXT = { model: 'modelling walk', evaluation: 'evaluation walk' } as const;

/**
 * What the screen has said of each upload (its state, whether its turns were found), kept while
 * the page lives: uploads go on while the admin is on other screens, and on coming back only what
 * happened since is said.
 */
const told = new WeakMap<Upload, { state: string; turns: boolean }>();

export function mount(root: HTMLElement, ctx: AdminContext): () => void {
  const abort = new AbortController();
  const venue = ctx.venue();
  const venueId = venue.id;
  let videos: Video[] = [];

  // ---- what the new videos are: floor, lens, role --------------------------------------------
  const floorSel = el('select');
  for (const f of venue.floors) floorSel.append(new Option(f.name === f.id ? `Floor ${f.id}` : f.name, f.id));
  floorSel.value = ctx.floor();
  const lensSel = el('select');
  const lensNames = Object.keys(venue.lenses);
  for (const n of lensNames) {
    const l = venue.lenses[n];
    lensSel.append(new Option(`${n} (${l.model}, ${l.image_size[0]}x${l.image_size[1]})`, n));
  }
  const roleSel = el('select');
  roleSel.append(
    new Option('Modelling walk (builds the map)', 'model'),
    new Option('Evaluation walk (checks the map)', 'evaluation'),
  );
  const fileInput = el('input', { type: 'file', multiple: true, accept: 'video/*,.mp4,.mov,.m4v,.avi,.mkv,.webm' });
  fileInput.disabled = lensNames.length === 0;
  const noLens = lensNames.length
    ? null
    : el(
        'p',
        { className: 'problem' },
        'This venue has no lens profile yet: add the lens the videos were filmed with first (',
        el('a', { href: `#/v/${encodeURIComponent(venueId)}/lenses`, textContent: 'Lenses' }),
        ').',
      );

  const drop = el(
    'div',
    { className: 'dropzone', id: 'video-drop' },
    el('p', { className: 'dropzone-text', textContent: 'Drop walk videos here, or choose them:' }),
    field('Walk video files', fileInput).wrap,
  );
  const addSection = el(
    'section',
    { className: 'add-videos' },
    el('h3', { textContent: 'Add walk videos' }),
    noLens,
    el(
      'div',
      { className: 'row' },
      field('Floor', floorSel).wrap,
      field('Lens', lensSel).wrap,
      field('Role', roleSel).wrap,
    ),
    drop,
    el('p', {
      className: 'hint',
      textContent:
        'Each video is sent in pieces. If the connection drops it continues by itself; if the page is ' +
        'reloaded or closed, choose the same file again (here, or beside its name below) and it continues ' +
        'from where the server stands, not from the beginning. The page keeps which file is which only ' +
        'while it is open.',
    }),
  );

  const uploadList = el('ul', { className: 'uploads', id: 'uploads' });
  const uploadTitle = el('h3', { id: uid('uploads-title'), textContent: 'Uploads from this window' });
  uploadList.setAttribute('aria-labelledby', uploadTitle.id);
  const uploadSection = el('section', { hidden: true }, uploadTitle, uploadList);

  const { table, body: tableBody } = dataTable(
    'Videos of this venue',
    ['Video', 'Floor and lens', 'Role', 'Status', 'Walk path', 'Actions'],
    { id: 'video-table', className: 'videos' },
  );
  const noVideos = el('p', { id: 'no-videos', textContent: 'No videos yet.', hidden: true });

  root.replaceChildren(
    el('h2', { textContent: 'Videos' }),
    el('p', {
      textContent:
        'Walk videos filmed with the lens: modelling walks build the map (their walk path is tagged next), ' +
        'evaluation walks check it.',
    }),
    addSection,
    uploadSection,
    el('section', {}, el('h3', { textContent: 'On the server' }), table, noVideos),
  );

  // ---- adding files ----------------------------------------------------------------------------
  const options = (): UploadOptions => {
    const lens = venue.lenses[lensSel.value];
    return {
      venue: venueId,
      floor: floorSel.value,
      lens: lensSel.value,
      role: roleSel.value as 'model' | 'evaluation',
      imageSize: lens?.image_size,
    };
  };

  const addFiles = (files: File[], opts = options()) => {
    if (!files.length) return;
    if (fileInput.disabled) {
      ctx.announce('Add a lens profile first: the videos need one.', true);
      return;
    }
    // a file that continues an unfinished upload keeps that upload's floor, lens and role
    const groups = files.map((f) => {
      const v = matchUpload(f, videos);
      return {
        f,
        opts: v ? { ...opts, floor: v.floor, lens: v.lens, role: v.role, imageSize: lensSize(v.lens) } : opts,
      };
    });
    for (const g of groups) uploads.add([g.f], g.opts, ctx.api);
    ctx.announce(
      files.length === 1
        ? `Checking ${files[0].name}.`
        : `Checking ${files.length} videos; they upload one after another.`,
    );
    render();
  };
  const lensSize = (name: string): [number, number] | undefined => ctx.venue().lenses[name]?.image_size;

  fileInput.addEventListener('change', () => {
    addFiles([...(fileInput.files ?? [])]);
    fileInput.value = '';
  });
  drop.addEventListener('dragover', (e) => {
    e.preventDefault();
    drop.classList.add('over');
  });
  drop.addEventListener('dragleave', () => drop.classList.remove('over'));
  drop.addEventListener('drop', (e) => {
    e.preventDefault();
    drop.classList.remove('over');
    addFiles([...(e.dataTransfer?.files ?? [])].filter((f) => f.type.startsWith('video/') || /\.\w+$/.test(f.name)));
  });

  // ---- the uploads of this window ------------------------------------------------------------
  interface Row {
    li: HTMLLIElement;
    bar: HTMLProgressElement;
    facts: HTMLElement;
    status: HTMLElement;
    pause: HTMLButtonElement;
    replace: HTMLButtonElement;
    remove: HTMLButtonElement;
    turns: HTMLElement;
    state: string;
    suggest: string;
    /** The connection was lost and that was said (retries are not announced again). */
    lost: boolean;
    received: number;
    turnsSaid: boolean;
  }
  const rows = new Map<Upload, Row>();

  const rowFor = (u: Upload): Row => {
    let r = rows.get(u);
    if (r) return r;
    const bar = el('progress', { max: Math.max(1, u.size), value: 0 });
    bar.setAttribute('aria-label', `Upload of ${u.name}`);
    const status = el('span', { className: 'upload-status' });
    const pause = button('Pause', () => {
      if (u.state === 'sending' || u.state === 'offline' || u.state === 'retrying' || u.state === 'waiting') u.pause();
      else void u.resume();
    });
    const replace = button(`Replace the one on the server`, () => void u.replaceExisting(), 'secondary');
    const remove = button(
      'Remove from this list',
      () => {
        uploads.remove(u);
        rows.get(u)?.li.remove();
        rows.delete(u);
        ctx.announce(
          u.state === 'done' ? `${u.name} removed from the list.` : `${u.name} removed; choose it again to continue.`,
        );
        render();
      },
      'secondary',
    );
    const facts = el('span', { className: 'upload-facts' });
    const turns = el('div', { className: 'upload-turns' });
    const li = el(
      'li',
      { className: 'upload', dataset: { name: u.name } },
      el('p', {}, el('strong', { textContent: u.name }), ' ', facts),
      el('div', { className: 'upload-progress' }, bar, ' ', status),
      el('div', { className: 'row' }, pause, replace, remove),
      turns,
    );
    r = {
      li,
      bar,
      facts,
      status,
      pause,
      replace,
      remove,
      turns,
      // what was said of this upload on an earlier visit is not said again; what happened since is
      state: told.get(u)?.state ?? '',
      suggest: '',
      lost: false,
      received: 0,
      turnsSaid: told.get(u)?.turns ?? false,
    };
    rows.set(u, r);
    return r;
  };

  const drawUpload = (u: Upload) => {
    const r = rowFor(u);
    const p = u.probe;
    r.facts.textContent =
      `${formatBytes(u.size)}, floor ${u.opts.floor}, lens ${u.opts.lens}, ${ROLE_TEXT[u.opts.role]}` +
      (p ? `, ${p.width}x${p.height}${p.duration ? `, ${formatTime(p.duration)} long` : ''}` : '');
    r.bar.value = u.shown;
    r.bar.setAttribute('aria-valuetext', `${Math.floor((100 * u.shown) / Math.max(1, u.size))} %`);
    r.status.textContent = u.describe();
    r.li.classList.toggle('refused', u.state === 'refused' || u.state === 'failed');
    const running = ['sending', 'offline', 'retrying', 'waiting'].includes(u.state);
    r.pause.textContent = running ? 'Pause' : 'Resume';
    r.pause.setAttribute('aria-label', `${running ? 'Pause' : 'Resume'} the upload of ${u.name}`);
    r.pause.hidden = !(running || u.state === 'paused' || u.state === 'failed');
    r.replace.hidden = u.state !== 'exists';
    r.replace.setAttribute('aria-label', `Replace the one on the server: ${u.name}`);
    r.remove.setAttribute('aria-label', `Remove from this list: ${u.name}`);
    if (r.lost && u.state === 'sending' && u.received > r.received) {
      r.lost = false;
      ctx.announce(`Connection back: ${u.name} continues from ${formatBytes(u.received)}.`);
    }
    r.received = u.received;
    if (u.state !== r.state) {
      announceState(u, r.state, r);
      r.state = u.state;
      told.set(u, { state: r.state, turns: r.turnsSaid });
    }
    drawTurns(u, r);
  };

  const announceState = (u: Upload, before: string, r: Row) => {
    switch (u.state) {
      case 'sending':
        // a retry after a dropped connection is not news; the connection coming back is (below)
        if (!r.lost && before !== 'sending')
          ctx.announce(
            u.received > 0
              ? `Continuing ${u.name} from ${formatBytes(u.received)}, where the server stands.`
              : `Uploading ${u.name}.`,
          );
        break;
      case 'retrying':
        if (!r.lost) ctx.announce(`${u.name} waits: ${u.reason}. It tries again by itself.`);
        r.lost = true;
        break;
      case 'paused':
        r.lost = false;
        ctx.announce(`${u.name} paused at ${formatBytes(u.received)}.`);
        break;
      case 'offline':
        if (!r.lost)
          ctx.announce(
            `Connection lost while uploading ${u.name}; it continues by itself when the server answers again.`,
            true,
          );
        r.lost = true;
        break;
      case 'refused':
        r.lost = false;
        ctx.announce(`${u.name} was refused: ${u.reason}`, true);
        break;
      case 'failed':
        r.lost = false;
        ctx.announce(`${u.name} stopped: ${u.reason}`, true);
        break;
      case 'exists':
        ctx.announce(`A finished video named ${u.name} is already on the server: replace it, or remove this file.`);
        break;
      case 'done':
        r.lost = false;
        ctx.announce(`${u.name} is uploaded; finding its turns and stops.`);
        void loadVideos();
        ctx.recheck();
        break;
    }
  };

  const drawTurns = (u: Upload, r: Row) => {
    const job = u.suggest;
    const key = `${job?.state ?? ''}:${job?.frames_done ?? ''}:${u.suggestError}:${u.video?.suggestions ? 1 : 0}`;
    if (key === r.suggest) return;
    r.suggest = key;
    if (u.suggestError) {
      r.turns.replaceChildren(
        el('p', {
          textContent: `Could not find the turns and stops: ${u.suggestError}. The walk path can still be tagged by hand.`,
        }),
        walkPathLink(u.name),
      );
      return;
    }
    if (!job) {
      r.turns.replaceChildren();
      return;
    }
    if (job.state === 'queued' || job.state === 'running') {
      const bar = el('progress', { max: Math.max(1, job.frames_total), value: job.frames_done });
      bar.setAttribute('aria-label', `Finding turns and stops in ${u.name}`);
      r.turns.replaceChildren(
        el(
          'p',
          {},
          'Finding turns and stops: ',
          bar,
          ` ${job.state === 'queued' ? 'waiting to start' : `${job.frames_done} of ${job.frames_total} frames`}`,
        ),
      );
      return;
    }
    if (job.state === 'done') {
      const n = u.video?.suggestions?.suggestions.length ?? 0;
      r.turns.replaceChildren(el('p', {}, `${n} suggested waypoints (turns and stops). `, walkPathLink(u.name)));
      if (!r.turnsSaid) {
        ctx.announce(`${n} turns and stops found in ${u.name}. Its walk path can be tagged now.`);
        r.turnsSaid = true;
        told.set(u, { state: r.state, turns: true });
      }
      void loadVideos();
      return;
    }
    r.turns.replaceChildren(
      el('p', {
        textContent: `Finding turns and stops ${job.state}${job.error ? `: ${job.error}` : ''}. The walk path can still be tagged by hand.`,
      }),
      walkPathLink(u.name),
    );
  };

  const walkPathLink = (name: string) =>
    el('a', {
      href: `#/v/${encodeURIComponent(venueId)}/walk-path?video=${encodeURIComponent(name)}`,
      textContent: `Tag the walk path of ${name}`,
    });

  const render = () => {
    const mine = uploads.list.filter((u) => u.opts.venue === venueId);
    for (const [u, r] of rows)
      if (!mine.includes(u)) {
        r.li.remove();
        rows.delete(u);
      }
    for (const u of mine) {
      drawUpload(u);
      const li = rowFor(u).li;
      if (li.parentElement !== uploadList) uploadList.append(li);
    }
    uploadSection.hidden = mine.length === 0;
  };

  // ---- the server's videos -------------------------------------------------------------------
  const drawTable = () => {
    tableBody.replaceChildren(
      ...videos.map((v) => {
        const actions = el('td', { className: 'actions' });
        const inMemory = uploads.list.some((u) => u.opts.venue === venueId && u.name === v.name && u.state !== 'done');
        if (v.status === 'uploading' && !inMemory && !(v.error && v.received === 0)) {
          const again = el('input', { type: 'file', accept: 'video/*,.mp4,.mov,.m4v,.avi,.mkv,.webm' });
          again.setAttribute('aria-label', `Choose ${v.name} again to continue its upload`);
          again.addEventListener('change', () => {
            const f = again.files?.[0];
            again.value = '';
            if (!f) return;
            if (f.size !== v.size) {
              ctx.announce(
                `That file is ${formatBytes(f.size)}; the upload of ${v.name} is for a file of ${formatBytes(v.size)}. Choose the same file.`,
                true,
              );
              return;
            }
            const same = f.name === v.name ? f : new File([f], v.name, { type: f.type });
            addFiles([same], {
              venue: venueId,
              floor: v.floor,
              lens: v.lens,
              role: v.role,
              imageSize: lensSize(v.lens),
            });
          });
          actions.append(el('label', { className: 'file-again' }, 'Continue: ', again));
        }
        if (v.status !== 'uploading')
          actions.append(
            el('a', {
              href: `#/v/${encodeURIComponent(venueId)}/walk-path?video=${encodeURIComponent(v.name)}`,
              textContent: v.has_walk_path ? 'Edit the walk path' : 'Tag the walk path',
            }),
          );
        const del = button('Delete', () => confirmDelete(v, actions, del), 'danger');
        del.setAttribute('aria-label', `Delete ${v.name}`);
        actions.append(' ', del);
        const sugg = v.suggestions ? `, ${v.suggestions.suggestions.length} suggested waypoints` : '';
        const walkPath = v.has_walk_path
          ? `tagged (${v.walk_path?.waypoints.length ?? 0} waypoints)`
          : `not tagged${sugg}`;
        const tr = el(
          'tr',
          { dataset: { name: v.name } },
          el('th', { scope: 'row', textContent: v.name }),
          el('td', { textContent: `floor ${v.floor}, lens ${v.lens}` }),
          el('td', { textContent: ROLE_TEXT[v.role] ?? v.role }),
          el('td', { className: 'video-status', textContent: videoStatus(v) }),
          el('td', { textContent: v.status === 'uploading' ? '–' : walkPath }),
          actions,
        );
        return tr;
      }),
    );
    noVideos.hidden = videos.length > 0;
    table.hidden = videos.length === 0;
  };

  const confirmDelete = (v: Video, cell: HTMLElement, del: HTMLButtonElement) => {
    const what =
      v.status === 'modelled'
        ? `Delete ${v.name} and its ${v.frames} modelled frames? The venue then answers without them.`
        : `Delete ${v.name}${v.has_walk_path ? ' and its walk path' : ''}?`;
    const yes = button(
      `Delete ${v.name}`,
      async () => {
        try {
          await ctx.api.del(venuePath(venueId, `/videos/${encodeURIComponent(v.name)}`));
          ctx.announce(`${v.name} deleted.`);
          await ctx.refresh();
          await loadVideos();
        } catch (e) {
          ctx.fail(e, `Deleting ${v.name}`);
        }
      },
      'danger',
    );
    const no = button(
      'Keep it',
      () => {
        box.remove();
        del.hidden = false;
        del.focus();
      },
      'secondary',
    );
    const box = el('div', { className: 'confirm', role: 'group' }, el('p', { textContent: what }), yes, ' ', no);
    box.setAttribute('aria-label', `Confirm deleting ${v.name}`);
    del.hidden = true;
    cell.append(box);
    no.focus();
  };

  let loading: Promise<void> | null = null;
  const loadVideos = (): Promise<void> => {
    loading ??= (async () => {
      try {
        const r = await ctx.api.get<{ videos: Video[] }>(venuePath(venueId, '/videos'), abort.signal);
        videos = r.videos;
        drawTable();
      } catch (e) {
        if (!abort.signal.aborted) ctx.fail(e, 'Reading the videos');
      } finally {
        loading = null;
      }
    })();
    return loading;
  };

  const unlisten = uploads.listen((u) => {
    if (u.opts.venue !== venueId) return;
    render();
  });
  render();
  void loadVideos();

  return () => {
    abort.abort();
    unlisten();
  };
}

/**
 * A video's state in words, for the table: what was received while it uploads; then its size and
 * length, and for a modelling walk whether it is modelled (an evaluation walk is scored, never
 * modelled); whether it fits its lens.
 */
export function videoStatus(v: Video): string {
  if (v.status === 'uploading') {
    // a refused file is gone from the server (received is 0 again): say why, not "0 B received"
    if (v.error && v.received === 0) return `refused: ${v.error}`;
    return `uploading: ${formatBytes(v.received)} of ${formatBytes(v.size)} received`;
  }
  const facts = [
    v.width && v.height ? `${v.width}x${v.height}` : '',
    v.duration_s ? `${formatTime(v.duration_s)} long` : '',
  ].filter(Boolean);
  const what =
    v.role === 'evaluation'
      ? 'uploaded, to score the venue with (evaluation walks are not modelled)'
      : v.status === 'modelled'
        ? `modelled (${v.frames} frames)`
        : 'uploaded, not modelled yet';
  const lens = lensText(v.suggestions?.lens_check);
  return [facts.length ? `${what}; ${facts.join(', ')}` : what, lens].filter(Boolean).join('. ');
}

/** Does the video fit its lens (the server's check on its first frames)? Words for the table. */
export function lensText(check: LensCheck | null | undefined): string {
  if (!check) return '';
  if (check.verdict === 'same') return 'The lens sits where its profile says';
  if (check.verdict === 'corrected') return `The lens sits ${check.moved_px.toFixed(1)} px off its profile: corrected`;
  return `Does not fit its lens profile: ${check.message}`;
}
