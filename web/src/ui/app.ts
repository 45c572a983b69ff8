// The page's state: the instances it talks to, the drone the operator selected, the event log and
// live behavior records, and the commands every view sends (mission updates, upload, hold, land).
// Drones other Kestrels fly (remote, heard over a fleet bus) are listed apart: never a command
// target here.

import { behaviorRecord, describeEvent, updateMarker, type BehaviorRecord, type LogLine, type Marker } from '../lib/events';
import { linkView, missionStateName, type DroneView, type LinkView } from '../lib/fleet';
import { buildUpdate, holdUpdate, landUpdate, type UpdateArgs } from '../lib/missionUpdate';
import { remoteLink, type RemoteLink } from '../lib/remote';
import type { ActionName, Mission, MissionItem, MissionUpdate, RemoteDrone, ServerMessage } from '../lib/types';
import type { Outcome } from './feedback';
import { describeError, Instance } from './instance';

export type Topic = 'fleet' | 'mission' | 'event' | 'map' | 'instances' | 'selection';

export interface DroneRef {
  key: string;
  inst: Instance;
  drone: string;
  /** drone name, prefixed by the instance label when there are several instances */
  name: string;
}

/** A drone another Kestrel flies, as one instance hears it over its fleet bus. */
export interface RemoteRef {
  key: string;
  inst: Instance;
  drone: RemoteDrone;
  /** drone id, prefixed by the instance label when there are several instances */
  name: string;
}

const MAX_EVENTS = 1000;

export class App {
  instances: Instance[] = [];
  selectedKey: string | null = null;
  events: LogLine[] = [];
  records: BehaviorRecord[] = [];
  markers: Marker[] = [];
  /** Last mission id this page loaded per drone key. */
  missionIds = new Map<string, number>();
  /** The last occupancy-grid patch from the merged map. */
  lastMapUpdate: Extract<ServerMessage, { type: 'map_update' }> | null = null;
  /** Plans by `droneKey/missionId` (ids are per drone), to name pending items. */
  plans = new Map<string, MissionItem[]>();
  private listeners = new Set<(topic: Topic) => void>();
  private fetchingPlans = new Set<string>();

  on(fn: (topic: Topic) => void): void {
    this.listeners.add(fn);
  }

  emit(topic: Topic): void {
    for (const fn of this.listeners) fn(topic);
  }

  async addInstance(label: string, base: string, token: string): Promise<Instance> {
    const inst = new Instance(this.instances.length, label, base, token, (i, m) => this.onMessage(i, m));
    await inst.start();
    this.instances.push(inst);
    this.emit('instances');
    return inst;
  }

  drones(): DroneRef[] {
    const several = this.instances.length > 1;
    return this.instances.flatMap((inst) =>
      [...inst.state.drones.keys()].sort().map((drone) => ({
        key: `${inst.id}/${drone}`,
        inst,
        drone,
        name: several ? `${inst.label}:${drone}` : drone,
      })),
    );
  }

  /**
   * Remote drones of every instance, sorted; one this page also reaches as a local drone of
   * another instance is listed there only.
   */
  remoteDrones(): RemoteRef[] {
    const several = this.instances.length > 1;
    const local = new Set(this.instances.flatMap((i) => [...i.state.drones.keys()]));
    return this.instances.flatMap((inst) =>
      [...inst.remote.drones.values()]
        .filter((r) => !local.has(r.id))
        .sort((a, b) => a.id.localeCompare(b.id))
        .map((drone) => ({ key: `${inst.id}/remote/${drone.id}`, inst, drone, name: several ? `${inst.label}:${drone.id}` : drone.id })),
    );
  }

  remoteLink(ref: RemoteRef, nowMs = Date.now()): RemoteLink {
    return remoteLink(ref.drone, ref.inst.remote, nowMs, ref.inst.socketOpen);
  }

  ref(key: string | null): DroneRef | undefined {
    return this.drones().find((d) => d.key === key);
  }

  selected(): DroneRef | undefined {
    return this.ref(this.selectedKey) ?? this.drones()[0];
  }

  select(key: string): void {
    this.selectedKey = key;
    this.emit('selection');
  }

  view(ref: DroneRef): DroneView {
    return ref.inst.state.drones.get(ref.drone) ?? { drone: ref.drone, status: null, lastSeenMs: null, mission: null, trail: [] };
  }

  link(ref: DroneRef, nowMs = Date.now()): LinkView {
    return linkView(this.view(ref), nowMs, ref.inst.socketOpen);
  }

  planOf(ref: DroneRef): MissionItem[] | null {
    const id = this.view(ref).mission?.mission_id ?? this.missionIds.get(ref.key);
    return id == null ? null : (this.plans.get(`${ref.key}/${id}`) ?? null);
  }

  log(line: LogLine): void {
    this.events.push(line);
    if (this.events.length > MAX_EVENTS) this.events.splice(0, this.events.length - MAX_EVENTS);
    this.emit('event');
  }

