// Exploration panel: the drones to explore with (ticked: the selected drone, never silently all),
// start and stop (several drones: asked first), the drones exploring and a stop of the whole run
// (both from the server's state, so right after a page reload), the live progress (known area,
// elapsed, estimated time left, each drone's phase and goal) and the report download. It polls
// GET /api/exploration and hands each view to the map overlay (frontiers, goals).

import { defaultChoice, exploringDrones, progressText, runningText, stopNeedsConfirm } from '../lib/exploration';
import type { ExplorationView as View } from '../lib/types';
import type { App, DroneRef } from './app';
import { byId, fmt, h } from './dom';
import { act, type Outcome } from './feedback';
import type { Instance } from './instance';
import { describeError } from './instance';

/** Poll period: fast while a run goes on or the panel is open, slow otherwise. */
const FAST_MS = 1000;
const SLOW_MS = 5000;

export class ExplorationPanel {
  /** The last view of each instance (by instance id). */
  readonly views = new Map<number, View>();
  onView: () => void = () => {};
  private chosen: Set<string> | null = null;
  /** Whether the operator ticked or unticked a drone here (then the header selection only adds). */
  private edited = false;
  private readonly checks = h('div', { id: 'exp-drones', className: 'row', role: 'group', 'aria-label': 'drones to explore with' });
  private readonly height = h('input', { id: 'exp-height', type: 'number', step: '0.1', placeholder: '1.0', 'aria-label': 'exploration height (m)' });
  private readonly speed = h('input', { id: 'exp-speed', type: 'number', step: '0.05', placeholder: '0.75', 'aria-label': 'exploration speed (m/s)' });
  private readonly answer = h('p', { id: 'exp-answer', className: 'answer' });
  private readonly running = h('p', { id: 'exp-running', className: 'exp-running' }, runningText([]));
  private readonly stopAll = h('button', { id: 'btn-exp-stop-all', className: 'hold', disabled: true }, 'Stop the whole run');
  private readonly known = h('strong', { id: 'exp-known' }, '—');
  private readonly elapsed = h('span', { id: 'exp-elapsed' }, '—');
  private readonly remaining = h('span', { id: 'exp-remaining' }, '—');
  private readonly state = h('span', { id: 'exp-state' }, '');
  private readonly frontiers = h('span', { id: 'exp-frontiers' }, '—');
  private readonly table = h('tbody', { id: 'exp-table' });
  private lastPoll = 0;

  constructor(private readonly app: App) {
    const start = h('button', { id: 'btn-exp-start', className: 'primary' }, 'Start exploring');
    const stop = h('button', { id: 'btn-exp-stop', className: 'hold' }, 'Stop');
    const report = h('button', { id: 'btn-exp-report' }, 'Download report');
    start.addEventListener('click', () => act(start, 'start exploration', this.answer, () => this.start()));
    stop.addEventListener('click', () => act(stop, 'stop exploration', this.answer, () => this.stop()));
    this.stopAll.addEventListener('click', () => act(this.stopAll, 'stop the whole exploration', this.answer, () => this.stopRun()));
    report.addEventListener('click', () => act(report, 'exploration report', this.answer, () => this.download()));
    byId('panel-explore').append(
      h('h2', {}, 'Exploration'),
      h('p', { className: 'hint' }, 'The ticked drones explore the unknown area together (the explore behavior, one mission each): they take off, fly to frontiers, and land when none is left. Stop holds them where they are.'),
      this.running,
      this.checks,
      h('div', { className: 'row' }, h('label', {}, 'Height m ', this.height), h('label', {}, 'Speed m/s ', this.speed)),
      h('div', { className: 'buttons' }, start, stop, this.stopAll, report),
      this.answer,
      h('h3', {}, 'Progress'),
      h(
        'dl',
        { className: 'exp-progress' },
        h('dt', {}, 'Known area'), h('dd', {}, this.known, ' %'),
        h('dt', {}, 'Elapsed'), h('dd', {}, this.elapsed),
        h('dt', {}, 'Remaining (est.)'), h('dd', { title: 'unknown share over the area rate of the last 30 s: an upper bound, obstacles hide part of the map' }, this.remaining),
        h('dt', {}, 'Frontiers'), h('dd', {}, this.frontiers),
        h('dt', {}, 'State'), h('dd', {}, this.state),
      ),
      h('table', { className: 'exp-drones' }, h('thead', {}, h('tr', {}, h('th', {}, 'Drone'), h('th', {}, 'Phase'), h('th', {}, 'Goal (x, y) m'), h('th', {}, 'Path m'))), this.table),
    );
  }

