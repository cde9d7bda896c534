/**
 * The floor plan as a view: the plan image with a pose drawn on it (position dot, heading arrow,
 * accuracy circle and the nearest place), a route when guiding (the way ahead, the way walked and
 * the destination), and its text alternative. The same facts are in the text
 * answer and the canvas's label: nothing is only on the map, and nothing is told by colour alone
 * (shapes and outlines differ too). It knows nothing of the phone's session, so that any page that
 * shows a plan (the app, the admin pages) draws it the same way.
 */
import { isSure } from '../../shared/sure';

/** What the view needs of a floor (a venue document's floor is one). */
export interface PlanFloor {
  name: string;
  plan_url: string | null;
  px_per_m: number | null;
}

/** What the view needs of a place (a venue document's place is one). */
export interface PlanPlace {
  name: string;
  x: number;
  y: number;
  area?: readonly number[] | null;
}

/** A pose to draw, in plan metres (a localisation answer is one). */
export interface PlanPose {
  x: number;
  y: number;
  heading_deg: number;
  low_confidence: boolean;
  confidence: number;
  accuracy_m: number | null;
  area: string | null;
  nearest: { name: string; distance_m: number } | null;
}

type XY = readonly [number, number];

/** A route to draw while guiding, in plan metres on the floor shown. */
export interface PlanRoute {
  /** The way ahead, from the user to the destination or the floor change (guidance.route). */
  ahead: readonly XY[];
  /** Where the user has been since guidance started (the filtered positions). */
  walked: readonly XY[];
  /** The destination, when it is on this floor. */
  to: { name: string; x: number; y: number } | null;
  /** Metres still to walk (guidance.remaining_m), for the text alternative. */
  remaining_m: number | null;
  /** The destination's name, for the text alternative. */
  toName: string;
}

const images = new Map<string, Promise<HTMLImageElement>>();

function loadImage(url: string): Promise<HTMLImageElement> {
  let p = images.get(url);
  if (!p) {
    p = new Promise((resolve, reject) => {
      const img = new Image();
      img.onload = () => resolve(img);
      img.onerror = () => reject(new Error(`floor plan ${url} did not load`));
      img.src = url;
    });
    images.set(url, p);
    p.catch(() => images.delete(url));
  }
  return p;
}

/** A canvas that shows one floor at a time; its label (the text alternative) follows the drawing. */
export class PlanView {
  // a newer drawing wins over an older one still waiting for its plan image
  private drawn = 0;

  constructor(readonly canvas: HTMLCanvasElement) {}

  /**
   * Draw the floor (a blank sheet when it has no plan) with the pose, if any, and the route when
   * guiding; resolves with the label.
   */
  async show(
    floor: PlanFloor | undefined,
    places: readonly PlanPlace[],
    pose: PlanPose | null,
    route: PlanRoute | null = null,
  ): Promise<string> {
    const mine = ++this.drawn;
    const img = floor?.plan_url ? await loadImage(floor.plan_url).catch(() => null) : null;
    if (mine !== this.drawn) return '';
    const label = draw(this.canvas, img, floor, places, pose, route);
    this.canvas.setAttribute('aria-label', label);
    return label;
  }
}

/** The text alternative for a floor and a pose: the same facts the drawing shows. */
export function planLabel(floorName: string | undefined, a: PlanPose | null): string {
  const fname = floorName ?? 'the floor';
  if (!a || a.low_confidence)
    return `Floor plan of ${fname}: no position shown${a ? ', the last answer was not sure' : ' yet'}.`;
  const where = a.area ? `in ${a.area}` : `at ${a.x.toFixed(1)} m, ${a.y.toFixed(1)} m`;
  const near = a.nearest ? `; nearest place ${a.nearest.name}, ${a.nearest.distance_m.toFixed(0)} m away` : '';
  const acc = a.accuracy_m ? `, within about ${a.accuracy_m} m` : '';
  const probably = isSure(a) ? '' : 'probably ';
  return `Floor plan of ${fname}: you are ${probably}${where}${acc}, facing ${planWay(a.heading_deg)} of the plan${near}.`;
}

