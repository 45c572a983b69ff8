import { describe, expect, it } from 'vitest';
import { buildUpdate, holdUpdate, inspectMission, landUpdate } from '../src/lib/missionUpdate';
import { takeoffItem } from '../src/lib/mission';

describe('MissionUpdate construction', () => {
  it('START carries the mission id and no item', () => {
    expect(buildUpdate('START', 'drone_0', { missionId: 4, itemId: 2 })).toEqual({
      update: { drone_id: 'drone_0', mission_id: 4, item_id: null, action: 2, mission: null },
    });
  });

  it('LOAD carries the mission retargeted at the drone', () => {
    const r = buildUpdate('LOAD', 'drone_1', { missionId: 1, mission: { target: 'drone_0', plan: [] } });
    expect(r).toMatchObject({ update: { action: 1, mission_id: 1, mission: { target: 'drone_1' } } });
  });

  it('item actions need an index; INSERT and MODIFY need an item', () => {
    expect(buildUpdate('JUMP_TO', 'd', { missionId: 1 })).toHaveProperty('error');
    expect(buildUpdate('REMOVE', 'd', { missionId: 1, itemId: -1 })).toHaveProperty('error');
    expect(buildUpdate('REMOVE', 'd', { missionId: 1, itemId: 2 })).toMatchObject({ update: { action: 10, item_id: 2 } });
    expect(buildUpdate('MODIFY', 'd', { missionId: 1, itemId: 0 })).toHaveProperty('error');
    const it1 = takeoffItem(2, 1);
    expect(buildUpdate('INSERT', 'd', { missionId: 1, itemId: 1, item: it1 })).toEqual({
      update: { drone_id: 'd', mission_id: 1, item_id: 1, action: 8, mission: { target: 'd', plan: [it1] } },
    });
    expect(buildUpdate('INSERT', 'd', { missionId: 1, item: it1 })).toMatchObject({ update: { item_id: null } });
    expect(buildUpdate('INSERT', 'd', { missionId: 1, itemId: -1, item: it1 })).toMatchObject({ update: { item_id: -1 } });
    expect(buildUpdate('INSERT', 'd', { missionId: 1, itemId: -2, item: it1 })).toHaveProperty('error');
    expect(buildUpdate('LOAD', 'd', {})).toHaveProperty('error');
  });

  it('hold pauses, land executes a one-item land mission', () => {
    expect(holdUpdate('d', 3)).toEqual({ drone_id: 'd', mission_id: 3, item_id: null, action: 3, mission: null });
    const l = landUpdate('d');
    expect(l.action).toBe(0);
    expect(l.mission?.plan.map((i) => i.behavior)).toEqual(['land']);
  });
});

describe('on-demand inspection', () => {
  it('is built relative to the panel frame, with takeoff when landed', () => {
    const m = inspectMission('drone_1', {
      frameId: 'panel_7',
      approachHeight_m: 8,
      inspectHeight_m: 3,
      speed_mps: 2,
      landed: true,
      available: new Set(['takeoff', 'go_to', 'take_photo']),
    });
    expect(m.target).toBe('drone_1');
    expect(m.plan.map((i) => i.behavior)).toEqual(['takeoff', 'go_to', 'go_to', 'take_photo', 'go_to']);
    expect(m.plan[2].args).toEqual({ x: 0, y: 0, z: 3, speed: 2, frame_id: 'panel_7' });
  });
});
