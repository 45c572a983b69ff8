import { describe, expect, it } from 'vitest';
import { hasPosition, linkView } from '../src/lib/fleet';
import { sideExtent, sidePixel } from '../src/lib/sideView';
import type { DroneStatus } from '../src/lib/types';

const status = (over: Partial<DroneStatus>): DroneStatus =>
  ({ drone: 'd', link: 'ok', position_enu_m: [0, 0, 0], active_behaviors: [], ...over }) as DroneStatus;

describe('altitude view geometry', () => {
  it('holds a 30 m climb 40 m east, ground at the bottom and the top point inside', () => {
    const e = sideExtent([{ x: 0, z: 0 }, { x: 35, z: 30 }]);
    expect(e.xMin).toBeLessThan(0);
    expect(e.xMax).toBeGreaterThan(35);
    expect(e.zMax).toBeGreaterThan(30);
    const [, ground] = sidePixel(e, 200, 300, 20, 0, 0);
    const [, top] = sidePixel(e, 200, 300, 20, 35, 30);
    expect(ground).toBe(280);
    expect(top).toBeGreaterThan(20);
    expect(top).toBeLessThan(ground);
  });

  it('never collapses to a point when nothing has moved', () => {
    const e = sideExtent([]);
    expect(e.xMax - e.xMin).toBeGreaterThanOrEqual(10);
    expect(e.zMax - e.zMin).toBeGreaterThan(0);
  });
});

describe('no made-up position, stale shown as stale', () => {
  it('has no position while the autopilot has not spoken, or when the server says so', () => {
    expect(hasPosition(null)).toBe(false);
    expect(hasPosition(status({ link: 'connecting' }))).toBe(false);
    expect(hasPosition(status({ link: 'ok', has_position: false }))).toBe(false);
    expect(hasPosition(status({ link: 'lost', has_position: true }))).toBe(true);
    expect(hasPosition(status({ link: 'ok' }))).toBe(true);
    // A null position is no position, whatever else the status says.
    expect(hasPosition(status({ link: 'ok', has_position: true, position_enu_m: null }))).toBe(false);
  });

  it('a status the server marks stale is lost, whatever its link word', () => {
    const v = { drone: 'd', status: status({ link: 'ok', stale: true }), lastSeenMs: 1000, mission: null, trail: [] };
    expect(linkView(v, 1000, true).state).toBe('lost');
  });
});
