// Control panel: MissionUpdate buttons for the page's selected drone (or, chosen explicitly, all
// drones: STOP and RESET then ask first), with the executor's answer, and the on-demand task
// (inspect a registered frame now) sent to the drone the operator picks.

import { CONTROL_ACTIONS, inspectMission } from '../lib/missionUpdate';
import type { ActionName } from '../lib/types';
import type { App, DroneRef } from './app';
import { byId, h, setOptions } from './dom';
import { act, type Outcome } from './feedback';
import { describeError } from './instance';
import type { PlanView } from './planView';

const ALL = '*';
/** Fleet-wide actions that end or discard what every drone is doing: asked before sending. */
const CONFIRM_FLEET: ActionName[] = ['STOP', 'RESET'];

export class ControlView {
  private drone = h('select', { id: 'ctl-drone', 'aria-label': 'drone to command' });
  private missionId = h('input', { id: 'ctl-mission-id', type: 'number', placeholder: 'current', 'aria-label': 'mission id' });
  private itemId = h('input', { id: 'ctl-item', type: 'number', min: '0', placeholder: 'index', 'aria-label': 'item index' });
  private answer = h('p', { id: 'ctl-answer', className: 'answer' });
  private odFrame = h('select', { id: 'od-frame', 'aria-label': 'frame to inspect' });
  private odDrone = h('select', { id: 'od-drone', 'aria-label': 'drone for the task' });
  private odAnswer = h('p', { id: 'od-answer', className: 'answer' });

  constructor(
    private readonly app: App,
    private readonly plan: PlanView,
  ) {
    this.drone.addEventListener('change', () => {
      if (this.drone.value !== ALL) this.app.select(this.drone.value);
    });
    const buttons = CONTROL_ACTIONS.map((a) => {
      const b = h('button', { 'data-action': a, className: a === 'START' ? 'primary' : a === 'PAUSE' ? 'hold' : '' }, a.replace('_', ' '));
      b.addEventListener('click', () => act(b, a, this.answer, () => this.run(a)));
      return b;
    });
    const approach = h('input', { id: 'od-approach', type: 'number', value: '6', 'aria-label': 'approach height (m)' });
    const inspect = h('input', { id: 'od-height', type: 'number', value: '2', 'aria-label': 'inspection height (m)' });
    const go = h('button', { id: 'btn-inspect', className: 'primary' }, 'Inspect now');
    go.addEventListener('click', () =>
      act(go, 'on-demand inspection', this.odAnswer, () => this.inspect(parseFloat(approach.value), parseFloat(inspect.value))),
    );
    const frameForm = this.frameForm();
    byId('panel-control').append(
      h('h2', {}, 'Mission control'),
      h('div', { className: 'row' }, h('label', {}, 'Drone ', this.drone), h('label', {}, 'Mission # ', this.missionId), h('label', {}, 'Item ', this.itemId)),
      h('div', { className: 'buttons', id: 'ctl-buttons' }, buttons),
      h('p', { className: 'hint' }, `LOAD sends the plan editor's mission; INSERT and MODIFY send the plan item marked "use"; JUMP TO, MODIFY and REMOVE act at the item index; INSERT goes after it (-1: at the start, empty: at the end).`),
      this.answer,
      h('h3', {}, 'On-demand task'),
      h('p', { className: 'hint' }, 'Inspect a registered frame (a panel) now: the drone flies above it, descends, takes a photo where the behaviors exist, and climbs back. It replaces the drone\'s current mission.'),
      h('div', { className: 'row' }, h('label', {}, 'Frame ', this.odFrame), h('label', {}, 'Drone ', this.odDrone)),
      h('div', { className: 'row' }, h('label', {}, 'Approach m ', approach), h('label', {}, 'Inspect m ', inspect), go),
      this.odAnswer,
      frameForm,
    );
  }

