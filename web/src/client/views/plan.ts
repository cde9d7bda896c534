/**
 * The floor plan as a view: the plan image with a pose drawn on it (position dot, heading arrow,
 * accuracy circle and the nearest place), and its text alternative. The same facts are in the text
 * answer and the canvas's label: nothing is only on the map, and nothing is told by colour alone
 * (shapes and outlines differ too). It knows nothing of the phone's session, so that any page that
 * shows a plan (the app, the admin pages) draws it the same way.
 */

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
  accuracy_m: number | null;
  area: string | null;
  nearest: { name: string; distance_m: number } | null;
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

  /** Draw the floor (a blank sheet when it has no plan) with the pose, if any; resolves with the label. */
  async show(floor: PlanFloor | undefined, places: readonly PlanPlace[], pose: PlanPose | null): Promise<string> {
    const mine = ++this.drawn;
    const img = floor?.plan_url ? await loadImage(floor.plan_url).catch(() => null) : null;
    if (mine !== this.drawn) return '';
    const label = draw(this.canvas, img, floor, places, pose);
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
  return `Floor plan of ${fname}: you are ${where}${acc}, heading ${Math.round(a.heading_deg)} degrees on the plan${near}.`;
}

/** Paint the sheet and the pose; returns the label ('' where the canvas cannot draw). */
function draw(
  canvas: HTMLCanvasElement,
  img: HTMLImageElement | null,
  floor: PlanFloor | undefined,
  places: readonly PlanPlace[],
  a: PlanPose | null,
): string {
  const ctx = canvas.getContext('2d');
  if (!ctx) return '';
  const scale = floor?.px_per_m ?? 20;
  canvas.width = img?.naturalWidth ?? Math.max(600, Math.ceil(((a?.x ?? 10) + 10) * scale));
  canvas.height = img?.naturalHeight ?? Math.max(300, Math.ceil(((a?.y ?? 10) + 10) * scale));
  ctx.fillStyle = '#ffffff';
  ctx.fillRect(0, 0, canvas.width, canvas.height);
  if (img) ctx.drawImage(img, 0, 0);
  const label = planLabel(floor?.name, a);
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
