/**
 * Step 5, lens profiles: upload a lens.json (PUT lenses/{name}) and see it drawn over a frame of
 * an uploaded video (the server's raw frame at a chosen time): the ring's two circles and the
 * forward direction, so that a wrong profile shows at a glance; and a table of its values.
 */
import { venuePath } from '../api';
import type { AdminContext } from '../context';
import { el, enable, field, markInvalid, num, numberInput } from '../dom';
import { lensOverlay, lensRows } from '../lens-view';
import type { Lens } from '../../shared/lens';
import type { Video } from '../types';

const ID = /^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$/;

export function mount(root: HTMLElement, ctx: AdminContext): () => void {
  const abort = new AbortController();
  const venueId = ctx.venue().id;
  const urls: string[] = [];
  let videos: Video[] = [];

  // ---- upload
  const file = el('input', { type: 'file', accept: 'application/json,.json', name: 'lens-file' });
  const nameIn = el('input', { name: 'lens-name', pattern: ID.source, autocomplete: 'off', spellcheck: false });
  file.addEventListener('change', () => {
    const f = file.files?.[0];
    if (f && !nameIn.value)
      nameIn.value = f.name
        .replace(/\.json$/i, '')
        .replace(/[^A-Za-z0-9_-]/g, '-')
        .slice(0, 64);
  });
  const uploadBtn = el('button', { type: 'submit', textContent: 'Upload the lens profile' });
  const form = el(
    'form',
    { noValidate: true, className: 'row' },
    field('Lens profile file (lens.json)', file).wrap,
    field('Profile name', nameIn, 'Letters, digits, - and _; videos name their lens by it.').wrap,
    uploadBtn,
  );

  // ---- view
  const lensSel = el('select', { name: 'lens' });
  const videoSel = el('select', { name: 'video' });
  const tIn = numberInput(1, 0);
  const showBtn = el('button', { type: 'submit', textContent: 'Show the frame' });
  const viewForm = el(
    'form',
    { noValidate: true, className: 'row' },
    field('Lens profile', lensSel).wrap,
    field('Video', videoSel).wrap,
    field('Time in the video (seconds)', tIn).wrap,
    showBtn,
  );
  const frameBox = el('div', { className: 'frame-view', id: 'lens-frame' });
  const caption = el('p', { id: 'lens-caption' });
  const figure = el('figure', { className: 'lens-figure' }, frameBox, el('figcaption', {}, caption));
  const warn = el('p', { className: 'problem', hidden: true, id: 'lens-warning' });
  const table = el('table', { id: 'lens-table' });

  root.append(
    el('h2', { textContent: 'Lens profiles' }),
    el('h3', { textContent: 'Upload a profile' }),
    form,
    el('h3', { textContent: 'Check a profile on a frame' }),
    el(
      'p',
      { className: 'hint' },
      'The yellow circle is the ring’s outer edge, the dashed blue one its inner edge, the red arrow ' +
        'points forward. On a right profile the circles follow the picture’s ring.',
    ),
    viewForm,
    warn,
    figure,
    el('h3', { textContent: 'Values' }),
    table,
  );

  const lenses = (): Record<string, Lens> => ctx.venue().lenses;

  const fillLenses = (want?: string): void => {
    const names = Object.keys(lenses()).sort();
    lensSel.replaceChildren(...names.map((n) => new Option(n, n)));
    if (!names.length) lensSel.append(new Option('(no profile yet)', ''));
    lensSel.value = want && names.includes(want) ? want : (names[0] ?? '');
  };

  const fillVideos = (): void => {
    const ok = videos.filter((v) => v.status !== 'uploading');
    videoSel.replaceChildren(...ok.map((v) => new Option(`${v.name} (lens ${v.lens})`, v.name)));
    if (!ok.length) videoSel.append(new Option('(no uploaded video: the profile is drawn on a blank frame)', ''));
    const forLens = ok.find((v) => v.lens === lensSel.value);
    if (forLens) videoSel.value = forLens.name;
  };

  let shown = 0;
  /** Draw the chosen profile over the chosen video's frame (or a blank frame of its size). */
  const show = async (announce: boolean): Promise<void> => {
    const mine = ++shown;
    const name = lensSel.value;
    const lens = lenses()[name];
    warn.hidden = true;
    if (!lens) {
      frameBox.replaceChildren();
      table.replaceChildren();
      caption.textContent = 'No lens profile yet: upload one above.';
      return;
    }
    table.replaceChildren(
      el('caption', { textContent: `Lens profile ${name}` }),
      el('tr', {}, el('th', { scope: 'col', textContent: 'Value' }), el('th', { scope: 'col', textContent: name })),
      ...lensRows(lens).map(([k, v]) =>
        el('tr', {}, el('th', { scope: 'row', textContent: k }), el('td', { textContent: v })),
      ),
    );
    const video = videos.find((v) => v.name === videoSel.value);
    const size: [number, number] =
      video?.width && video.height ? [video.width, video.height] : [lens.image_size[0], lens.image_size[1]];
    let img: HTMLImageElement | null = null;
    const t = Number.isFinite(num(tIn)) ? Math.max(0, num(tIn)) : 0;
    if (video) {
      try {
        const q = new URLSearchParams({ t: t.toFixed(2), view: 'raw' });
        const url = await ctx.api.blobUrl(
          venuePath(venueId, `/videos/${encodeURIComponent(video.name)}/frame?${q}`),
          abort.signal,
        );
        urls.push(url);
        img = el('img', {
          src: url,
          alt: `Frame of ${video.name} at ${t.toFixed(1)} s`,
          width: size[0],
          height: size[1],
        });
      } catch (err) {
        if (mine === shown) ctx.fail(err, `Reading a frame of ${video.name}`);
      }
    }
    if (mine !== shown) return;
    const blank = el('div', { className: 'blank-frame' });
    blank.style.aspectRatio = `${size[0]} / ${size[1]}`;
    frameBox.replaceChildren(img ?? blank, lensOverlay(lens, size));
    frameBox.style.width = `min(100%, ${Math.min(size[0], 960)}px)`;
    const what = img ? `a frame of ${video!.name} at ${t.toFixed(1)} s` : `a blank ${size[0]} × ${size[1]} frame`;
    caption.textContent =
      lens.model === 'catadioptric'
        ? `Lens profile ${name} over ${what}: the ring from ${lens.r_inner} to ${lens.r_outer} pixels around ` +
          `${lens.center[0]}, ${lens.center[1]}; forward at ${lens.forward_deg ?? 0}° image angle.`
        : `Lens profile ${name} over ${what}: forward at column ${lens.forward_x}, the horizon across the middle.`;
    if (video?.width && video.height && (video.width !== lens.image_size[0] || video.height !== lens.image_size[1])) {
      warn.textContent =
        `${video.name}'s frames are ${video.width} × ${video.height} pixels, but ${name} is for ` +
        `${lens.image_size[0]} × ${lens.image_size[1]}: this profile does not fit this camera.`;
      warn.hidden = false;
    }
    if (announce) ctx.announce(caption.textContent + (warn.hidden ? '' : ` ${warn.textContent}`));
  };

  form.addEventListener('submit', (e) => {
    e.preventDefault();
    const f = file.files?.[0];
    const name = nameIn.value.trim();
    if (!f) return ctx.announce('Choose a lens profile file (lens.json) first.', true);
    if (!ID.test(name)) {
      markInvalid(nameIn);
      return ctx.announce(
        'The profile name must start with a letter or digit and have only letters, digits, - and _.',
        true,
      );
    }
    nameIn.removeAttribute('aria-invalid');
    uploadBtn.disabled = true;
    void f
      .text()
      .then(async (text) => {
        let body: unknown;
        try {
          body = JSON.parse(text);
        } catch {
          return ctx.announce(`${f.name} is not JSON: a lens profile is a JSON object (docs/formats.md).`, true);
        }
        await ctx.api.put<Lens>(venuePath(venueId, `/lenses/${encodeURIComponent(name)}`), body);
        await ctx.refresh();
        fillLenses(name);
        fillVideos();
        await show(false);
        ctx.announce(`Lens profile ${name} saved. ${caption.textContent ?? ''}`);
      })
      .catch((err: unknown) => ctx.fail(err, `Saving lens profile ${name}`))
      .finally(() => enable(uploadBtn));
  });

  viewForm.addEventListener('submit', (e) => {
    e.preventDefault();
    void show(true);
  });
  lensSel.addEventListener('change', () => {
    fillVideos();
    void show(true);
  });
  videoSel.addEventListener('change', () => void show(true));

  fillLenses();
  fillVideos();
  void show(false);
  ctx.api
    .get<{ videos: Video[] }>(venuePath(venueId, '/videos'), abort.signal)
    .then((r) => {
      videos = r.videos;
      fillVideos();
      return show(false);
    })
    .catch((err: unknown) => ctx.fail(err, 'Reading the videos'));

  return () => {
    abort.abort();
    for (const u of urls) URL.revokeObjectURL(u);
  };
}