  /** Registers a frame (a panel named in an alert) at an ENU position, for the on-demand task. */
  private frameForm(): HTMLElement {
    const id = h('input', { id: 'frame-id', placeholder: 'panel_12', 'aria-label': 'frame id' });
    const num = (name: string) => h('input', { id: `frame-${name}`, type: 'number', step: '0.1', value: '0', 'aria-label': `frame ${name}` });
    const [x, y, z, yaw] = ['x', 'y', 'z', 'yaw'].map(num);
    const answer = h('p', { className: 'answer', id: 'frame-answer' });
    const add = h('button', { id: 'btn-frame' }, 'Register frame');
    add.addEventListener('click', () =>
      act(add, 'register frame', answer, async () => {
        const inst = this.app.ref(this.odDrone.value)?.inst ?? this.app.instances[0];
        if (!inst) return { ok: false, text: 'not connected' };
        if (!id.value.trim()) return { ok: false, text: 'name the frame' };
        const v = (el: HTMLInputElement) => Number(el.value) || 0;
        try {
          const r = await inst.client.postFrame({ frame_id: id.value.trim(), parent: 'earth', translation_m: [v(x), v(y), v(z)], yaw_rad: (v(yaw) * Math.PI) / 180 });
          await inst.refreshFrames();
          this.selectFrame(r.frame_id);
          this.app.emit('instances');
          return { ok: true, text: `${r.frame_id} at (${v(x)}, ${v(y)}, ${v(z)}) m` };
        } catch (e) {
          return { ok: false, text: describeError(e) };
        }
      }),
    );
    return h(
      'details',
      { id: 'frame-details' },
      h('summary', {}, 'Register a frame (a panel from an alert)'),
      h('div', { className: 'row' }, h('label', {}, 'Frame ', id), h('label', {}, 'x m ', x), h('label', {}, 'y m ', y), h('label', {}, 'z m ', z), h('label', {}, 'yaw ° ', yaw), add),
      answer,
    );
  }

  refreshChoices(): void {
    const drones = this.app.drones().map((d) => ({ value: d.key, label: d.name }));
    const fleetWide = this.drone.value === ALL;
    setOptions(this.drone, [...drones, { value: ALL, label: 'all drones' }]);
    setOptions(this.odDrone, drones);
    // The page's selected drone unless the operator chose "all drones" here.
    const selected = this.app.selected()?.key;
    if (!fleetWide && selected) this.drone.value = selected;
    const frames = this.app.instances.flatMap((i) => i.frames.filter((f) => f.frame_id !== 'earth').map((f) => f.frame_id));
    setOptions(this.odFrame, [...new Set(frames)].map((f) => ({ value: f, label: f })));
  }

  selectDrone(key: string): void {
    this.drone.value = key;
    this.odDrone.value = key;
  }

  selectFrame(frameId: string): void {
    this.refreshChoices();
    this.odFrame.value = frameId;
  }

  private targets(): DroneRef[] {
    if (this.drone.value === ALL) return this.app.drones();
    const r = this.app.ref(this.drone.value) ?? this.app.selected();
    return r ? [r] : [];
  }

  private async run(action: ActionName): Promise<Outcome> {
    const targets = this.targets();
    if (this.drone.value === ALL && CONFIRM_FLEET.includes(action) && targets.length > 0) {
      const names = targets.map((r) => r.name).join(', ');
      if (!window.confirm(`${action} on ALL drones (${names})?`)) return { ok: false, text: `not sent: ${action} on all drones cancelled` };
    }
    const num = (el: HTMLInputElement) => (el.value.trim() === '' ? null : Number(el.value));
    const missionId = num(this.missionId);
    const itemId = num(this.itemId);
    return this.app.forAll(targets, async (ref) => {
      if (action === 'LOAD') {
        try {
          const r = await this.app.upload(ref, this.plan.draft);
          return r.outcome;
        } catch (e) {
          return { ok: false, text: `${ref.name}: ${describeError(e)}` };
        }
      }
      return this.app.action(ref, action, { missionId, itemId, item: this.plan.chosen() });
    });
  }

  private async inspect(approach: number, height: number): Promise<Outcome> {
    const ref = this.app.ref(this.odDrone.value);
    const frameId = this.odFrame.value;
    if (!ref) return { ok: false, text: 'choose a drone' };
    if (!frameId) return { ok: false, text: 'no registered frame: POST /api/frames registers panels' };
    const flight = this.app.view(ref).status?.flight;
    const mission = inspectMission(ref.drone, {
      frameId,
      approachHeight_m: approach,
      inspectHeight_m: height,
      speed_mps: this.plan.defaults().speed_mps,
      landed: flight !== 'flying',
      available: ref.inst.behaviorNames(),
    });
    try {
      const r = await this.app.upload(ref, mission);
      if (!r.outcome.ok) return r.outcome;
      return await this.app.action(ref, 'START', { missionId: r.missionId });
    } catch (e) {
      return { ok: false, text: describeError(e) };
    }
  }
}
