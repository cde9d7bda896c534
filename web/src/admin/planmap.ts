/**
 * A floor plan as a Leaflet map in plan METRES (docs/formats.md): L.CRS.Simple with lat = -y_m and
 * lng = x_m, the plan image spanning [[-h_px/px_per_m, 0], [0, w_px/px_per_m]]. Before a scale is
 * set, px_per_m is 1 (metres are pixels) and the scale bar says the scale is missing. Leaflet does
 * the pan and zoom; the screens add markers, lines and rectangles through the helpers, all in
 * metres, so that a plan replaced or re-scaled shows the same places where they are in the building.
 */
import * as L from 'leaflet';
import type { Floor } from '../shared/api-types';
import { fromMap, metresLabel, planBounds, scaleBar, toMap, type Metres } from './geometry';

export type { Metres } from './geometry';

export interface MarkerOptions {
  /** The marker's accessible name (and tooltip), e.g. "Place: the lifts". */
  label: string;
  /** A CSS class for its look (admin.css): 'pm-place', 'pm-point', 'pm-waypoint', ... */
  className?: string;
  /** Text shown inside the marker (a letter or number), if any. */
  text?: string;
  draggable?: boolean;
  /** Called when a drag ends, with the new position in metres. */
  onMove?: (m: Metres) => void;
  /** Called on click or Enter/Space on the focused marker. */
  onSelect?: () => void;
  /**
   * Only to be seen (a landmark drawn beside what is edited): not focusable, not clickable, and
   * hidden from screen readers, for whom the screen says the same in text.
   */
  passive?: boolean;
}

/** Draws the scale bar: Leaflet's own control measures the earth, which a CRS.Simple plan is not. */
class ScaleBar extends L.Control {
  private bar!: HTMLElement;
  private text!: HTMLElement;

  constructor(private readonly plan: PlanMap) {
    super({ position: 'bottomleft' });
  }

  onAdd(map: L.Map): HTMLElement {
    const box = L.DomUtil.create('div', 'pm-scale');
    this.bar = L.DomUtil.create('div', 'pm-scale-bar', box);
    this.text = L.DomUtil.create('div', 'pm-scale-text', box);
    map.on('zoomend', () => this.update());
    this.update();
    return box;
  }

  update(): void {
    if (!this.bar) return;
    const map = this.plan.map;
    // CRS.Simple: one map unit is 2^zoom screen pixels
    const pxPerUnit = 2 ** map.getZoom();
    const { length, px } = scaleBar(pxPerUnit);
    this.bar.style.width = `${Math.round(px)}px`;
    this.text.textContent = this.plan.scaled
      ? metresLabel(length)
      : `${+length.toPrecision(3)} plan pixels (scale not set)`;
  }
}

export class PlanMap {
  readonly map: L.Map;
  /** What the screens draw (cleared by clear()); the plan image is not in it. */
  readonly layers: L.LayerGroup;
  private image: L.ImageOverlay | null = null;
  private floorDoc: Floor | null = null;
  private readonly scaleBar: ScaleBar;
  private clicks = new Set<(m: Metres, e: L.LeafletMouseEvent) => void>();
  private moves = new Set<(m: Metres) => void>();

  /**
   * @param el the container (given a size by CSS); it becomes a labelled region
   * @param label the region's name, e.g. "Floor plan of Ground floor"
   */
  constructor(
    readonly el: HTMLElement,
    label = 'Floor plan',
  ) {
    el.classList.add('planmap');
    this.map = L.map(el, {
      crs: L.CRS.Simple,
      minZoom: -6,
      maxZoom: 7,
      zoomSnap: 0.25,
      zoomDelta: 0.5,
      attributionControl: false,
      boxZoom: false,
      doubleClickZoom: false, // two quick clicks are two points (scale, rectangle corners)
    });
    el.setAttribute('role', 'region');
    el.setAttribute('aria-label', label);
    el.setAttribute('aria-roledescription', 'map');
    // the drawing layer (walk path lines, areas) is a picture without a name: every screen says the
    // same in text beside the map (the place list, the waypoint table), so screen readers skip it
    this.map.on('layeradd', () =>
      el.querySelectorAll('svg.leaflet-zoom-animated:not([aria-hidden])').forEach((svg) => {
        svg.setAttribute('aria-hidden', 'true');
      }),
    );
    this.layers = L.layerGroup().addTo(this.map);
    this.scaleBar = new ScaleBar(this);
    this.scaleBar.addTo(this.map);
    this.map.setView([-15, 25], 3);
    this.map.on('click', (e: L.LeafletMouseEvent) => {
      const m = fromMap(e.latlng);
      for (const cb of this.clicks) cb(m, e);
    });
    this.map.on('mousemove', (e: L.LeafletMouseEvent) => {
      const m = fromMap(e.latlng);
      for (const cb of this.moves) cb(m);
    });
  }

  /** The floor shown (null before setFloor). */
  get floor(): Floor | null {
    return this.floorDoc;
  }

  /** Plan pixels per metre: the floor's scale, or 1 when none is set (metres are then pixels). */
  get pxPerM(): number {
    return this.floorDoc?.px_per_m ?? 1;
  }

  /** Whether the floor has a scale (without one, distances are in plan pixels). */
  get scaled(): boolean {
    return !!this.floorDoc?.px_per_m;
  }

