/**
 * Step 4, places: click on the plan to add a named place, drag it to move it, draw a rectangle (two
 * corners) for an area ("North corridor"), give it a kind and a sentence to speak on arrival, edit
 * and delete it; import a place file (docs/formats.md) and export one. Every value the plan sets is
 * also typeable (metres), and every place is also in the list beside the plan.
 */
import { venuePath } from '../api';
import type { AdminContext } from '../context';
import { button, el, field, markInvalid, num, numberInput } from '../dom';
import { areaOf, cm, type Metres } from '../geometry';
import { PLACE_KINDS, exportPlaces, parsePlaces, toInput, type EditablePlace, type PlaceInput } from '../places-io';
import type { PlanMap } from '../planmap';
import type * as L from 'leaflet';

type Mode = 'none' | 'add' | 'area1' | 'area2';

const where = (p: { x: number; y: number }): string => `${p.x.toFixed(1)} m, ${p.y.toFixed(1)} m`;

export function mount(root: HTMLElement, ctx: AdminContext): () => void {
  const venueId = ctx.venue().id;
  const floorId = ctx.floor();
  const placesPath = venuePath(venueId, '/places');
  const all = (): EditablePlace[] => ctx.venue().places as EditablePlace[];
  const mine = (): EditablePlace[] => all().filter((p) => p.floor === floorId);

  // ---- tools
  const addBtn = button('Add a place on the plan', () => setMode(mode === 'add' ? 'none' : 'add'), 'secondary');
  const areaBtn = button(
    'Draw an area on the plan',
    () => setMode(mode.startsWith('area') ? 'none' : 'area1'),
    'secondary',
  );
  addBtn.setAttribute('aria-pressed', 'false');
  areaBtn.setAttribute('aria-pressed', 'false');
  const typeBtn = button('New place by typing', () => edit(null, { x: NaN, y: NaN }), 'secondary');
  const modeHint = el('p', { className: 'hint', id: 'places-mode' });

  // ---- import / export
  const importFile = el('input', { type: 'file', accept: 'application/json,.json', name: 'places-file' });
  const importMode = el('select', { name: 'import-mode' });
  importMode.append(
    new Option('add them to the places there are', 'add'),
    new Option('replace all the places of the venue', 'replace'),
  );
  const importForm = el(
    'form',
    { noValidate: true, className: 'row' },
    field('Place file (JSON)', importFile, 'A list of {name, floor, x, y, area} in metres (docs/formats.md).').wrap,
    field('Imported places', importMode).wrap,
    el('button', { type: 'submit', textContent: 'Import the places' }),
  );
  const exportBtn = button('Export the places', () => exportNow(), 'secondary');

  const list = el('ul', { className: 'place-list', id: 'place-list' });
  const count = el('p', { id: 'places-count' });
  const editor = el('div', { className: 'editor', id: 'place-editor' });
  const planEl = el('div', { id: 'places-plan' });
  root.append(
    el('h2', { textContent: 'Places' }),
    el(
      'p',
      { className: 'hint' },
      'A place is a point one can be near or facing (the lifts, Room 102); with an area it is also a ' +
        'region one can be in (a corridor, a room). Positions are in metres on the plan; drag a place to move it.',
    ),
    el('div', { className: 'row' }, addBtn, areaBtn, typeBtn),
    modeHint,
    el(
      'div',
      { className: 'work' },
      planEl,
      el('div', { className: 'side' }, el('h3', { textContent: 'On this floor' }), count, list, editor),
    ),
    el('h3', { textContent: 'Import and export' }),
    importForm,
    exportBtn,
  );

  const map: PlanMap = ctx.planMap(planEl);
  let mode: Mode = 'none';
  let corner: Metres | null = null;
  let preview: L.Rectangle | null = null;
  let selected: string | null = null; // the selected place's id
  const markers = new Map<string, L.Marker>();

  function setMode(m: Mode): void {
    mode = m;
    addBtn.setAttribute('aria-pressed', String(m === 'add'));
    areaBtn.setAttribute('aria-pressed', String(m.startsWith('area')));
    planEl.classList.toggle('picking', m !== 'none');
    if (m !== 'area2') {
      preview?.remove();
      preview = null;
      corner = null;
    }
    const hint = {
      none: '',
      add: 'Click on the plan where the place is. Escape stops.',
      area1: 'Click one corner of the area on the plan. Escape stops.',
      area2: 'Now click the opposite corner.',
    }[m];
    modeHint.textContent = hint;
    if (hint) ctx.announce(hint);
  }

  const offMove = map.onMove((m) => {
    if (mode === 'area2' && corner) {
      const a = areaOf(corner, m);
      if (preview) map.setRectangle(preview, a);
      else preview = map.addRectangle(a, { dashArray: '5 5', interactive: false });
    }
  });

  const offClick = map.onClick((m) => {
    const p = { x: cm(m.x), y: cm(m.y) };
    if (mode === 'add') {
      setMode('none');
      edit(null, p);
    } else if (mode === 'area1') {
      corner = p;
      setMode('area2');
    } else if (mode === 'area2' && corner) {
      const area = areaOf(corner, p).map(cm) as [number, number, number, number];
      setMode('none');
      if (area[2] - area[0] < 0.05 || area[3] - area[1] < 0.05) {
        ctx.announce('That area has no size: click two opposite corners apart.', true);
        return;
      }
      edit(null, { x: cm((area[0] + area[2]) / 2), y: cm((area[1] + area[3]) / 2) }, area);
    }
  });

  /** The plan and the list, from the venue as held. */
  function draw(): void {
    map.clear();
    markers.clear();
    const ps = mine();
    for (const p of ps) {
      if (p.area)
        map.addRectangle(p.area, {
          interactive: false,
          color: p.id === selected ? '#0047b3' : '#005a00',
          weight: p.id === selected ? 3 : 2,
        });
      const mk = map.addMarker(p.x, p.y, {
        label: `Place: ${p.name}, at ${where(p)}`,
        className: p.id === selected ? 'pm-place pm-selected' : 'pm-place',
        draggable: true,
        onMove: (m) => void move(p, m),
        onSelect: () => edit(p),
      });
      markers.set(p.id, mk);
    }
    count.textContent = ps.length
      ? `${ps.length} place${ps.length === 1 ? '' : 's'} on this floor.`
      : 'No place on this floor yet.';
    list.replaceChildren(
      ...ps.map((p) => {
        const b = button(`${p.name} — ${where(p)}${p.area ? ', area' : ''}`, () => edit(p));
        b.setAttribute('aria-pressed', String(p.id === selected));
        b.dataset.place = p.id;
        return el('li', {}, b);
      }),
    );
  }

  /** Save the whole list with one place changed (the API has no PATCH of one place). */
  async function saveAll(places: PlaceInput[], what: string, name: string): Promise<void> {
    try {
      await ctx.api.put(placesPath, places);
      await settle(what, name);
    } catch (err) {
      ctx.fail(err, what);
      draw(); // a refused drag goes back where it was
    }
  }

  /** After a write: the venue re-read, the place found again by name (ids change on a PUT). */
  async function settle(said: string, name: string | null): Promise<void> {
    const typing = editor.contains(document.activeElement); // a form sent by keyboard, not a drag
    await ctx.refresh();
    const p = name ? mine().find((q) => q.name === name) : undefined;
    selected = p?.id ?? null;
    draw();
    if (p) edit(p, undefined, undefined, false);
    else editor.replaceChildren();
    ctx.announce(`${said}.`);
    // the form that had the focus was redrawn: a keyboard user goes on from the place in the list
    if (typing && (!document.activeElement || document.activeElement === document.body)) {
      const b = p ? list.querySelector<HTMLElement>(`button[data-place="${CSS.escape(p.id)}"]`) : null;
      (b ?? root.querySelector<HTMLElement>('button'))?.focus();
    }
  }

  async function move(p: EditablePlace, m: Metres): Promise<void> {
    const x = cm(m.x);
    const y = cm(m.y);
    const next = all().map((q) => (q.id === p.id ? { ...toInput(q), x, y } : toInput(q)));
    await saveAll(next, `Moved ${p.name} to ${where({ x, y })}`, p.name);
  }

  /** The editor: a new place (p null) at `at`, or an existing one. */
  function edit(p: EditablePlace | null, at?: Metres, area?: [number, number, number, number], focus = true): void {
    if (p) {
      selected = p.id;
      for (const b of list.querySelectorAll<HTMLButtonElement>('button[data-place]'))
        b.setAttribute('aria-pressed', String(b.dataset.place === p.id));
      for (const [id, mk] of markers) mk.getElement()?.classList.toggle('pm-selected', id === p.id);
    }
    const name = el('input', { value: p?.name ?? '', required: true, maxLength: 200, autocomplete: 'off' });
    const kind = el('select');
    kind.append(new Option('(none)', ''), ...PLACE_KINDS.map((k) => new Option(k, k)));
    kind.value = p?.kind ?? '';
    const x = numberInput(p ? p.x : (at?.x ?? NaN));
    const y = numberInput(p ? p.y : (at?.y ?? NaN));
    const a0 = p?.area ?? area ?? null;
    const isArea = el('input', { type: 'checkbox', checked: !!a0 });
    const ax0 = numberInput(a0 ? a0[0] : null);
    const ay0 = numberInput(a0 ? a0[1] : null);
    const ax1 = numberInput(a0 ? a0[2] : null);
    const ay1 = numberInput(a0 ? a0[3] : null);
    const areaBox = el(
      'fieldset',
      { hidden: !a0 },
      el('legend', { textContent: 'Area corners (metres)' }),
      el(
        'div',
        { className: 'row' },
        field('Area left x0', ax0).wrap,
        field('Area top y0', ay0).wrap,
        field('Area right x1', ax1).wrap,
        field('Area bottom y1', ay1).wrap,
      ),
    );
    isArea.addEventListener('change', () => {
      areaBox.hidden = !isArea.checked;
    });
    const say = el('textarea', { value: p?.say ?? '', maxLength: 500, rows: 2 });
    const title = p ? `Edit ${p.name}` : 'New place';
    const heading = el('h3', { id: 'place-editor-title', textContent: title, tabIndex: -1 });
    const form = el(
      'form',
      { noValidate: true },
      field('Place name', name).wrap,
      field('Kind', kind).wrap,
      el(
        'fieldset',
        {},
        el('legend', { textContent: 'Position (metres)' }),
        el('div', { className: 'row' }, field('Place x (m)', x).wrap, field('Place y (m)', y).wrap),
      ),
      el(
        'div',
        { className: 'field' },
        el('label', {}, isArea, ' This place is an area one can be in (a corridor, a room)'),
      ),
      areaBox,
      field('Sentence to say on arrival (optional)', say, 'e.g. “The lifts are on your left.”').wrap,
      el(
        'div',
        { className: 'row' },
        el('button', { type: 'submit', textContent: p ? 'Save the place' : 'Add the place' }),
        p ? button(`Delete ${p.name}`, () => void remove(p), 'danger') : null,
        button('Cancel', () => close(), 'secondary'),
      ),
    );
    form.setAttribute('aria-labelledby', heading.id);
    form.addEventListener('submit', (e) => {
      e.preventDefault();
      const input: PlaceInput = { name: name.value.trim(), floor: floorId, x: num(x), y: num(y) };
      if (!input.name) return problem(name, 'A place needs a name.');
      if (!Number.isFinite(input.x)) return problem(x, 'Type the place’s x in metres.');
      if (!Number.isFinite(input.y)) return problem(y, 'Type the place’s y in metres.');
      if (isArea.checked) {
        const c = [num(ax0), num(ay0), num(ax1), num(ay1)];
        if (!c.every(Number.isFinite)) return problem(ax0, 'Type all four corners of the area in metres.');
        if (c[2] <= c[0] || c[3] <= c[1]) return problem(ax1, 'The area needs x0 < x1 and y0 < y1.');
        input.area = [c[0], c[1], c[2], c[3]];
      }
      if (say.value.trim()) input.say = say.value.trim();
      if (kind.value) input.kind = kind.value;
      if (p) {
        const next = all().map((q) => (q.id === p.id ? input : toInput(q)));
        ctx.api
          .put(placesPath, next)
          .then(() => settle(`Saved ${input.name}`, input.name))
          .catch((err: unknown) => ctx.fail(err, `Saving ${input.name}`));
      } else {
        ctx.api
          .post(placesPath, [input])
          .then(() => settle(`Added ${input.name} at ${where(input)}`, input.name))
          .catch((err: unknown) => ctx.fail(err, `Adding ${input.name}`));
      }
    });
    // a typed position shows on the plan at once
    const preview = (): void => {
      const mk = p && markers.get(p.id);
      if (mk && Number.isFinite(num(x)) && Number.isFinite(num(y))) map.moveMarker(mk, num(x), num(y));
    };
    x.addEventListener('input', preview);
    y.addEventListener('input', preview);
    if (!p) {
      // a new place shows on the plan before it is saved (dashed: not yet a place), and the
      // status says the next step instead of the click it asked for
      draw();
      if (a0) map.addRectangle(a0, { dashArray: '5 5', interactive: false, className: 'pm-pending' });
      // ("New place by typing" has no point yet: NaN, nothing to show)
      const c = a0 ? { x: (a0[0] + a0[2]) / 2, y: (a0[1] + a0[3]) / 2 } : at;
      if (c && Number.isFinite(c.x) && Number.isFinite(c.y)) {
        map.addMarker(c.x, c.y, {
          label: 'The new place, not saved yet',
          className: 'pm-place pm-pending',
          passive: true,
        });
        ctx.announce(
          `${a0 ? 'Area' : 'Place'} marked at ${where({ x: c.x, y: c.y })}: name it, then press Add the place (or Cancel).`,
        );
      }
    }
    editor.replaceChildren(heading, form);
    if (focus) (p ? heading : name).focus();
  }

  function problem(input: HTMLElement, msg: string): void {
    ctx.announce(msg, true);
    markInvalid(input);
  }

  function close(): void {
    const was = selected;
    selected = null;
    editor.replaceChildren();
    draw();
    (list.querySelector<HTMLElement>(`button[data-place="${was}"]`) ?? addBtn).focus();
  }

  async function remove(p: EditablePlace): Promise<void> {
    try {
      await ctx.api.del(`${placesPath}/${encodeURIComponent(p.id)}`);
      selected = null;
      await settle(`Deleted ${p.name}`, null);
      addBtn.focus();
    } catch (err) {
      ctx.fail(err, `Deleting ${p.name}`);
    }
  }

  importForm.addEventListener('submit', (e) => {
    e.preventDefault();
    const f = importFile.files?.[0];
    if (!f) return ctx.announce('Choose a place file (JSON) first.', true);
    void f.text().then(async (text) => {
      let items: PlaceInput[];
      try {
        items = parsePlaces(
          text,
          ctx.venue().floors.map((fl) => fl.id),
        );
      } catch (err) {
        return ctx.announce(`${f.name} was not imported: ${err instanceof Error ? err.message : String(err)}.`, true);
      }
      const replace = importMode.value === 'replace';
      try {
        if (replace) await ctx.api.put(placesPath, items);
        else await ctx.api.post(placesPath, items);
        selected = null;
        await settle(
          `Imported ${items.length} place${items.length === 1 ? '' : 's'} from ${f.name}` +
            (replace ? ', replacing the ones there were' : ''),
          null,
        );
      } catch (err) {
        ctx.fail(err, `Importing ${f.name}`);
      }
    });
  });

  const urls: string[] = [];
  function exportNow(): void {
    const blob = new Blob([exportPlaces(all())], { type: 'application/json' });
    const url = URL.createObjectURL(blob);
    urls.push(url);
    const a = el('a', { href: url, download: `${venueId}-places.json` });
    a.hidden = true;
    root.append(a);
    a.click();
    a.remove();
    ctx.announce(`Exported ${all().length} places as ${venueId}-places.json.`);
  }

  const keys = (e: KeyboardEvent): void => {
    if (e.key === 'Escape' && mode !== 'none') {
      setMode('none');
      ctx.announce('Stopped.');
    }
  };
  document.addEventListener('keydown', keys);
  draw();
  return () => {
    document.removeEventListener('keydown', keys);
    offClick();
    offMove();
    for (const u of urls) URL.revokeObjectURL(u);
    map.remove();
  };
}
