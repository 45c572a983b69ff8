// Fleet panel: one card per drone (link, armed, mode, flight, battery, position, behavior, mission
// progress, hold/land), the fleet bus and the drones other Kestrels fly (remoteCards.ts), and the
// list of Kestrel instances with a form to add one.

import { fleetPeerLost, hasPosition, missionProgress, missionStateName, motionBehavior, pilotTakeover } from '../lib/fleet';
import { behaviorColor } from '../lib/colors';
import type { App, DroneRef } from './app';
import { byId, fmt, h } from './dom';
import { act } from './feedback';
import { describeError } from './instance';
import { RemoteCards } from './remoteCards';

const INSTANCES_KEY = 'kestrel.instances';

function savedInstances(): { base: string; token: string }[] {
  try {
    const list = JSON.parse(sessionStorage.getItem(INSTANCES_KEY) ?? '[]') as unknown;
    return Array.isArray(list) ? list.filter((i) => typeof i?.base === 'string' && typeof i?.token === 'string') : [];
  } catch {
    return [];
  }
}

function saveInstance(base: string, token: string): void {
  const list = savedInstances().filter((i) => i.base !== base);
  sessionStorage.setItem(INSTANCES_KEY, JSON.stringify([...list, { base, token }]));
}

/** Reconnects the instances added earlier in this browser session (tokens kept per session only). */
export async function restoreInstances(app: App): Promise<void> {
  for (const { base, token } of savedInstances()) {
    try {
      await app.addInstance(new URL(base).host, base, token);
    } catch (e) {
      app.log({ t: null, drone: null, kind: 'instance', level: 'error', text: `${base}: ${describeError(e)}` });
    }
  }
}

interface Card {
  root: HTMLElement;
  fields: Record<string, HTMLElement>;
}

const FIELDS = ['armed', 'mode', 'flight', 'battery', 'position', 'behavior', 'mission'] as const;

export class FleetView {
  private cards = new Map<string, Card>();
  private list = h('div', { className: 'cards', id: 'fleet-cards' });
  private instances = h('ul', { className: 'instances', id: 'instances' });
  private remote: RemoteCards;

