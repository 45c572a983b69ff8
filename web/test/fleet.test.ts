import { describe, expect, it } from 'vitest';
import {
  applyMessage,
  feedbackPaths,
  itemRows,
  linkView,
  missionProgress,
  motionBehavior,
  newInstanceState,
  pilotTakeover,
  fleetPeerLost,
  STALE_AFTER_MS,
} from '../src/lib/fleet';
import type { DroneStatus, MissionStatus } from '../src/lib/types';

function drone(name: string, over: Partial<DroneStatus> = {}): DroneStatus {
  return {
    drone: name,
    link: 'ok',
    armed: false,
    offboard: false,
    mode: 'HOLD',
    flight: 'landed',
    ready_to_fly: true,
    battery: { voltage_v: 16.5, remaining_fraction: 0.97 },
    last_error: null,
    position_enu_m: [0, 0, 0],
    yaw_rad: 0,
    velocity_enu_mps: [0, 0, 0],
    geo: null,
    active_behaviors: [],
    ...over,
  };
}

const status = (over: Partial<MissionStatus> = {}): MissionStatus => ({
  state: 1,
  pending_items: 2,
  done_items: 1,
  current_item: { behavior: 'go_to', method: '__call__', args: {} },
  feedback_current: null,
  mission_id: 1,
  item_index: 1,
  done_results: [{ item: 0, behavior: 'takeoff', result: 'succeeded' }],
  last_error: null,
  ...over,
});

describe('status reduction', () => {
  it('telemetry creates views and grows trails coloured by behavior', () => {
    const s = newInstanceState();
    const running = [{ id: 1, behavior: 'takeoff', state: 'running' }];
    applyMessage(s, { type: 'telemetry', t: 1, drones: [drone('drone_0', { active_behaviors: running })] }, 1000);
    applyMessage(s, { type: 'telemetry', t: 1.2, drones: [drone('drone_0', { position_enu_m: [0, 0, 0.05], active_behaviors: running })] }, 1200);
    applyMessage(s, { type: 'telemetry', t: 1.4, drones: [drone('drone_0', { position_enu_m: [0, 0, 1], active_behaviors: running })] }, 1400);
    const v = s.drones.get('drone_0')!;
    expect(v.trail.map((p) => p.z)).toEqual([0, 1]);
    expect(v.trail[1].behavior).toBe('takeoff');
    expect(v.lastSeenMs).toBe(1400);
    expect(s.serverT).toBe(1.4);
  });

  it('telemetry without a position leaves no trail point until one comes', () => {
    const s = newInstanceState();
    const none = { has_position: false, position_enu_m: null, yaw_rad: null, velocity_enu_mps: null };
    applyMessage(s, { type: 'telemetry', t: 1, drones: [drone('drone_0', { link: 'connecting', ...none })] }, 1000);
    expect(s.drones.get('drone_0')!.trail).toEqual([]);
    applyMessage(s, { type: 'telemetry', t: 2, drones: [drone('drone_0', { has_position: true, position_enu_m: [3, 4, 0] })] }, 2000);
    expect(s.drones.get('drone_0')!.trail.map((p) => [p.x, p.y])).toEqual([[3, 4]]);
  });

  it('mission_status is kept apart from telemetry, which has no mission', () => {
    const s = newInstanceState();
    applyMessage(s, { type: 'mission_status', drone: 'drone_1', status: status() }, 0);
    applyMessage(s, { type: 'telemetry', t: 2, drones: [drone('drone_1')] }, 10);
    expect(s.drones.get('drone_1')!.mission?.mission_id).toBe(1);
  });

  it('prefers the running motion behavior over payload ones', () => {
    expect(
      motionBehavior(drone('d', {
        active_behaviors: [
          { id: 1, behavior: 'point_gimbal', state: 'running' },
          { id: 2, behavior: 'follow_path', state: 'running' },
        ],
      })),
    ).toBe('follow_path');
    expect(motionBehavior(drone('d'))).toBeNull();
  });
});

