import { describe, expect, it } from 'vitest';
import { enuToGeo } from '../src/lib/geo';
import {
  addGpsWaypoint,
  addPath,
  addWaypoint,
  coverageMissions,
  emptyMission,
  goToItem,
  landItem,
  moveItem,
  moveTarget,
  parseMission,
  plannedPath,
  sortErrors,
  takeoffItem,
} from '../src/lib/mission';

const d = { height_m: 4, speed_mps: 2 };

describe('mission building from clicks', () => {
  it('a click adds a go_to at the planning height', () => {
    const m = addWaypoint(emptyMission('drone_0'), [3.456, -1.2], d);
    expect(m.plan).toEqual([
      { behavior: 'go_to', method: '__call__', args: { x: 3.46, y: -1.2, z: 4, speed: 2 } },
    ]);
  });

  it('takeoff, clicks, land gives takeoff-go_to-go_to-land, clicks after land go before it', () => {
    let m = { target: 'drone_0', plan: [takeoffItem(4, 2)] };
    m = addWaypoint(m, [1, 1], d);
    m = { ...m, plan: [...m.plan, landItem(0.5)] };
    m = addWaypoint(m, [2, 2], d);
    expect(m.plan.map((i) => i.behavior)).toEqual(['takeoff', 'go_to', 'go_to', 'land']);
    expect(m.plan[2].args).toMatchObject({ x: 2, y: 2 });
  });

  it('a drawn path becomes one follow_path item', () => {
    const m = addPath(emptyMission('d'), [[0, 0], [5, 0], [5, 5]], d);
    expect(m.plan).toHaveLength(1);
    expect(m.plan[0].args.path).toEqual([[0, 0, 4], [5, 0, 4], [5, 5, 4]]);
    expect(addPath(m, [], d)).toBe(m);
  });

  it('moves items within bounds only', () => {
    const m = { target: 'd', plan: [takeoffItem(1, 1), landItem(1)] };
    expect(moveItem(m, 1, -1).plan.map((i) => i.behavior)).toEqual(['land', 'takeoff']);
    expect(moveItem(m, 1, 1)).toBe(m);
  });
});

describe('coverage', () => {
  it('each drone gets takeoff, reach first point, sweep, land', () => {
    const missions = coverageMissions(
      {
        angle_deg: 0,
        per_drone: { drone_0: [[0, 0, 6], [10, 0, 6]], drone_1: [[0, 5, 6], [10, 5, 6]], drone_2: [] },
        lengths_m: { drone_0: 10, drone_1: 10, drone_2: 0 },
      },
      d,
    );
    expect(Object.keys(missions)).toEqual(['drone_0', 'drone_1']);
    const m = missions.drone_1;
    expect(m.target).toBe('drone_1');
    expect(m.plan.map((i) => i.behavior)).toEqual(['takeoff', 'go_to', 'follow_path', 'land']);
    expect(m.plan[0].args.height).toBe(6);
    expect(m.plan[1].args).toMatchObject({ x: 0, y: 5, z: 6 });
    expect(m.plan[2].args.path).toEqual([[0, 5, 6], [10, 5, 6]]);
  });
});

describe('planned path', () => {
  it('follows takeoff, go_to, follow_path, land from the start', () => {
    const m = {
      target: 'd',
      plan: [
        takeoffItem(3, 1),
        goToItem([5, 0, 3], 1),
        { behavior: 'follow_path', args: { path: [[5, 5, 3], [0, 5, 3]] } },
        { behavior: 'go_to', args: { x: 0, y: 0, z: 2, frame_id: 'panel_3' } },
        landItem(1),
      ],
    };
    const { points, items, framed } = plannedPath(m, [1, 1, 0]);
    expect(items).toEqual([-1, 0, 1, 2, 2, 4]);
    expect(points).toEqual([[1, 1, 0], [1, 1, 3], [5, 0, 3], [5, 5, 3], [0, 5, 3], [0, 5, 0]]);
    expect(framed).toEqual(['panel_3']);
  });
});