const PLAN_WAYS = [
  'the top',
  'the top right',
  'the right',
  'the bottom right',
  'the bottom',
  'the bottom left',
  'the left',
  'the top left',
];

/**
 * A plan heading (degrees clockwise from the plan's top) as the part of the plan it points to, for
 * whoever looks at the plan with the user: "the top right" (a number of degrees says nothing there).
 */
export function planWay(headingDeg: number): string {
  const h = ((headingDeg % 360) + 360) % 360;
  return PLAN_WAYS[Math.floor((h + 22.5) / 45) % 8];
}

/** The words for a route on the plan: how far to go, and how far walked. */
export function routeLabel(r: PlanRoute): string {
  const left = r.remaining_m !== null ? `${Math.round(r.remaining_m)} metres` : 'the way';
  const walked = pathLength(r.walked);
  const done = walked >= 1 ? ` You have walked about ${Math.round(walked)} metres since you started.` : '';
  const shown = r.ahead.length >= 2 ? ` The route ahead is drawn as a thick purple line` : '';
  const end = shown ? `${shown}${r.to ? ', ending at a diamond' : ''}.` : '';
  return `Route: ${left} to ${r.toName}.${end}${done}`;
}

function pathLength(p: readonly XY[]): number {
  let d = 0;
  for (let i = 1; i < p.length; i++) d += Math.hypot(p[i][0] - p[i - 1][0], p[i][1] - p[i - 1][1]);
  return d;
}

/** A polyline in plan metres, `casing` first (a wider white line under it, readable on any plan). */
function polyline(
  ctx: CanvasRenderingContext2D,
  pts: readonly XY[],
  scale: number,
  colour: string,
  width: number,
  dash: number[],
): void {
  if (pts.length < 2) return;
  for (const [c, w, d] of [
    ['#ffffff', width + 4, []],
    [colour, width, dash],
  ] as const) {
    ctx.beginPath();
    ctx.moveTo(pts[0][0] * scale, pts[0][1] * scale);
    for (const [x, y] of pts.slice(1)) ctx.lineTo(x * scale, y * scale);
    ctx.strokeStyle = c;
    ctx.lineWidth = w;
    ctx.lineJoin = 'round';
    ctx.lineCap = 'round';
    ctx.setLineDash(d);
    ctx.stroke();
  }
  ctx.setLineDash([]);
}

/** The way walked (dashed grey), the way ahead (thick purple) and the destination (a diamond). */
function drawRoute(ctx: CanvasRenderingContext2D, r: PlanRoute, scale: number): void {
  polyline(ctx, r.walked, scale, '#555555', 3, [6, 6]);
  polyline(ctx, r.ahead, scale, '#7a00cc', 7, []);
  if (!r.to) return;
  const x = r.to.x * scale;
  const y = r.to.y * scale;
  ctx.beginPath();
  ctx.moveTo(x, y - 11);
  ctx.lineTo(x + 11, y);
  ctx.lineTo(x, y + 11);
  ctx.lineTo(x - 11, y);
  ctx.closePath();
  ctx.fillStyle = '#7a00cc';
  ctx.fill();
  ctx.lineWidth = 3;
  ctx.strokeStyle = '#000';
  ctx.stroke();
  ctx.font = 'bold 16px system-ui, sans-serif';
  // the name on the right of the diamond, or on its left where it would run off the sheet
  const w = ctx.measureText(r.to.name).width;
  const tx = x + 14 + w > ctx.canvas.width ? x - 14 - w : x + 14;
  ctx.lineWidth = 4;
  ctx.strokeStyle = '#fff';
  ctx.strokeText(r.to.name, tx, y + 18);
  ctx.fillStyle = '#000';
  ctx.fillText(r.to.name, tx, y + 18);
}

/** How far the sheet must reach (metres) to show the pose and the route. */
function extent(a: PlanPose | null, r: PlanRoute | null): XY {
  let [x, y] = [a?.x ?? 10, a?.y ?? 10];
  for (const [px, py] of [...(r?.ahead ?? []), ...(r?.walked ?? []), ...(r?.to ? [[r.to.x, r.to.y] as XY] : [])]) {
    x = Math.max(x, px);
    y = Math.max(y, py);
  }
  return [x, y];
}

