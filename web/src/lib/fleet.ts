// Status reduction: WebSocket messages of one Kestrel instance folded into per-drone views, the
// link judged with a staleness timeout, and mission progress read from MissionStatus.

import type { DroneStatus, MissionItem, MissionStatus, PlacedStatus, ServerMessage } from './types';

export interface TrailPoint {
  x: number;
  y: number;
  z: number;
  /** Server time (s) of the telemetry frame. */
  t: number;
  behavior: string | null;
}

export interface DroneView {
  drone: string;
  status: DroneStatus | null;
  /** Page clock (ms) when telemetry last mentioned this drone. */
  lastSeenMs: number | null;
  mission: MissionStatus | null;
  trail: TrailPoint[];
}

export interface InstanceState {
  drones: Map<string, DroneView>;
  /** Server time (s) of the last telemetry frame. */
  serverT: number | null;
}

export const TRAIL_MAX_POINTS = 5000;
/** A new trail point is kept when the drone moved this far (m) or its behavior changed. */
export const TRAIL_MIN_STEP_M = 0.15;
/** Telemetry older than this (ms) means the link is lost, whatever the last frame said. */
export const STALE_AFTER_MS = 3000;

export function newInstanceState(): InstanceState {
  return { drones: new Map(), serverT: null };
}

function viewOf(state: InstanceState, drone: string): DroneView {
  let v = state.drones.get(drone);
  if (!v) {
    v = { drone, status: null, lastSeenMs: null, mission: null, trail: [] };
    state.drones.set(drone, v);
  }
  return v;
}

const PAYLOAD = new Set(['point_gimbal', 'take_photo', 'panel_diagnose', 'record', 'gripper']);

/** The behavior that moves the drone (what colours its trail), or null when none runs. */
export function motionBehavior(status: DroneStatus | null): string | null {
  const active = status?.active_behaviors ?? [];
  const moving = active.filter((b) => !PAYLOAD.has(b.behavior));
  const running = moving.find((b) => b.state === 'running') ?? moving[0];
  return running?.behavior ?? null;
}

function extendTrail(v: DroneView, s: DroneStatus, t: number): void {
  if (!hasPosition(s)) return;
  const [x, y, z] = s.position_enu_m;
  const behavior = motionBehavior(s);
  const last = v.trail[v.trail.length - 1];
  if (last) {
    const moved = Math.hypot(x - last.x, y - last.y, z - last.z);
    if (moved < TRAIL_MIN_STEP_M && behavior === last.behavior) return;
  }
  v.trail.push({ x, y, z, t, behavior });
  if (v.trail.length > TRAIL_MAX_POINTS) v.trail.splice(0, v.trail.length - TRAIL_MAX_POINTS);
}

/** Folds one server message into the state. Returns the drones it touched. */
export function applyMessage(state: InstanceState, msg: ServerMessage, nowMs: number): string[] {
  switch (msg.type) {
    case 'telemetry': {
      state.serverT = msg.t;
      return msg.drones.map((s) => {
        const v = viewOf(state, s.drone);
        v.status = s.mission === undefined ? { ...s, mission: v.status?.mission } : s;
        if (s.mission) v.mission = s.mission;
        v.lastSeenMs = nowMs;
        extendTrail(v, s, msg.t);
        return s.drone;
      });
    }
    case 'mission_status':
      viewOf(state, msg.drone).mission = msg.status;
      return [msg.drone];
    default:
      return [];
  }
}

/** Seeds the views from `GET /api/status` (before the first telemetry frame). */
export function applyStatus(state: InstanceState, drones: DroneStatus[], nowMs: number): void {
  for (const s of drones) {
    const v = viewOf(state, s.drone);
    v.status = s;
    if (s.mission) v.mission = s.mission;
    v.lastSeenMs = nowMs;
  }
}

export type LinkView = { state: 'ok' | 'connecting' | 'lost'; reason: string };

/** The link as the operator must see it: a drone not heard from recently is lost, not live. */
export function linkView(
  v: DroneView,
  nowMs: number,
  socketOpen: boolean,
  staleAfterMs = STALE_AFTER_MS,
): LinkView {
  if (!socketOpen) return { state: 'lost', reason: 'no connection to kestrel' };
  if (!v.status || v.lastSeenMs === null) return { state: 'connecting', reason: 'waiting for telemetry' };
  const age = nowMs - v.lastSeenMs;
  if (age > staleAfterMs) {
    return { state: 'lost', reason: `no telemetry for ${(age / 1000).toFixed(0)} s` };
  }
  if (v.status.link === 'lost' || v.status.stale) return { state: 'lost', reason: 'autopilot link lost' };
  if (v.status.link === 'connecting') return { state: 'connecting', reason: 'waiting for the autopilot (HEARTBEAT)' };
  return { state: 'ok', reason: 'live' };
}

