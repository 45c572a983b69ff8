// Timeline panel: behavior activations per drone as SVG bars (like the thesis's figures 5.4 and
// 5.12: rows by drone and behavior, or by drone only with LOAD/START markers), live and for a
// past flight log fetched from kestrel or opened from a file.

import { behaviorColor } from '../lib/colors';
import { parseFlightLog, type ParsedLog } from '../lib/events';
import { buildTimeline, tickStep, type Timeline } from '../lib/timeline';
import type { App } from './app';
import { byId, h, setOptions } from './dom';
import { act } from './feedback';
import { describeError } from './instance';

const SVG = 'http://www.w3.org/2000/svg';

function s<K extends keyof SVGElementTagNameMap>(tag: K, attrs: Record<string, string | number>, text?: string): SVGElementTagNameMap[K] {
  const el = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, String(v));
  if (text !== undefined) el.textContent = text;
  return el;
}

export type Rows = 'behavior' | 'drone';

/** Draws a timeline: one row per (drone, behavior) or per drone; markers as X on drone rows. */
export function drawTimeline(tl: Timeline, rows: Rows, width: number): SVGSVGElement {
  const rowH = 22;
  const left = 150;
  const top = 8;
  const list = rows === 'behavior' ? tl.rows.map((r) => ({ ...r, label: `${r.drone} ${r.behavior}` })) : tl.drones.map((d) => ({ drone: d, behavior: null, label: d }));
  const pad = 8;
  const plotW = Math.max(100, width - left - 12 - pad);
  const height = top + Math.max(1, list.length) * rowH + 30;
  const x = (t: number) => left + pad + ((t - tl.t0) / (tl.t1 - tl.t0)) * plotW;
  const svg = s('svg', { width, height, viewBox: `0 0 ${width} ${height}`, class: 'timeline', role: 'img' });
  const step = tickStep(tl.t1 - tl.t0);
  for (let t = Math.ceil(tl.t0 / step) * step; t <= tl.t1; t += step) {
    svg.append(s('line', { x1: x(t), x2: x(t), y1: top, y2: height - 24, class: 'tick' }));
    svg.append(s('text', { x: x(t), y: height - 8, 'text-anchor': 'middle' }, `${+t.toFixed(1)} s`));
  }
  list.forEach((row, i) => {
    const y = top + i * rowH;
    svg.append(s('text', { x: left - 6, y: y + rowH * 0.7, 'text-anchor': 'end' }, row.label));
    svg.append(s('line', { x1: left, x2: left + pad + plotW, y1: y + rowH, y2: y + rowH, class: 'rowline' }));
    for (const seg of tl.segments) {
      if (seg.drone !== row.drone || (row.behavior && seg.behavior !== row.behavior)) continue;
      const x0 = x(seg.start);
      const x1 = x(seg.end ?? tl.t1);
      const rect = s('rect', { x: x0, y: y + 3, width: Math.max(2, x1 - x0), height: rowH - 6, fill: behaviorColor(seg.behavior), class: seg.end === null ? 'running' : '', 'data-behavior': seg.behavior });
      rect.append(s('title', {}, `${seg.drone} ${seg.behavior} ${seg.start.toFixed(1)}–${seg.end === null ? 'now' : seg.end.toFixed(1)} s${seg.result ? ` (${seg.result})` : ''}`));
      svg.append(rect);
    }
    if (rows === 'drone') {
      for (const m of tl.markers) {
        if (m.drone !== row.drone) continue;
        const mx = x(m.t);
        const cy = y + rowH / 2;
        const g = s('g', { class: 'marker' });
        g.append(s('path', { d: `M${mx - 5},${cy - 5} L${mx + 5},${cy + 5} M${mx - 5},${cy + 5} L${mx + 5},${cy - 5}` }), s('title', {}, `${m.label} at ${m.t.toFixed(1)} s`));
        svg.append(g);
      }
    }
  });
  return svg;
}