/** Paint the sheet, the route and the pose; returns the label ('' where the canvas cannot draw). */
function draw(
  canvas: HTMLCanvasElement,
  img: HTMLImageElement | null,
  floor: PlanFloor | undefined,
  places: readonly PlanPlace[],
  a: PlanPose | null,
  route: PlanRoute | null = null,
): string {
  const ctx = canvas.getContext('2d');
  if (!ctx) return '';
  const scale = floor?.px_per_m ?? 20;
  const [ex, ey] = extent(a, route);
  canvas.width = img?.naturalWidth ?? Math.max(600, Math.ceil((ex + 10) * scale));
  canvas.height = img?.naturalHeight ?? Math.max(300, Math.ceil((ey + 10) * scale));
  ctx.fillStyle = '#ffffff';
  ctx.fillRect(0, 0, canvas.width, canvas.height);
  if (img) ctx.drawImage(img, 0, 0);
  if (route) drawRoute(ctx, route, scale);
  const label = planLabel(floor?.name, a) + (route ? ` ${routeLabel(route)}` : '');
  if (!a || a.low_confidence) return label;
  const px = a.x * scale;
  const py = a.y * scale;
  const n = a.nearest ? places.find((p) => p.name === a.nearest!.name && !p.area) : undefined;
  if (n) {
    // the nearest place: a square with a label (a dot is "you", a square is a place)
    const nx = n.x * scale;
    const ny = n.y * scale;
    ctx.fillStyle = '#006400';
    ctx.strokeStyle = '#000';
    ctx.lineWidth = 2;
    ctx.fillRect(nx - 7, ny - 7, 14, 14);
    ctx.strokeRect(nx - 7, ny - 7, 14, 14);
    ctx.font = 'bold 16px system-ui, sans-serif';
    ctx.lineWidth = 4;
    ctx.strokeStyle = '#fff';
    ctx.strokeText(n.name, nx + 10, ny - 10);
    ctx.fillStyle = '#000';
    ctx.fillText(n.name, nx + 10, ny - 10);
  }
  if (a.accuracy_m) {
    ctx.beginPath();
    ctx.arc(px, py, a.accuracy_m * scale, 0, 2 * Math.PI);
    ctx.fillStyle = 'rgba(0, 90, 255, 0.18)';
    ctx.fill();
    ctx.setLineDash([6, 4]);
    ctx.strokeStyle = '#0033aa';
    ctx.lineWidth = 2;
    ctx.stroke();
    ctx.setLineDash([]);
  }
  // heading: plan headings are clockwise from up, so the direction is (sin h, -cos h)
  const h = (a.heading_deg * Math.PI) / 180;
  const len = 2.5 * scale;
  const tx = px + Math.sin(h) * len;
  const ty = py - Math.cos(h) * len;
  ctx.strokeStyle = '#c00000';
  ctx.fillStyle = '#c00000';
  ctx.lineWidth = 4;
  ctx.beginPath();
  ctx.moveTo(px, py);
  ctx.lineTo(tx, ty);
  ctx.stroke();
  const wing = 0.5;
  ctx.beginPath();
  ctx.moveTo(tx + Math.sin(h) * 10, ty - Math.cos(h) * 10);
  ctx.lineTo(tx + Math.sin(h + Math.PI - wing) * 14, ty - Math.cos(h + Math.PI - wing) * 14);
  ctx.lineTo(tx + Math.sin(h + Math.PI + wing) * 14, ty - Math.cos(h + Math.PI + wing) * 14);
  ctx.closePath();
  ctx.fill();
  ctx.beginPath();
  ctx.arc(px, py, 8, 0, 2 * Math.PI);
  ctx.fillStyle = '#000';
  ctx.fill();
  ctx.lineWidth = 3;
  ctx.strokeStyle = '#fff';
  ctx.stroke();
  return label;
}
