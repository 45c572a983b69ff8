// Altitude (side) view beside the top-down map: every drone and its trail seen from the south
// (east across, up the side), so a vertical inspection (a wind-turbine climb) is visible.

import { hasPosition } from '../lib/fleet';
import type { DroneDraw } from './mapView';
import { sideExtent, sidePixel } from '../lib/sideView';

const NS = 'http://www.w3.org/2000/svg';
const MARGIN = 26;

function svg<K extends keyof SVGElementTagNameMap>(tag: K, attrs: Record<string, string | number>, text?: string): SVGElementTagNameMap[K] {
  const el = document.createElementNS(NS, tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, String(v));
  if (text !== undefined) el.textContent = text;
  return el;
}

export class AltitudeView {
  private readonly root: SVGSVGElement;

  constructor(private readonly el: HTMLElement) {
    this.root = svg('svg', { id: 'alt-svg', role: 'img', 'aria-label': 'altitude view: east across, up the side' });
    el.append(this.root);
  }

  render(drones: DroneDraw[]): void {
    const width = this.el.clientWidth || 300;
    const height = this.el.clientHeight || 200;
    this.root.setAttribute('viewBox', `0 0 ${width} ${height}`);
    const placed = drones.flatMap((d) => {
      const s = d.view.status;
      return hasPosition(s) ? [{ d, p: s.position_enu_m }] : [];
    });
    const points = placed.flatMap(({ d, p }) => [...d.view.trail.map((t) => ({ x: t.x, z: t.z })), { x: p[0], z: p[2] }]);
    const e = sideExtent(points);
    const at = (x: number, z: number) => sidePixel(e, width, height, MARGIN, x, z);
    const children: SVGElement[] = [];
    const [gx0, gy] = at(e.xMin, 0);
    const [gx1] = at(e.xMax, 0);
    children.push(svg('line', { x1: gx0, y1: gy, x2: gx1, y2: gy, class: 'alt-ground' }));
    for (const z of niceTicks(e.zMin, e.zMax)) {
      const [, y] = at(e.xMin, z);
      children.push(svg('line', { x1: MARGIN, y1: y, x2: width - MARGIN, y2: y, class: 'alt-tick' }), svg('text', { x: 2, y: y + 4, class: 'alt-label' }, `${z}`));
    }
    children.push(svg('text', { x: width - MARGIN, y: height - 6, class: 'alt-label', 'text-anchor': 'end' }, `east ${e.xMin.toFixed(0)}…${e.xMax.toFixed(0)} m`));
    children.push(svg('text', { x: 2, y: 12, class: 'alt-label' }, 'up m'));
    for (const { d, p } of placed) {
      if (d.view.trail.length > 1) {
        const pts = d.view.trail.map((p) => at(p.x, p.z).map((v) => v.toFixed(1)).join(',')).join(' ');
        children.push(svg('polyline', { points: pts, class: 'alt-trail', stroke: d.color }));
      }
      const [x, y] = at(p[0], p[2]);
      const stale = d.link.state !== 'ok';
      children.push(
        svg('circle', { cx: x, cy: y, r: 6, fill: stale ? '#888' : d.color, class: `alt-drone${stale ? ' stale' : ''}`, 'data-drone': d.name, 'data-z': p[2].toFixed(2) }),
        svg('text', { x: x + 8, y: y - 6, class: 'alt-label' }, `${d.name} ${p[2].toFixed(1)} m${stale ? ' (stale)' : ''}`),
      );
    }
    this.root.replaceChildren(...children);
  }
}

/** About five round altitude ticks (m) between `lo` and `hi`. */
function niceTicks(lo: number, hi: number): number[] {
  const raw = (hi - lo) / 5;
  const step = [1, 2, 5, 10, 20, 50, 100, 200, 500].find((s) => s >= raw) ?? 1000;
  const out: number[] = [];
  for (let z = Math.ceil(lo / step) * step; z <= hi; z += step) out.push(z);
  return out;
}