  constructor(private readonly app: App) {
    const panel = byId('panel-fleet');
    this.remote = new RemoteCards(app);
    byId('topbar').after(this.remote.banner);
    const addr = h('input', { id: 'inst-addr', placeholder: 'http://drone-2.local:8080', 'aria-label': 'instance address' });
    const token = h('input', { id: 'inst-token', type: 'password', placeholder: 'token', 'aria-label': 'instance token' });
    const answer = h('p', { className: 'answer', id: 'inst-answer' });
    const add = h('button', { id: 'inst-add' }, 'Add instance');
    add.addEventListener('click', () =>
      act(add, 'add instance', answer, async () => {
        const base = addr.value.trim().replace(/\/$/, '');
        if (!/^https?:\/\//.test(base)) return { ok: false, text: 'address as http://host:port' };
        try {
          const inst = await this.app.addInstance(new URL(base).host, base, token.value.trim());
          saveInstance(base, token.value.trim());
          return { ok: true, text: `${inst.label}: ${inst.state.drones.size} drone(s)` };
        } catch (e) {
          return { ok: false, text: describeError(e) };
        }
      }),
    );
    panel.append(
      h('h2', {}, 'Fleet'),
      this.remote.bus,
      this.list,
      this.remote.list,
      h('h3', {}, 'Kestrel instances'),
      this.instances,
      h('div', { className: 'row' }, addr, token, add),
      answer,
    );
  }

  private card(ref: DroneRef): Card {
    let c = this.cards.get(ref.key);
    if (c) return c;
    const fields: Record<string, HTMLElement> = {
      link: h('span', { 'data-field': 'link' }),
      takeover: h('p', { className: 'takeover', 'data-field': 'takeover', role: 'alert', hidden: true }),
    };
    const dl = h('dl', {});
    for (const f of FIELDS) {
      fields[f] = h('dd', { 'data-field': f });
      dl.append(h('dt', {}, f), fields[f]);
    }
    const hold = h('button', { className: 'hold' }, 'Hold');
    hold.addEventListener('click', () => act(hold, `hold ${ref.name}`, null, () => this.app.hold(ref)));
    const land = h('button', { className: 'land' }, 'Land');
    land.addEventListener('click', () => act(land, `land ${ref.name}`, null, () => this.app.land(ref)));
    const name = h('button', { className: 'name', title: 'select this drone' }, ref.name);
    name.addEventListener('click', () => this.app.select(ref.key));
    const root = h('article', { className: 'card drone', 'data-drone': ref.name }, h('div', { className: 'card-head' }, name, fields.link), fields.takeover, dl, h('div', { className: 'card-actions' }, hold, land));
    c = { root, fields };
    this.cards.set(ref.key, c);
    this.list.append(root);
    return c;
  }

  render(): void {
    const now = Date.now();
    const refs = this.app.drones();
    const selected = this.app.selected()?.key;
    for (const ref of refs) {
      const { root, fields } = this.card(ref);
      const v = this.app.view(ref);
      const link = this.app.link(ref, now);
      const s = v.status;
      root.dataset.link = link.state;
      root.classList.toggle('lost', link.state === 'lost');
      root.classList.toggle('selected', ref.key === selected);
      fields.link.className = `badge link ${link.state}`;
      fields.link.textContent = link.state === 'ok' ? 'LINK OK' : `${link.state.toUpperCase()}: ${link.reason}`;
      fields.armed.textContent = s ? (s.armed ? 'ARMED' : 'disarmed') : '—';
      fields.armed.className = s?.armed ? 'armed' : '';
      fields.mode.textContent = s ? `${s.mode}${s.offboard ? ' (offboard)' : ''}` : '—';
      // A stale status does not claim the drone is still flying: it was, when last heard.
      const flight = s && link.state === 'lost' ? `stale (last: ${s.flight}${s.age_s != null ? `, ${s.age_s.toFixed(0)} s ago` : ''})` : s?.flight;
      fields.flight.textContent = s ? `${flight}${s.last_error ? ` — ${s.last_error}` : ''}` : '—';
      const b = s?.battery;
      fields.battery.textContent = b ? `${Math.round(b.remaining_fraction * 100)} % (${fmt(b.voltage_v)} V)` : '—';
      fields.battery.className = b && b.remaining_fraction < 0.25 ? 'warn' : '';
      const p = hasPosition(s) ? s.position_enu_m : null;
      fields.position.textContent = p
        ? `${link.state === 'lost' ? 'stale, last known ' : ''}x ${fmt(p[0])} y ${fmt(p[1])} z ${fmt(p[2])} m`
        : 'no position';
      fields.position.dataset.position = p ? 'yes' : 'none';
      const behavior = motionBehavior(s);
      const others = (s?.active_behaviors ?? []).map((a) => a.behavior).filter((n) => n !== behavior);
      fields.behavior.replaceChildren(
        behavior ? h('span', { className: 'swatch', style: `background:${behaviorColor(behavior)}` }) : '',
        behavior ? [behavior, ...others].join(', ') : 'none',
      );
      const ms = v.mission;
      fields.mission.textContent = ms ? `${missionStateName(ms)} ${missionProgress(ms).label}${ms.mission_id != null ? ` (#${ms.mission_id})` : ''}` : 'no mission';
      const takeover = pilotTakeover(ms);
      const peerLost = fleetPeerLost(ms);
      fields.takeover.textContent = takeover ?? peerLost ?? '';
      fields.takeover.hidden = takeover === null && peerLost === null;
      root.classList.toggle('taken-over', takeover !== null);
      root.classList.toggle('peer-lost', peerLost !== null);
    }
    for (const [key, c] of this.cards) {
      if (!refs.some((r) => r.key === key)) {
        c.root.remove();
        this.cards.delete(key);
      }
    }
    this.remote.render();
    this.instances.replaceChildren(
      ...this.app.instances.map((i) =>
        h('li', {}, `${i.label} — ${i.client.base || 'this server'} — `, h('span', { className: i.socketOpen ? 'ok' : 'bad' }, i.socketOpen ? 'connected' : (i.problem ?? 'disconnected'))),
      ),
    );
  }
}
