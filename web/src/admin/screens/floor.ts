/**
 * Step 3, the floor and its plan: upload a plan (PNG or JPEG), set the scale by two points on the
 * plan and the distance between them (PUT floor `scale: {a, b, distance_m}` in plan pixels), see
 * the scale bar. Places and walk paths are stored in metres, so a replaced or re-scaled plan keeps them
 * where they are in the building; they are drawn on the plan to be checked. Every point can also be
 * typed (plan pixels), and the floor's name edited.
 */
import { venuePath } from '../api';
import type { AdminContext } from '../context';
import { el, enable, field, num, numberInput } from '../dom';
import { cm, metresLabel, scaleFromPoints } from '../geometry';
import type { PlanMap } from '../planmap';
import type { Floor } from '../../shared/api-types';
import type { Video } from '../types';
import type * as L from 'leaflet';

/** A floor id as the API takes it (openapi.yaml FloorId). */
const FLOOR_ID = /^[A-Za-z0-9][A-Za-z0-9_-]{0,31}$/;
const KEPT =
  'Places, areas and walk paths are stored in metres: replacing the plan or changing its scale keeps ' +
  'them where they are in the building. They are drawn on the plan below: check that they still ' +
  'sit where they belong.';

export function mount(root: HTMLElement, ctx: AdminContext): () => void {
  const venueId = ctx.venue().id;
  const floorId = ctx.floor();
  const floorPath = venuePath(venueId, `/floors/${encodeURIComponent(floorId)}`);
  const floorOf = (): Floor | undefined => ctx.venue().floors.find((f) => f.id === floorId);

  const facts = el('p', { id: 'floor-facts' });
  const kept = el('p', { className: 'hint', textContent: KEPT });
  const shown = el('p', { id: 'floor-shown' });
  let videos: Video[] = [];

  // ---- the plan image
  const file = el('input', { type: 'file', accept: 'image/png,image/jpeg', name: 'plan' });
  const uploadBtn = el('button', { type: 'submit', textContent: 'Upload the plan' });
  const uploadForm = el(
    'form',
    { noValidate: true, className: 'row' },
    field('Plan image (PNG or JPEG)', file, 'A picture of the floor plan, at most 8192 pixels on a side.').wrap,
    uploadBtn,
  );

  // ---- the floor's name
  const nameIn = el('input', { value: floorOf()?.name ?? '', maxLength: 200, autocomplete: 'off' });
  const nameForm = el(
    'form',
    { noValidate: true, className: 'row' },
    field('Floor name', nameIn).wrap,
    el('button', { type: 'submit', textContent: 'Save the name' }),
  );

  // ---- another floor of the building (each has its own plan, scale, places and walks)
  const newId = el('input', { maxLength: 32, autocomplete: 'off' });
  const newName = el('input', { maxLength: 200, autocomplete: 'off' });
  const addFloorForm = el(
    'form',
    { noValidate: true, className: 'row' },
    field('New floor id', newId, 'As answers name it, e.g. 2, B1 or mezzanine.').wrap,
    field('New floor name', newName, 'e.g. Second floor.').wrap,
    el('button', { type: 'submit', textContent: 'Add the floor' }),
  );

  // ---- the scale: two points (plan pixels) and their distance
  const ax = numberInput(null);
  const ay = numberInput(null);
  const bx = numberInput(null);
  const by = numberInput(null);
  const dist = numberInput(null, 0);
  const pick = el('button', { type: 'button', textContent: 'Pick the two points on the plan', className: 'secondary' });
  pick.setAttribute('aria-pressed', 'false');
  const pickHint = el('p', { className: 'hint', id: 'scale-pick-hint' });
  const saveScale = el('button', { type: 'submit', textContent: 'Save the scale' });
  const measured = el('p', { id: 'scale-measured' });
  const scaleForm = el(
    'form',
    { noValidate: true, className: 'scale-form' },
    el(
      'p',
      {},
      'Click two points on the plan whose distance you know (the two ends of a wall, a corridor), ' +
        'then type the distance between them. The points are in plan pixels and can also be typed.',
    ),
    pick,
    pickHint,
    el(
      'fieldset',
      {},
      el('legend', { textContent: 'First point (plan pixels)' }),
      el('div', { className: 'row' }, field('First point x', ax).wrap, field('First point y', ay).wrap),
    ),
    el(
      'fieldset',
      {},
      el('legend', { textContent: 'Second point (plan pixels)' }),
      el('div', { className: 'row' }, field('Second point x', bx).wrap, field('Second point y', by).wrap),
    ),
    field('Distance between the points (metres)', dist).wrap,
    measured,
    saveScale,
  );

  const planEl = el('div', { id: 'floor-plan' });
  const side = el(
    'div',
    { className: 'side' },
    el('h3', { textContent: 'Plan image' }),
    uploadForm,
    el('h3', { textContent: 'Scale' }),
    scaleForm,
    el('h3', { textContent: 'Name' }),
    nameForm,
    el('h3', { textContent: 'Another floor' }),
    addFloorForm,
  );
  root.append(
    el('h2', { textContent: 'Floor plan' }),
    facts,
    kept,
    shown,
    el('div', { className: 'work' }, planEl, side),
  );

  const map: PlanMap = ctx.planMap(planEl);
  let a: L.Marker | null = null;
  let b: L.Marker | null = null;
  let line: L.Polyline | null = null;
  let picking = 0; // 0: not picking; 1: the next click is the first point; 2: the second

  const pt = (x: HTMLInputElement, y: HTMLInputElement): [number, number] | null =>
    Number.isFinite(num(x)) && Number.isFinite(num(y)) ? [num(x), num(y)] : null;

  /** The typed points' pixel distance and, with a distance, the scale they make. */
  const describe = (): void => {
    const pa = pt(ax, ay);
    const pb = pt(bx, by);
    if (!pa || !pb) {
      measured.textContent = 'No points yet.';
      return;
    }
    const d = Math.hypot(pb[0] - pa[0], pb[1] - pa[1]);
    const m = num(dist);
    measured.textContent =
      `The points are ${d.toFixed(1)} plan pixels apart` +
      (m > 0 && d > 0 ? `: ${(d / m).toFixed(2)} pixels per metre.` : '.');
  };

  /** Draw the facts, the places (in metres, on the current scale) and the scale points. */
  const draw = (): void => {
    const f = floorOf();
    if (!f?.plan_url || !f.plan_size_px)
      facts.textContent = `${f?.name ?? `Floor ${floorId}`}: no plan yet. Upload one.`;
    else if (!f.px_per_m)
      facts.textContent =
        `${f.name}: plan ${f.plan_size_px[0]} × ${f.plan_size_px[1]} pixels; the scale is not set ` +
        '(distances are in plan pixels until it is).';
    else
      facts.textContent =
        `${f.name}: plan ${f.plan_size_px[0]} × ${f.plan_size_px[1]} pixels, ` +
        `${f.px_per_m.toFixed(2)} pixels per metre, so ${metresLabel(cm(f.plan_size_px[0] / f.px_per_m))} × ` +
        `${metresLabel(cm(f.plan_size_px[1] / f.px_per_m))}.`;
    map.clear();
    const places = ctx.venue().places.filter((p) => p.floor === floorId);
    for (const p of places) {
      if (p.area) map.addRectangle(p.area, { interactive: false });
      map.addMarker(p.x, p.y, { label: `Place: ${p.name}`, className: 'pm-place' });
    }
    const withPaths = videos.filter((v) => v.floor === floorId && v.walk_path?.waypoints.length);
    for (const v of withPaths)
      map.addPolyline(
        v.walk_path!.waypoints.map((w) => [w.x, w.y] as [number, number]),
        { color: '#6a00a8', weight: 3, dashArray: '8 4', interactive: false },
      );
    shown.textContent =
      `Drawn on the plan: ${places.length} place${places.length === 1 ? '' : 's'}` +
      (withPaths.length
        ? ` and the walk path${withPaths.length === 1 ? '' : 's'} of ${withPaths.map((v) => v.name).join(', ')}`
        : '') +
      ' (squares are places, green rectangles areas, dashed purple lines walk paths).';
    drawPoints();
  };

  const drawPoints = (): void => {
    a?.remove();
    b?.remove();
    line?.remove();
    a = b = line = null;
    const pa = pt(ax, ay);
    const pb = pt(bx, by);
    const s = map.pxPerM;
    const marker = (p: [number, number], which: string, text: string, xi: HTMLInputElement, yi: HTMLInputElement) =>
      map.addMarker(p[0] / s, p[1] / s, {
        label: `${which} scale point, at ${p[0].toFixed(0)}, ${p[1].toFixed(0)} plan pixels`,
        className: 'pm-point',
        text,
        draggable: true,
        onMove: (m) => {
          const [px, py] = map.toPx(m);
          xi.value = px.toFixed(1);
          yi.value = py.toFixed(1);
          drawPoints();
          describe();
          ctx.announce(`${which} point moved to ${px.toFixed(0)}, ${py.toFixed(0)} plan pixels.`);
        },
      });
    if (pa) a = marker(pa, 'First', 'A', ax, ay);
    if (pb) b = marker(pb, 'Second', 'B', bx, by);
    if (pa && pb)
      line = map.addPolyline(
        [
          [pa[0] / s, pa[1] / s],
          [pb[0] / s, pb[1] / s],
        ],
        { color: '#b00000', dashArray: '6 4', interactive: false },
      );
  };

  const setPicking = (n: number): void => {
    picking = n;
    pick.setAttribute('aria-pressed', String(n > 0));
    planEl.classList.toggle('picking', n > 0);
    pickHint.textContent =
      n === 1 ? 'Click the first point on the plan.' : n === 2 ? 'Now click the second point.' : '';
  };

  const offClick = map.onClick((m) => {
    if (!picking) return;
    const [px, py] = map.toPx(m);
    const [xi, yi] = picking === 1 ? [ax, ay] : [bx, by];
    xi.value = px.toFixed(1);
    yi.value = py.toFixed(1);
    const which = picking === 1 ? 'First' : 'Second';
    drawPoints();
    describe();
    if (picking === 1) {
      setPicking(2);
      ctx.announce(`${which} point at ${px.toFixed(0)}, ${py.toFixed(0)} plan pixels. Now click the second point.`);
    } else {
      setPicking(0);
      ctx.announce(`${which} point at ${px.toFixed(0)}, ${py.toFixed(0)} plan pixels. Type the distance between them.`);
      dist.focus();
    }
  });

  pick.addEventListener('click', () => {
    if (!floorOf()?.plan_url) return ctx.announce('Upload a plan first.', true);
    setPicking(picking ? 0 : 1);
    if (picking) ctx.announce('Click the first point on the plan.');
  });
  for (const i of [ax, ay, bx, by, dist])
    i.addEventListener('input', () => {
      describe();
      if (i !== dist) drawPoints();
    });

  const reload = async (fit: boolean): Promise<void> => {
    const v = await ctx.refresh();
    const f = v.floors.find((x) => x.id === floorId);
    if (f) await map.setFloor(f, v.revision, fit);
    nameIn.value = f?.name ?? nameIn.value;
    draw();
  };

  uploadForm.addEventListener('submit', (e) => {
    e.preventDefault();
    const f = file.files?.[0];
    if (!f) return ctx.announce('Choose a plan image (PNG or JPEG) first.', true);
    if (f.type !== 'image/png' && f.type !== 'image/jpeg')
      return ctx.announce(`${f.name} is not a PNG or JPEG image: the plan must be one.`, true);
    const had = !!floorOf()?.plan_url;
    uploadBtn.disabled = true; // which drops the keyboard focus: it is put back where the next step is
    let next: HTMLElement = file;
    ctx.api
      .upload<Floor>('PUT', `${floorPath}/plan`, f, f.type)
      .then(async (fl) => {
        await reload(true);
        next = fl.px_per_m ? uploadBtn : pick;
        ctx.announce(
          `Plan uploaded: ${fl.plan_size_px?.[0]} × ${fl.plan_size_px?.[1]} pixels.` +
            (had ? ' Places and walk paths kept their metres; check them on the new plan.' : '') +
            (fl.px_per_m ? '' : ' Now set its scale.'),
        );
      })
      .catch((err: unknown) => ctx.fail(err, 'Uploading the plan'))
      .finally(() => {
        uploadBtn.disabled = false;
        if (!document.activeElement || document.activeElement === document.body) next.focus();
      });
  });

  scaleForm.addEventListener('submit', (e) => {
    e.preventDefault();
    const pa = pt(ax, ay);
    const pb = pt(bx, by);
    const m = num(dist);
    if (!pa || !pb) return ctx.announce('Pick or type both points first.', true);
    if (!Number.isFinite(m)) {
      // text in a number field reads as empty: say what to type, not that it is 0
      dist.focus();
      return ctx.announce('Type the distance between the points in metres, as a number (for example 12.5).', true);
    }
    try {
      scaleFromPoints(pa, pb, m);
    } catch (err) {
      (m > 0 ? ax : dist).focus();
      return ctx.announce(`The scale cannot be set: ${err instanceof Error ? err.message : String(err)}.`, true);
    }
    saveScale.disabled = true;
    ctx.api
      .put<Floor>(floorPath, { scale: { a: pa, b: pb, distance_m: m } })
      .then(async (fl) => {
        await reload(true);
        ctx.announce(
          `Scale saved: ${fl.px_per_m?.toFixed(2)} pixels per metre. Places and walk paths kept their metres; check them on the plan.`,
        );
      })
      .catch((err: unknown) => ctx.fail(err, 'Saving the scale'))
      .finally(() => enable(saveScale));
  });

  addFloorForm.addEventListener('submit', (e) => {
    e.preventDefault();
    const id = newId.value.trim();
    const name = newName.value.trim() || `Floor ${id}`;
    if (!FLOOR_ID.test(id))
      return ctx.announce('A floor id is 1 to 32 letters, digits, "-" or "_", starting with a letter or digit.', true);
    if (ctx.venue().floors.some((f) => f.id === id)) return ctx.announce(`The venue already has floor ${id}.`, true);
    ctx.api
      .put<Floor>(venuePath(venueId, `/floors/${encodeURIComponent(id)}`), { name })
      .then(async () => {
        await ctx.refresh();
        ctx.announce(`Floor ${name} added: upload its plan.`);
        ctx.go('floor', { floor: id });
      })
      .catch((err: unknown) => ctx.fail(err, 'Adding the floor'));
  });

  nameForm.addEventListener('submit', (e) => {
    e.preventDefault();
    const name = nameIn.value.trim();
    if (!name) return ctx.announce('A floor name is needed.', true);
    ctx.api
      .put<Floor>(floorPath, { name })
      .then(async () => {
        await reload(false);
        ctx.announce(`Floor renamed to ${name}.`);
      })
      .catch((err: unknown) => ctx.fail(err, 'Renaming the floor'));
  });

  describe();
  draw();
  const abort = new AbortController();
  ctx.api
    .get<{ videos: Video[] }>(venuePath(venueId, '/videos'), abort.signal)
    .then((r) => {
      videos = r.videos;
      draw();
    })
    .catch((err: unknown) => ctx.fail(err, 'Reading the videos’ walk paths'));
  const keys = (e: KeyboardEvent): void => {
    if (e.key === 'Escape' && picking) {
      setPicking(0);
      ctx.announce('Stopped picking points.');
    }
  };
  document.addEventListener('keydown', keys);
  return () => {
    abort.abort();
    document.removeEventListener('keydown', keys);
    offClick();
    map.remove();
  };
}