  /** Rebuilds the checkboxes when the drones change, keeping what the operator ticked. */
  refreshChoices(): void {
    const refs = this.app.drones();
    if (this.chosen === null && refs.length) this.chosen = defaultChoice(this.app.selected()?.key ?? null, refs.map((r) => r.key));
    const keys = refs.map((r) => r.key).join(',');
    if (this.checks.dataset.keys === keys) return;
    this.checks.dataset.keys = keys;
    this.checks.replaceChildren(
      ...refs.map((r) => {
        const box = h('input', { type: 'checkbox', value: r.key, 'data-drone': r.drone, 'aria-label': `explore with ${r.name}` });
        box.checked = this.chosen?.has(r.key) ?? false;
        box.addEventListener('change', () => {
          this.edited = true;
          this.chosen ??= new Set();
          if (box.checked) this.chosen.add(r.key);
          else this.chosen.delete(r.key);
        });
        return h('label', { className: 'exp-drone' }, box, ` ${r.name}`);
      }),
    );
  }

  /** The operator picked another drone in the header: until ticks were edited here, the ticks
   *  follow the selection (that drone only); after, that one is ticked too. */
  selectDrone(key: string): void {
    if (this.chosen === null) return;
    if (!this.edited) this.chosen.clear();
    this.chosen.add(key);
    for (const box of this.checks.querySelectorAll<HTMLInputElement>('input[type=checkbox]')) {
      box.checked = this.chosen.has(box.value);
    }
  }

  private picked(): DroneRef[] {
    return this.app.drones().filter((r) => this.chosen?.has(r.key));
  }

  /** The picked drones, one group per instance. */
  private byInstance(refs: DroneRef[]): Map<Instance, DroneRef[]> {
    const out = new Map<Instance, DroneRef[]>();
    for (const r of refs) out.set(r.inst, [...(out.get(r.inst) ?? []), r]);
    return out;
  }

  private args(): Record<string, unknown> {
    const args: Record<string, unknown> = {};
    if (this.height.value.trim() !== '') args.height = Number(this.height.value);
    if (this.speed.value.trim() !== '') args.speed = Number(this.speed.value);
    return args;
  }

  /** Whether the last view shows this drone exploring. */
  private exploring(ref: DroneRef): boolean {
    return exploringDrones(this.views.get(ref.inst.id)?.progress ?? null).includes(ref.drone);
  }

  /** Starts the ticked drones that are not exploring yet (they join a run going on). */
  private async start(): Promise<Outcome> {
    const picked = this.picked();
    if (picked.length === 0) return { ok: false, text: 'tick the drones to explore with' };
    const refs = picked.filter((r) => !this.exploring(r));
    if (refs.length === 0) return { ok: false, text: 'the ticked drones are exploring already' };
    const texts: string[] = [];
    for (const [inst, group] of this.byInstance(refs)) {
      try {
        const r = await inst.client.startExploration(group.map((g) => g.drone), this.args());
        texts.push(r.drones.map((d) => `${this.app.nameOf(inst, d.drone)} mission #${d.mission_id}`).join(', '));
      } catch (e) {
        return { ok: false, text: describeError(e) };
      }
    }
    await this.poll(true);
    return { ok: true, text: `exploring: ${texts.join(', ')}` };
  }

  /** Stops the ticked drones that are exploring; several at once only once confirmed. */
  private async stop(): Promise<Outcome> {
    const refs = this.picked().filter((r) => this.exploring(r));
    if (refs.length === 0) return { ok: false, text: 'none of the ticked drones is exploring' };
    const names = refs.map((r) => r.name);
    if (stopNeedsConfirm(names) && !window.confirm(`Stop exploring with ${names.join(', ')}? They hold where they are.`)) {
      return { ok: false, text: 'not stopped (cancelled)' };
    }
    for (const [inst, group] of this.byInstance(refs)) {
      try {
        await inst.client.stopExploration(group.map((g) => g.drone));
      } catch (e) {
        return { ok: false, text: describeError(e) };
      }
    }
    await this.poll(true);
    return { ok: true, text: `stopped: ${names.join(', ')}` };
  }