  private onMessage(inst: Instance, msg: ServerMessage | null): void {
    if (!msg) {
      this.emit('instances');
      return;
    }
    switch (msg.type) {
      case 'telemetry':
        this.emit('fleet');
        break;
      case 'mission_status': {
        const id = msg.status.mission_id;
        if (id != null) this.ensurePlan(inst, msg.drone, id);
        this.emit('mission');
        break;
      }
      case 'event': {
        const drone = msg.drone ? this.nameOf(inst, msg.drone) : null;
        const rec = behaviorRecord(msg.t, drone, msg.event);
        if (rec) this.records.push(rec);
        const marker = updateMarker(msg.t, drone, msg.event);
        if (marker) this.markers.push(marker);
        this.log(describeEvent(msg.t, drone, msg.event));
        break;
      }
      case 'map_update':
        if (msg.drone !== null) break;
        this.lastMapUpdate = msg;
        this.emit('map');
        break;
      default:
        break;
    }
  }

  nameOf(inst: Instance, drone: string): string {
    return this.instances.length > 1 ? `${inst.label}:${drone}` : drone;
  }

  private ensurePlan(inst: Instance, drone: string, id: number): void {
    const k = `${inst.id}/${drone}/${id}`;
    if (this.plans.has(k) || this.fetchingPlans.has(k)) return;
    this.fetchingPlans.add(k);
    inst.client
      .mission(id, drone)
      .then((m) => {
        const plan = Array.isArray(m.plan) ? m.plan : m.plan?.plan;
        if (Array.isArray(plan)) this.plans.set(k, plan);
        this.emit('mission');
      })
      .catch(() => {})
      .finally(() => this.fetchingPlans.delete(k));
  }

  /** Sends a MissionUpdate and says what the executor answered. */
  async send(ref: DroneRef, update: MissionUpdate, label: string): Promise<Outcome> {
    const action = label;
    this.log({ t: ref.inst.state.serverT, drone: ref.name, kind: 'command', level: 'info', text: `sent ${action}` });
    try {
      const answer = await ref.inst.client.missionUpdate(update);
      if (answer.status) {
        const v = ref.inst.state.drones.get(ref.drone);
        if (v) v.mission = answer.status;
        this.emit('mission');
      }
      if (answer.accepted) {
        const state = answer.status ? ` — mission ${missionStateName(answer.status)}` : '';
        return { ok: true, text: `${ref.name} ${action}${state}` };
      }
      return { ok: false, text: `${ref.name} ${action}: ${answer.reason ?? 'refused'}` };
    } catch (e) {
      return { ok: false, text: `${ref.name} ${action}: ${describeError(e)}` };
    }
  }

  async action(ref: DroneRef, action: ActionName, args: UpdateArgs): Promise<Outcome> {
    const missionId = args.missionId ?? this.view(ref).mission?.mission_id ?? this.missionIds.get(ref.key) ?? null;
    const built = buildUpdate(action, ref.drone, { ...args, missionId });
    if ('error' in built) return { ok: false, text: built.error };
    return this.send(ref, built.update, action);
  }

  /** Pauses the running mission; a drone with no mission running is already holding. */
  async hold(ref: DroneRef): Promise<Outcome> {
    const ms = this.view(ref).mission;
    if (ms && ms.state !== 1) return { ok: true, text: `${ref.name}: no mission running, nothing to hold` };
    return this.send(ref, holdUpdate(ref.drone, ms?.mission_id ?? null), 'HOLD');
  }

  land(ref: DroneRef): Promise<Outcome> {
    return this.send(ref, landUpdate(ref.drone), 'LAND');
  }

  /** Several drones at once: one outcome naming every refusal. */
  async forAll(refs: DroneRef[], fn: (r: DroneRef) => Promise<Outcome>): Promise<Outcome> {
    if (refs.length === 0) return { ok: false, text: 'no drone known yet' };
    const outcomes = await Promise.all(refs.map(fn));
    const bad = outcomes.filter((o) => !o.ok);
    if (bad.length) return { ok: false, text: bad.map((o) => o.text).join('; ') };
    return { ok: true, text: outcomes.map((o) => o.text).join('; ') };
  }

  /**
   * Loads the mission on the drone through `POST /api/missions` (validated, then loaded as a
   * LOAD would). Throws ApiError with the validation details on 422.
   */
  async upload(ref: DroneRef, mission: Mission): Promise<{ missionId: number; outcome: Outcome; warnings: string[] }> {
    const m = { ...mission, target: ref.drone };
    const t = ref.inst.state.serverT;
    this.log({ t, drone: ref.name, kind: 'command', level: 'info', text: 'sent LOAD (upload)' });
    const { mission_id, warnings } = await ref.inst.client.postMission(m);
    // The server reports MissionUpdates as events; an upload is not one, so mark it here.
    this.markers.push({ t: ref.inst.state.serverT ?? t ?? 0, drone: ref.name, label: 'LOAD' });
    this.plans.set(`${ref.key}/${mission_id}`, m.plan);
    this.missionIds.set(ref.key, mission_id);
    const outcome: Outcome = { ok: true, text: `${ref.name} LOAD mission #${mission_id}` };
    return { missionId: mission_id, outcome, warnings: warnings ?? [] };
  }
}