export class TimelineView {
  private rows: Rows = 'behavior';
  private live = h('div', { id: 'timeline-live', className: 'tl' });
  private past = h('div', { id: 'timeline-past', className: 'tl' });
  private pastLog: ParsedLog | null = null;
  private logDrone = h('select', { id: 'log-drone', 'aria-label': 'flight log of' });
  private answer = h('p', { id: 'log-answer', className: 'answer' });
  onPast: (log: ParsedLog | null) => void = () => {};

  constructor(private readonly app: App) {
    const mode = h('select', { id: 'tl-rows', 'aria-label': 'timeline rows' });
    setOptions(mode, [
      { value: 'behavior', label: 'rows: drone × behavior' },
      { value: 'drone', label: 'rows: drone, with LOAD/START markers' },
    ]);
    mode.addEventListener('change', () => {
      this.rows = mode.value as Rows;
      this.render();
      this.renderPast();
    });
    const fetchBtn = h('button', { id: 'btn-fetch-log' }, 'Load flight log from kestrel');
    fetchBtn.addEventListener('click', () =>
      act(fetchBtn, 'flight log', this.answer, async () => {
        const ref = this.app.ref(this.logDrone.value);
        const inst = ref?.inst ?? this.app.instances[0];
        if (!inst) return { ok: false, text: 'not connected' };
        try {
          const text = await inst.client.log(ref?.drone);
          return this.setPast(text, `kestrel log${ref ? ` of ${ref.name}` : ''}`);
        } catch (e) {
          return { ok: false, text: describeError(e) };
        }
      }),
    );
    const file = h('input', { id: 'log-file', type: 'file', accept: '.jsonl,.ndjson,.json,.log' });
    file.addEventListener('change', async () => {
      const f = file.files?.[0];
      if (f) this.setPast(await f.text(), f.name);
      file.value = '';
    });
    const clear = h('button', {}, 'Clear past flight');
    clear.addEventListener('click', () => {
      this.pastLog = null;
      this.renderPast();
      this.onPast(null);
    });
    byId('panel-timeline').append(
      h('h2', {}, 'Behavior activations'),
      h('div', { className: 'row' }, mode),
      h('h3', {}, 'Live'),
      this.live,
      h('h3', {}, 'Past flight'),
      h('div', { className: 'row' }, this.logDrone, fetchBtn, h('label', { className: 'file' }, 'or open a log file ', file), clear),
      this.answer,
      this.past,
    );
  }

  private setPast(text: string, source: string): { ok: boolean; text: string } {
    const log = parseFlightLog(text);
    this.pastLog = log;
    this.renderPast();
    this.onPast(log);
    const bad = log.badLines ? `, ${log.badLines} unreadable line(s)` : '';
    return { ok: true, text: `${source}: ${log.behaviors.length} behavior events, ${[...log.poses.values()].reduce((n, p) => n + p.length, 0)} poses${bad}` };
  }

  private width(el: HTMLElement): number {
    return Math.max(320, el.clientWidth || byId('side').clientWidth - 24);
  }

  refreshChoices(): void {
    setOptions(this.logDrone, [{ value: '', label: 'all drones' }, ...this.app.drones().map((d) => ({ value: d.key, label: d.name }))]);
  }

  render(): void {
    const now = Math.max(0, ...this.app.instances.map((i) => i.state.serverT ?? 0));
    const tl = buildTimeline(this.app.records, this.app.markers, now);
    this.live.replaceChildren(tl.segments.length || tl.markers.length ? drawTimeline(tl, this.rows, this.width(this.live)) : h('p', { className: 'hint' }, 'No behavior has run since the page opened.'));
  }

  private renderPast(): void {
    const log = this.pastLog;
    if (!log) {
      this.past.replaceChildren();
      return;
    }
    const tl = buildTimeline(log.behaviors, log.markers);
    this.past.replaceChildren(tl.segments.length ? drawTimeline(tl, this.rows, this.width(this.past)) : h('p', { className: 'hint' }, 'The log has no behavior events.'));
  }
}