  /** The drones exploring by the last views, whichever are ticked: this page's own drones only
   *  (another Kestrel's drones are stopped from there). */
  private runDrones(): DroneRef[] {
    return this.app.drones().filter((r) => this.exploring(r));
  }

  /** Stops every drone of the run, as the server has it now (asked first when several). */
  private async stopRun(): Promise<Outcome> {
    await this.poll(true);
    const refs = this.runDrones();
    if (refs.length === 0) return { ok: false, text: 'no drone is exploring' };
    const names = refs.map((r) => r.name);
    if (stopNeedsConfirm(names) && !window.confirm(`Stop the whole exploration: ${names.join(', ')}? They hold where they are.`)) {
      return { ok: false, text: 'not stopped (cancelled)' };
    }
    for (const [inst, group] of this.byInstance(refs)) {
      try {
        await inst.client.stopExploration(group.map((g) => g.drone));
      } catch (e) {
        return { ok: false, text: describeError(e) };
      }
    }
    await this.poll(true);
    return { ok: true, text: `stopped: ${names.join(', ')}` };
  }

  private async download(): Promise<Outcome> {
    const inst = this.picked()[0]?.inst ?? this.app.instances[0];
    if (!inst) return { ok: false, text: 'not connected' };
    try {
      const { filename, text } = await inst.client.explorationReport();
      const url = URL.createObjectURL(new Blob([text], { type: 'application/json' }));
      const a = h('a', { href: url, download: filename });
      document.body.append(a);
      a.click();
      a.remove();
      setTimeout(() => URL.revokeObjectURL(url), 10_000);
      return { ok: true, text: filename };
    } catch (e) {
      return { ok: false, text: describeError(e) };
    }
  }

  /** Fetches every instance's view when due (`force`: now). */
  async poll(force = false): Promise<void> {
    const active = [...this.views.values()].some((v) => v.progress && !v.progress.finished);
    const open = byId('panel-explore').classList.contains('active');
    const now = Date.now();
    if (!force && now - this.lastPoll < (active || open ? FAST_MS : SLOW_MS)) return;
    this.lastPoll = now;
    await Promise.all(
      this.app.instances.map(async (inst) => {
        try {
          this.views.set(inst.id, await inst.client.exploration());
        } catch {
          // No exploration service (mapping off) or unreachable: keep the last view.
        }
      }),
    );
    this.render();
    this.onView();
  }

  render(): void {
    const inst = this.picked()[0]?.inst ?? this.app.instances[0];
    const v = inst ? this.views.get(inst.id) : undefined;
    const p = v?.progress ?? null;
    const t = progressText(p);
    this.known.textContent = fmt(v?.known_pct, 2);
    this.known.dataset.pct = String(v?.known_pct ?? '');
    this.elapsed.textContent = t.elapsed;
    this.elapsed.dataset.s = String(p?.elapsed_s ?? '');
    this.remaining.textContent = t.remaining;
    this.state.textContent = t.state;
    this.frontiers.textContent = v ? String(v.frontiers.length) : '—';
    const exploring = new Set(exploringDrones(p));
    const run = this.runDrones().map((r) => r.name);
    this.running.textContent = runningText(run);
    this.running.dataset.drones = run.join(',');
    this.stopAll.disabled = run.length === 0;
    this.stopAll.textContent = run.length > 1 ? `Stop the whole run (${run.length})` : 'Stop the whole run';
    this.table.replaceChildren(
      ...(p?.drones ?? []).map((d) =>
        h(
          'tr',
          { 'data-drone': d.drone, 'data-phase': d.phase, className: exploring.has(d.drone) ? 'exploring' : '' },
          h('td', {}, inst ? this.app.nameOf(inst, d.drone) : d.drone),
          h('td', {}, d.phase),
          h('td', { className: 'goal' }, d.goal_enu_m ? `${fmt(d.goal_enu_m[0])}, ${fmt(d.goal_enu_m[1])}` : '—'),
          h('td', {}, fmt(d.path_m)),
        ),
      ),
    );
  }
}
