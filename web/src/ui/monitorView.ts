// Monitor panel: live mission status per drone (done / current / pending items, behavior
// feedback, last error) and the event log (behaviors, STATUSTEXT, alerts, rejected commands).

import { itemRows, missionStateName } from '../lib/fleet';
import type { App } from './app';
import { byId, fmt, h, setOptions } from './dom';

const SHOWN_EVENTS = 300;

export class MonitorView {
  private status = h('div', { id: 'mission-status' });
  private filter = h('select', { id: 'log-filter', 'aria-label': 'event log filter' });
  private log = h('ol', { id: 'event-log', className: 'log', reversed: true });
  private shownEvents = -1;

  constructor(private readonly app: App) {
    this.filter.addEventListener('change', () => {
      this.shownEvents = -1;
      this.renderLog();
    });
    byId('panel-monitor').append(
      h('h2', {}, 'Mission status'),
      this.status,
      h('h2', {}, 'Event log ', this.filter),
      this.log,
    );
  }

  render(): void {
    this.status.replaceChildren(
      ...this.app.drones().map((ref) => {
        const v = this.app.view(ref);
        const ms = v.mission;
        const rows = itemRows(ms, this.app.planOf(ref));
        const feedback = Object.entries(ms?.feedback_current ?? {}).map(([k, val]) =>
          h('li', {}, `${k}: ${typeof val === 'number' ? fmt(val, 2) : JSON.stringify(val)}`),
        );
        return h(
          'section',
          { className: 'mstatus', 'data-drone': ref.name, 'data-state': missionStateName(ms) },
          h('h3', {}, `${ref.name} — ${missionStateName(ms)}${ms?.mission_id != null ? ` — mission #${ms.mission_id}` : ''}`),
          h(
            'ol',
            { className: 'mitems', start: 0 },
            rows.map((r) =>
              h('li', { className: `mitem ${r.state}`, 'data-index': r.index }, `${r.state === 'done' ? '✔' : r.state === 'current' ? '▶' : '·'} #${r.index} ${r.behavior}${r.result ? ` — ${r.result}` : ''}`),
            ),
          ),
          feedback.length ? h('ul', { className: 'feedback' }, feedback) : '',
          ms?.last_error ? h('p', { className: 'field-error' }, ms.last_error) : '',
        );
      }),
    );
    this.renderLog();
  }

  private renderLog(): void {
    const drones = [...new Set(this.app.events.map((e) => e.drone).filter((d): d is string => !!d))].sort();
    setOptions(this.filter, [{ value: '', label: 'all drones' }, ...drones.map((d) => ({ value: d, label: d }))]);
    if (this.shownEvents === this.app.events.length) return;
    this.shownEvents = this.app.events.length;
    const want = this.filter.value;
    const lines = this.app.events.filter((e) => !want || e.drone === want).slice(-SHOWN_EVENTS).reverse();
    this.log.replaceChildren(
      ...lines.map((e) =>
        h('li', { className: `ev ${e.level}`, 'data-kind': e.kind }, h('span', { className: 't' }, e.t === null ? '' : fmt(e.t, 1)), h('span', { className: 'who' }, e.drone ?? ''), h('span', { className: 'kind' }, e.kind), h('span', { className: 'text' }, e.text)),
      ),
    );
  }
}
