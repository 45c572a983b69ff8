// Fleet panel, fleet-bus part: the bus line (fleet, node, peers heard, latency, refused) of each
// instance on a bus, and one card per drone another Kestrel flies — marked "remote (node)", live
// or "silent N s", with no command button: the operator is sent to that Kestrel's ground station.

import { busSummary, joinBanner, remoteCommandNote } from '../lib/remote';
import type { App } from './app';
import { fmt, h } from './dom';

interface Card {
  root: HTMLElement;
  fields: Record<string, HTMLElement>;
}

const FIELDS = ['flight', 'battery', 'position', 'behavior', 'mission', 'commands'] as const;

export class RemoteCards {
  /** The bus line(s), hidden when no instance is on a bus. */
  readonly bus = h('div', { id: 'fleet-bus', className: 'bus-line', hidden: true });
  /** Under the top bar while an instance has not joined its fleet. */
  readonly banner = h('div', { id: 'fleet-join-banner', className: 'join-banner', role: 'alert', hidden: true });
  readonly list = h('div', { className: 'cards', id: 'remote-cards' });
  private cards = new Map<string, Card>();

  constructor(private readonly app: App) {}

  private card(key: string): Card {
    let c = this.cards.get(key);
    if (c) return c;
    const fields: Record<string, HTMLElement> = {
      name: h('strong', { className: 'name' }),
      node: h('span', { className: 'badge remote', 'data-field': 'node' }),
      link: h('span', { 'data-field': 'link' }),
    };
    const dl = h('dl', {});
    for (const f of FIELDS) {
      fields[f] = h('dd', { 'data-field': f });
      dl.append(h('dt', {}, f), fields[f]);
    }
    const root = h('article', { className: 'card drone remote' }, h('div', { className: 'card-head' }, fields.name, fields.node, fields.link), dl);
    c = { root, fields };
    this.cards.set(key, c);
    this.list.append(root);
    return c;
  }

  render(): void {
    const lines = this.app.instances.flatMap((i) => {
      const text = busSummary(i.remote);
      return text ? [h('div', {}, `Fleet bus${this.app.instances.length > 1 ? ` (${i.label})` : ''}: ${text}`)] : [];
    });
    this.bus.hidden = lines.length === 0;
    const banners = this.app.instances.flatMap((i) => {
      const text = joinBanner(i.remote);
      return text ? [`${this.app.instances.length > 1 ? `${i.label}: ` : ''}${text}`] : [];
    });
    this.banner.hidden = banners.length === 0;
    const bannerText = banners.join('\n');
    if (this.banner.textContent !== bannerText) this.banner.textContent = bannerText;
    if (this.bus.textContent !== lines.map((l) => l.textContent).join('')) this.bus.replaceChildren(...lines);

    const now = Date.now();
    const refs = this.app.remoteDrones();
    for (const ref of refs) {
      const { root, fields } = this.card(ref.key);
      const r = ref.drone;
      const link = this.app.remoteLink(ref, now);
      const silent = link.state === 'silent';
      root.dataset.remoteDrone = r.id;
      root.dataset.node = r.node;
      root.dataset.link = link.state;
      root.classList.toggle('silent', silent);
      fields.name.textContent = ref.name;
      fields.node.textContent = `remote (${r.node})`;
      fields.link.className = `badge link ${silent ? 'lost' : r.link === 'ok' ? 'ok' : 'connecting'}`;
      fields.link.textContent = silent ? link.reason.toUpperCase() : r.link === 'ok' ? 'LIVE' : `LIVE, autopilot ${r.link}`;
      const last = silent ? 'last heard: ' : '';
      fields.flight.textContent = `${last}${r.flying ? 'flying' : 'on the ground'}`;
      fields.battery.textContent = r.battery_pct === null ? '—' : `${Math.round(r.battery_pct)} %`;
      if (r.position_enu_m === null) {
        fields.position.textContent = 'no position yet';
      } else {
        const [x, y, z] = r.position_enu_m;
        fields.position.textContent = `${silent ? 'last known ' : ''}x ${fmt(x)} y ${fmt(y)} z ${fmt(z)} m`;
      }
      fields.behavior.textContent = r.behavior ?? 'none';
      fields.mission.textContent = r.mission ?? 'no mission';
      fields.commands.textContent = `none here: ${remoteCommandNote(r)}`;
      fields.commands.title = remoteCommandNote(r);
    }
    for (const [key, c] of this.cards) {
      if (!refs.some((r) => r.key === key)) {
        c.root.remove();
        this.cards.delete(key);
      }
    }
  }
}
