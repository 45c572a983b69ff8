// Map markers of remote drones (flown by other Kestrels of the fleet): a hollow grey outline
// pointing along the heading, labelled `drone_1 · node_1`, dimmed and labelled "silent N s" once
// its node is no longer heard. Not clickable: nothing is commanded from here.

import L from 'leaflet';
import { remoteLabel, type RemoteLink } from '../lib/remote';
import type { RemoteDrone } from '../lib/types';

export interface RemoteDraw {
  key: string;
  drone: RemoteDrone;
  link: RemoteLink;
}

export class RemoteLayer {
  private markers = new Map<string, L.Marker>();

  constructor(
    private readonly group: L.LayerGroup,
    private readonly ll: (x: number, y: number) => L.LatLng,
  ) {}

  render(drones: RemoteDraw[]): void {
    const seen = new Set<string>();
    for (const d of drones) {
      const r = d.drone;
      // Not drawn before its autopilot gives a position (its marker goes, if it had one).
      if (r.position_enu_m === null || r.yaw_rad === null) continue;
      seen.add(d.key);
      const [x, y, z] = r.position_enu_m;
      const yaw = r.yaw_rad;
      let m = this.markers.get(d.key);
      if (!m) {
        m = L.marker(this.ll(x, y), {
          interactive: false,
          keyboard: false,
          icon: L.divIcon({
            className: 'drone-icon',
            html: `<div class="drone-glyph remote"><svg viewBox="-12 -12 24 24" width="28" height="28"><path d="M11 0 L-8 -8 L-4 0 L-8 8 Z"/></svg><span class="drone-label"></span></div>`,
            iconSize: [28, 28],
            iconAnchor: [14, 14],
          }),
        }).addTo(this.group);
        this.markers.set(d.key, m);
      }
      m.setLatLng(this.ll(x, y));
      const el = m.getElement()?.querySelector<HTMLElement>('.drone-glyph');
      if (!el) continue;
      el.dataset.remoteDrone = r.id;
      el.dataset.node = r.node;
      el.dataset.x = x.toFixed(2);
      el.dataset.y = y.toFixed(2);
      el.classList.toggle('silent', d.link.state === 'silent');
      el.querySelector('svg')?.setAttribute('style', `transform: rotate(${(-yaw * 180) / Math.PI}deg)`);
      const label = el.querySelector('.drone-label');
      if (label) label.textContent = `${remoteLabel(r, d.link)} · ${z.toFixed(1)} m`;
    }
    for (const [key, m] of this.markers) {
      if (!seen.has(key)) {
        m.remove();
        this.markers.delete(key);
      }
    }
  }
}