describe('validation errors', () => {
  it('sorts JSON pointers by item and argument', () => {
    const e = sortErrors([
      { pointer: '/plan/1/args/speed', message: 'must be > 0 m/s' },
      { pointer: '/plan/1/behavior', message: 'unknown behavior' },
      { pointer: '/plan/0', message: 'bad item' },
      { pointer: '/target', message: 'no such drone' },
      { pointer: '', message: 'empty plan' },
    ]);
    expect(e.items.get(1)?.args.get('speed')).toEqual(['must be > 0 m/s']);
    expect(e.items.get(1)?.item).toEqual(['behavior: unknown behavior']);
    expect(e.items.get(0)?.item).toEqual(['bad item']);
    expect(e.general).toEqual(['/target: no such drone', 'empty plan']);
  });
});

describe('mission files', () => {
  it('reads a mission and fills method and target', () => {
    const r = parseMission('{"plan":[{"behavior":"land","args":{"speed":1}}]}', 'drone_1');
    expect(r).toEqual({ mission: { target: 'drone_1', plan: [{ behavior: 'land', method: '__call__', args: { speed: 1 } }] } });
  });
  it('accepts a bare plan array', () => {
    const r = parseMission('[{"behavior":"takeoff","args":{}}]', 'x');
    expect('mission' in r && r.mission.plan).toHaveLength(1);
  });
  it('says what is wrong', () => {
    expect(parseMission('{', 'x')).toHaveProperty('error');
    expect(parseMission('{"plan": 3}', 'x')).toHaveProperty('error');
    expect(parseMission('{"plan": [{"args": {}}]}', 'x')).toEqual({ error: 'plan[0] has no "behavior"' });
  });
});

describe('geographic missions', () => {
  it('a click in the geographic view adds a go_to_gps that is drawn back at the same ENU point', () => {
    const origin = { lat_deg: 40.44, lon_deg: -3.69, alt_m: 650 };
    const [lat, lon] = enuToGeo(origin, 30, -20);
    const m = addGpsWaypoint({ target: 'd', plan: [takeoffItem(5, 1), landItem(1)] }, [lat, lon], 650, d);
    expect(m.plan.map((i) => i.behavior)).toEqual(['takeoff', 'go_to_gps', 'land']);
    expect(m.plan[1].args.alt).toBe(654);
    const { points } = plannedPath(m, [0, 0, 0], origin);
    expect(points[2][0]).toBeCloseTo(30, 1);
    expect(points[2][1]).toBeCloseTo(-20, 1);
    expect(points[2][2]).toBeCloseTo(4, 6);
    expect(plannedPath(m).points).toHaveLength(3); // without the origin the lat/lon point is left out
  });
});

describe('dragging a target on the map', () => {
  const origin = { lat_deg: 47.3977, lon_deg: 8.5456, alt_m: 488 };

  it('moves a go_to and keeps its height and speed', () => {
    const m = addWaypoint(emptyMission('drone_0'), [1, 2], d);
    const moved = moveTarget(m, 0, 0, [10.123, -4.5], null);
    expect(moved.plan[0].args).toMatchObject({ x: 10.12, y: -4.5, z: 4, speed: 2 });
    expect(m.plan[0].args).toMatchObject({ x: 1, y: 2 });
  });

  it('moves one point of a follow_path, the others stay', () => {
    const m = addPath(emptyMission('drone_0'), [[0, 0], [5, 5], [10, 0]], d);
    const moved = moveTarget(m, 0, 1, [6, 7], null);
    expect(moved.plan[0].args.path).toEqual([[0, 0, 4], [6, 7, 4], [10, 0, 4]]);
  });

  it('moves a go_to_gps in lat/lon, and leaves it when the origin is unknown', () => {
    const m = addGpsWaypoint(emptyMission('drone_0'), enuToGeo(origin, 0, 0), 488, d);
    const [lat, lon] = enuToGeo(origin, 20, 10);
    const moved = moveTarget(m, 0, 0, [20, 10], origin);
    expect(moved.plan[0].args.lat).toBeCloseTo(lat, 7);
    expect(moved.plan[0].args.lon).toBeCloseTo(lon, 7);
    expect(moveTarget(m, 0, 0, [20, 10], null)).toBe(m);
  });

  it('leaves takeoff and land alone, and plannedPath marks only targets movable', () => {
    const m = { target: 'drone_0', plan: [takeoffItem(3, 1), goToItem([5, 5, 3], 1), landItem(0.5)] };
    expect(moveTarget(m, 0, 0, [9, 9], null)).toBe(m);
    expect(plannedPath(m).movable).toEqual([false, false, true, false]);
  });
});