export const MISSION_STATES = ['idle', 'running', 'paused'] as const;

export function missionStateName(ms: MissionStatus | null): string {
  if (!ms) return 'no mission';
  return MISSION_STATES[ms.state] ?? `state ${ms.state}`;
}

/**
 * When a pilot (or a ground station) took the drone from Kestrel: what to tell the operator, e.g.
 * "pilot took over (mode AUTO.LOITER)", with what RESUME and STOP do while the mission is paused.
 * Null otherwise.
 */
export function pilotTakeover(ms: MissionStatus | null): string | null {
  if (!ms || ms.last_error_code !== 'pilot_takeover' || !ms.last_error) return null;
  if (ms.state === 2) return `${ms.last_error}: mission paused — RESUME takes it back, STOP leaves it with the pilot`;
  return ms.last_error;
}

/**
 * A mission paused because a fleet-bus peer's drone fell silent while flying (`fleet_peer_lost`):
 * the drone holds until the peer is back (the mission then resumes by itself) or it is landed.
 */
export function fleetPeerLost(ms: MissionStatus | null): string | null {
  if (!ms || ms.last_error_code !== 'fleet_peer_lost' || !ms.last_error) return null;
  if (ms.state === 2) return `${ms.last_error} — mission paused, resumes by itself when the peer is back; LAND lands it now`;
  return ms.last_error;
}

export interface Progress {
  done: number;
  total: number;
  label: string;
}

/** `done/total` with the current item's behavior, e.g. "2/4 go_to". */
export function missionProgress(ms: MissionStatus | null): Progress {
  if (!ms) return { done: 0, total: 0, label: '—' };
  const current = ms.current_item ? 1 : 0;
  const total = ms.done_items + ms.pending_items + current;
  const label = total === 0 ? '—' : `${ms.done_items}/${total}${ms.current_item ? ` ${ms.current_item.behavior}` : ''}`;
  return { done: ms.done_items, total, label };
}

export interface ItemRow {
  index: number;
  behavior: string;
  state: 'done' | 'current' | 'pending';
  result: string | null;
}

/**
 * The mission's items as done / current / pending. With the plan known (the page loaded it) every
 * item is named; otherwise pending items are counted only.
 */
export function itemRows(ms: MissionStatus | null, plan: MissionItem[] | null): ItemRow[] {
  if (!ms) return (plan ?? []).map((it, index) => ({ index, behavior: it.behavior, state: 'pending', result: null }));
  const rows: ItemRow[] = [];
  const results = new Map(ms.done_results.map((r) => [r.item, r]));
  const currentIndex = ms.current_item ? (ms.item_index ?? ms.done_items) : null;
  const total = ms.done_items + ms.pending_items + (ms.current_item ? 1 : 0);
  const count = Math.max(total, plan?.length ?? 0);
  for (let index = 0; index < count; index++) {
    const done = results.get(index);
    const state: ItemRow['state'] =
      index === currentIndex ? 'current' : done || (currentIndex === null ? index < ms.done_items : index < currentIndex) ? 'done' : 'pending';
    const behavior =
      (index === currentIndex ? ms.current_item?.behavior : undefined) ?? done?.behavior ?? plan?.[index]?.behavior ?? '?';
    rows.push({ index, behavior, state, result: done?.result ?? null });
  }
  return rows;
}

/**
 * Paths a running behavior reports in its feedback (a planner's route for navigate_to): any
 * feedback value named like `path` holding [x, y(, z)] points.
 */
export function feedbackPaths(status: DroneStatus | null): { behavior: string; points: [number, number, number][] }[] {
  const out: { behavior: string; points: [number, number, number][] }[] = [];
  for (const b of status?.active_behaviors ?? []) {
    for (const [key, value] of Object.entries(b.feedback ?? {})) {
      if (!/path/i.test(key) || !Array.isArray(value)) continue;
      const points = value
        .filter((p): p is number[] => Array.isArray(p) && p.length >= 2 && p.every((v) => typeof v === 'number'))
        .map((p) => [p[0], p[1], p[2] ?? 0] as [number, number, number]);
      if (points.length >= 2) out.push({ behavior: b.behavior, points });
    }
  }
  return out;
}

/** Whether the status carries a position the autopilot gave (never one made up before it spoke). */
export function hasPosition(s: DroneStatus | null | undefined): s is PlacedStatus {
  if (!s || s.position_enu_m === null || s.yaw_rad === null) return false;
  return s.has_position ?? s.link !== 'connecting';
}
