/**
 * A lens profile drawn over a frame of its camera (SVG in the frame's own pixels), and its values
 * as table rows: the ring's two circles and the forward direction of a donut lens, or the forward
 * column and the horizon of a 360 camera's frame, so that a wrong profile shows at a glance.
 */
import type { CatadioptricLens, Lens } from '../shared/lens';
import { donutPixel, polyval } from '../shared/lens';

const SVG = 'http://www.w3.org/2000/svg';

function svgEl(tag: string, attrs: Record<string, string | number>): SVGElement {
  const e = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, String(v));
  return e;
}

/** The end of the forward arrow of a donut lens: from the centre at image angle forward_deg. */
export function forwardPoint(center: readonly [number, number], forwardDeg: number, r: number): [number, number] {
  const a = (forwardDeg * Math.PI) / 180;
  return [center[0] + r * Math.cos(a), center[1] + r * Math.sin(a)];
}

/**
 * Where a donut profile with a `sensor` (a real mirror's stretch and decentring) sees the circle
 * of radius r and its forward point: the circle's `n` points and the forward one, through the
 * sensor (lens.ts donutPixel), as the unwarp reads them. Without a sensor: null (a circle).
 */
export function sensorOutline(
  lens: CatadioptricLens,
  r: number,
  n = 120,
): { points: [number, number][]; forward: [number, number] } | null {
  if (!lens.sensor) return null;
  const points: [number, number][] = [];
  for (let k = 0; k < n; k++) {
    const t = (2 * Math.PI * k) / n;
    points.push(donutPixel(lens, r * Math.cos(t), r * Math.sin(t)));
  }
  const a = ((lens.forward_deg ?? 0) * Math.PI) / 180;
  return { points, forward: donutPixel(lens, r * Math.cos(a), r * Math.sin(a)) };
}

/**
 * The overlay for `lens` on a frame of `size` ([w, h] pixels, the video's; the lens's image_size
 * when unknown). Drawn in the frame's pixels (viewBox), so it scales with the image.
 */
export function lensOverlay(lens: Lens, size: readonly [number, number]): SVGSVGElement {
  const [w, h] = size;
  const svg = svgEl('svg', {
    viewBox: `0 0 ${w} ${h}`,
    preserveAspectRatio: 'none',
    'aria-hidden': 'true',
  }) as SVGSVGElement;
  svg.classList.add('lens-overlay');
  const stroke = Math.max(2, Math.round(w / 240));
  const shape = (attrs: Record<string, string | number>) =>
    attrs.r !== undefined ? 'circle' : attrs.points !== undefined ? 'polygon' : 'line';
  const line = (attrs: Record<string, string | number>, colour: string, dash = '') => {
    // a dark halo under each line keeps it visible on light and dark frames
    svg.append(
      svgEl(shape(attrs), {
        ...attrs,
        class: 'halo',
        fill: 'none',
        stroke: '#000',
        'stroke-width': stroke + 3,
      }),
    );
    svg.append(
      svgEl(shape(attrs), {
        ...attrs,
        fill: 'none',
        stroke: colour,
        'stroke-width': stroke,
        ...(dash ? { 'stroke-dasharray': dash } : {}),
      }),
    );
  };
  if (lens.model === 'catadioptric') {
    const [cx, cy] = lens.center;
    // a real mirror's profile (a sensor): its ring as the unwarp reads it, not a circle
    const inner = sensorOutline(lens, lens.r_inner);
    const outer = sensorOutline(lens, lens.r_outer);
    const ring = (o: ReturnType<typeof sensorOutline>, r: number, cls: string): Record<string, string | number> =>
      o ? { points: o.points.map((p) => p.join(',')).join(' '), class: cls } : { cx, cy, r, class: cls };
    line(ring(inner, lens.r_inner, 'ring-inner'), '#00e5ff', `${stroke * 3} ${stroke * 2}`);
    line(ring(outer, lens.r_outer, 'ring-outer'), '#ffd400');
    const [fx, fy] = outer ? outer.forward : forwardPoint(lens.center, lens.forward_deg ?? 0, lens.r_outer);
    line({ x1: cx, y1: cy, x2: fx, y2: fy, class: 'forward' }, '#ff3030');
    // the arrowhead at the ring
    const a = ((lens.forward_deg ?? 0) * Math.PI) / 180;
    const s = stroke * 6;
    const head = [
      [fx, fy],
      [fx - s * Math.cos(a - 0.45), fy - s * Math.sin(a - 0.45)],
      [fx - s * Math.cos(a + 0.45), fy - s * Math.sin(a + 0.45)],
    ];
    svg.append(
      svgEl('polygon', {
        points: head.map((p) => p.join(',')).join(' '),
        fill: '#ff3030',
        stroke: '#000',
        'stroke-width': 1,
        class: 'forward-head',
      }),
    );
    svg.append(svgEl('circle', { cx, cy, r: stroke * 2, fill: '#ff3030', stroke: '#000', class: 'centre' }));
  } else {
    line({ x1: lens.forward_x, y1: 0, x2: lens.forward_x, y2: h, class: 'forward' }, '#ff3030');
    line({ x1: 0, y1: h / 2, x2: w, y2: h / 2, class: 'horizon' }, '#ffd400', `${stroke * 3} ${stroke * 2}`);
  }
  return svg;
}

/** [field, value] rows of a profile's values, with what the ring sees (elevations at its edges). */
export function lensRows(lens: Lens): [string, string][] {
  const rows: [string, string][] = [
    ['Model', lens.model === 'catadioptric' ? 'catadioptric (donut lens)' : 'equirectangular (360 camera)'],
    ['Frame size', `${lens.image_size[0]} × ${lens.image_size[1]} pixels`],
  ];
  if (lens.model === 'catadioptric') {
    const e0 = polyval(lens.r_inner, lens.elevation_poly);
    const e1 = polyval(lens.r_outer, lens.elevation_poly);
    rows.push(
      ['Centre', `${lens.center[0]}, ${lens.center[1]} pixels`],
      ['Inner radius', `${lens.r_inner} pixels (sees ${e0.toFixed(1)}° elevation)`],
      ['Outer radius', `${lens.r_outer} pixels (sees ${e1.toFixed(1)}° elevation)`],
      ['Elevation polynomial', lens.elevation_poly.join(', ')],
      ['Forward', `${lens.forward_deg ?? 0}° image angle`],
      ['Azimuth turns', (lens.ccw ?? true) ? 'counter-clockwise (ccw: true)' : 'clockwise (ccw: false)'],
    );
    if (lens.sensor) {
      const [[a, b], [c, d]] = lens.sensor.matrix;
      const [p1, p2] = lens.sensor.tangential;
      const f = (v: number) => v.toFixed(5);
      rows.push([
        'Sensor',
        `matrix ${f(a)}, ${f(b)}; ${f(c)}, ${f(d)}; decentring ${f(p1)}, ${f(p2)} (unit ${lens.sensor.scale} pixels)`,
      ]);
    }
  } else {
    rows.push(
      ['Forward column', `${lens.forward_x}`],
      ['Azimuth turns', lens.ccw ? 'counter-clockwise (ccw: true)' : 'clockwise (ccw: false)'],
    );
  }
  return rows;
}