  /**
   * Show a floor: its plan image (the public plan URL, `?v=` the venue revision so that a replaced
   * plan is fetched again) fitted to the view. Resolves when the image has loaded (or failed).
   */
  async setFloor(floor: Floor, revision = 0, fit = true): Promise<void> {
    const scaleChanged = this.floorDoc?.px_per_m !== floor.px_per_m;
    this.floorDoc = floor;
    this.image?.remove();
    this.image = null;
    this.scaleBar.update();
    if (!floor.plan_url || !floor.plan_size_px) {
      if (fit) this.map.setView([-15, 25], 3);
      return;
    }
    const bounds = planBounds(floor.plan_size_px, this.pxPerM);
    const sep = floor.plan_url.includes('?') ? '&' : '?';
    const img = L.imageOverlay(`${floor.plan_url}${sep}v=${revision}`, bounds, {
      alt: `Plan image of ${floor.name}`,
      className: 'pm-plan',
    });
    this.image = img;
    const loaded = new Promise<void>((resolve) => {
      img.once('load', () => resolve());
      img.once('error', () => resolve());
    });
    img.addTo(this.map);
    img.bringToBack();
    if (fit || scaleChanged) this.fit();
    await loaded;
  }

  /** Fit the view to the plan (or to a default 50 m x 30 m sheet without one). */
  fit(): void {
    const f = this.floorDoc;
    if (f?.plan_size_px) this.map.fitBounds(planBounds(f.plan_size_px, this.pxPerM), { padding: [8, 8] });
    else
      this.map.fitBounds([
        [-30, 0],
        [0, 50],
      ]);
  }

  /** Metres -> a Leaflet LatLng on this map. */
  latLng(x: number, y: number): L.LatLng {
    const p = toMap(x, y);
    return L.latLng(p.lat, p.lng);
  }

  /** A Leaflet LatLng -> metres. */
  metres(ll: L.LatLngExpression): Metres {
    return fromMap(L.latLng(ll));
  }

  /** Metres -> plan pixels (for the scale, which the server takes in plan pixels). */
  toPx(m: Metres): [number, number] {
    return [m.x * this.pxPerM, m.y * this.pxPerM];
  }

  /** A click on the plan (not on a marker), in metres; returns its removal. */
  onClick(cb: (m: Metres, e: L.LeafletMouseEvent) => void): () => void {
    this.clicks.add(cb);
    return () => this.clicks.delete(cb);
  }

  /** The pointer moving over the plan, in metres; returns its removal. */
  onMove(cb: (m: Metres) => void): () => void {
    this.moves.add(cb);
    return () => this.moves.delete(cb);
  }

  /** A marker at (x, y) metres: focusable, named, optionally draggable (the new position in metres). */
  addMarker(x: number, y: number, opts: MarkerOptions): L.Marker {
    const icon = L.divIcon({
      className: `pm-marker ${opts.className ?? 'pm-place'}`,
      html: opts.text ? escapeHtml(opts.text) : '',
      iconSize: [18, 18],
      iconAnchor: [9, 9],
    });
    const m = L.marker(this.latLng(x, y), {
      icon,
      title: opts.label,
      alt: opts.label,
      draggable: !!opts.draggable && !opts.passive,
      keyboard: !opts.passive,
      interactive: !opts.passive,
      riseOnHover: !opts.passive,
    });
    m.on('add', () => {
      const el = m.getElement();
      if (el && opts.passive) el.setAttribute('aria-hidden', 'true');
      else if (el) {
        el.setAttribute('aria-label', opts.label);
        el.setAttribute('role', 'button');
        if (opts.onSelect) {
          el.addEventListener('keydown', (e) => {
            if (e.key === 'Enter' || e.key === ' ') {
              e.preventDefault();
              opts.onSelect?.();
            }
          });
        }
      }
    });
    if (opts.onMove) m.on('dragend', () => opts.onMove?.(this.metres(m.getLatLng())));
    if (opts.onSelect) m.on('click', () => opts.onSelect?.());
    m.addTo(this.layers);
    return m;
  }

  /** A line through points given as [x, y] metres. */
  addPolyline(points: readonly (readonly [number, number])[], opts: L.PolylineOptions = {}): L.Polyline {
    return L.polyline(
      points.map(([x, y]) => this.latLng(x, y)),
      { color: '#0033aa', weight: 3, ...opts },
    ).addTo(this.layers);
  }

  /** A rectangle [x0, y0, x1, y1] in metres (a place's area). */
  addRectangle(area: readonly number[], opts: L.PolylineOptions = {}): L.Rectangle {
    const [x0, y0, x1, y1] = area;
    return L.rectangle(L.latLngBounds(this.latLng(x0, y0), this.latLng(x1, y1)), {
      color: '#005a00',
      weight: 2,
      fillOpacity: 0.12,
      ...opts,
    }).addTo(this.layers);
  }

  /** A circle of `radiusM` metres around (x, y). */
  addCircle(x: number, y: number, radiusM: number, opts: L.CircleMarkerOptions = {}): L.Circle {
    return L.circle(this.latLng(x, y), { radius: radiusM, color: '#0033aa', weight: 2, ...opts }).addTo(this.layers);
  }

  /** Move a marker or set a rectangle's bounds in metres (after a typed value). */
  moveMarker(m: L.Marker, x: number, y: number): void {
    m.setLatLng(this.latLng(x, y));
  }

  setRectangle(r: L.Rectangle, area: readonly number[]): void {
    r.setBounds(L.latLngBounds(this.latLng(area[0], area[1]), this.latLng(area[2], area[3])));
  }

  /** Remove everything the screens drew (not the plan). */
  clear(): void {
    this.layers.clearLayers();
  }

  /** Call after the container's size changed (a panel opened beside it). */
  resize(): void {
    this.map.invalidateSize();
  }

  remove(): void {
    this.clicks.clear();
    this.moves.clear();
    this.map.remove();
    this.el.classList.remove('planmap');
  }
}

function escapeHtml(s: string): string {
  return s.replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);
}