describe('link-lost detection', () => {
  const s = newInstanceState();
  applyMessage(s, { type: 'telemetry', t: 1, drones: [drone('a'), drone('b', { link: 'lost' })] }, 10_000);
  it('fresh telemetry with link ok is live', () => {
    expect(linkView(s.drones.get('a')!, 10_500, true).state).toBe('ok');
  });
  it('a drone the server reports lost is lost', () => {
    expect(linkView(s.drones.get('b')!, 10_500, true)).toEqual({ state: 'lost', reason: 'autopilot link lost' });
  });
  it('stale telemetry is lost, not a stale live drone', () => {
    const l = linkView(s.drones.get('a')!, 10_000 + STALE_AFTER_MS + 1000, true);
    expect(l.state).toBe('lost');
    expect(l.reason).toMatch(/no telemetry for 4 s/);
  });
  it('a closed WebSocket makes every drone lost', () => {
    expect(linkView(s.drones.get('a')!, 10_100, false).state).toBe('lost');
  });
  it('a drone never heard from is connecting', () => {
    expect(linkView({ drone: 'c', status: null, lastSeenMs: null, mission: null, trail: [] }, 0, true).state).toBe('connecting');
  });
});

describe('mission progress', () => {
  it('counts done/total with the current behavior', () => {
    expect(missionProgress(status()).label).toBe('1/4 go_to');
    expect(missionProgress(null).label).toBe('—');
  });
  it('rows name done, current and pending items', () => {
    const plan = ['takeoff', 'go_to', 'go_to', 'land'].map((b) => ({ behavior: b, args: {} }));
    expect(itemRows(status(), plan).map((r) => `${r.behavior}:${r.state}`)).toEqual([
      'takeoff:done', 'go_to:current', 'go_to:pending', 'land:pending',
    ]);
    expect(itemRows(status(), null).map((r) => r.behavior)).toEqual(['takeoff', 'go_to', '?', '?']);
    const finished = status({ state: 0, pending_items: 0, done_items: 4, current_item: null, item_index: null });
    expect(itemRows(finished, plan).every((r) => r.state === 'done')).toBe(true);
  });
});

describe('planned paths in feedback', () => {
  it("reads a planner's path from a running behavior's feedback", () => {
    const s = drone('d', {
      active_behaviors: [
        { id: 1, behavior: 'navigate_to', state: 'running', feedback: { planned_path_m: [[0, 0], [1, 2, 3]], distance: 4 } },
        { id: 2, behavior: 'go_to', state: 'running', feedback: { path: 'none' } },
      ],
    });
    expect(feedbackPaths(s)).toEqual([{ behavior: 'navigate_to', points: [[0, 0, 0], [1, 2, 3]] }]);
    expect(feedbackPaths(null)).toEqual([]);
  });
});

describe('pilot takeover', () => {
  it('says the pilot took over, with the mode, and what RESUME and STOP do while paused', () => {
    const taken = status({ state: 2, last_error: 'pilot took over (mode AUTO.LOITER)', last_error_code: 'pilot_takeover' });
    expect(pilotTakeover(taken)).toBe(
      'pilot took over (mode AUTO.LOITER): mission paused — RESUME takes it back, STOP leaves it with the pilot',
    );
    expect(pilotTakeover({ ...taken, state: 0 })).toBe('pilot took over (mode AUTO.LOITER)');
  });

  it('says a lost fleet peer holds the drone, and what ends it', () => {
    const words = 'fleet peer lost: drone_1 fell silent while flying; holding until the peer is back or an operator lands it';
    const held = status({ state: 2, last_error: words, last_error_code: 'fleet_peer_lost' });
    expect(fleetPeerLost(held)).toBe(`${words} — mission paused, resumes by itself when the peer is back; LAND lands it now`);
    expect(fleetPeerLost({ ...held, state: 0 })).toBe(words);
    expect(pilotTakeover(held)).toBeNull();
    expect(fleetPeerLost(status({ state: 0, last_error: 'no progress', last_error_code: 'no_progress' }))).toBeNull();
  });

  it('stays quiet for other failures and older servers', () => {
    expect(pilotTakeover(status({ state: 0, last_error: 'mission 1 item 1 (go_to) failed', last_error_code: 'no_progress' }))).toBeNull();
    expect(pilotTakeover(status({ last_error: 'pilot took over (mode LOITER)' }))).toBeNull();
    expect(pilotTakeover(null)).toBeNull();
  });
});
