import { describe, expect, it } from 'vitest';
import { describeEvent, parseFlightLog, resultText, updateMarker } from '../src/lib/events';
import { buildTimeline, tickStep } from '../src/lib/timeline';
import { trailRuns } from '../src/lib/colors';
import { shortcutFor } from '../src/lib/keyboard';

const LOG = [
  '{"t":0.0,"drone":"drone_0","type":"pose","x":0,"y":0,"z":0,"behavior":null}',
  '{"t":0.5,"drone":"drone_0","type":"command","command":"mission_update","fields":{"action":1}}',
  '{"t":1.0,"drone":"drone_0","type":"command","command":"mission_update","fields":{"action":2}}',
  '{"t":1.1,"drone":"drone_0","type":"behavior","event":"started","id":1,"behavior":"takeoff","goal":{}}',
  '{"t":1.2,"drone":"drone_0","type":"pose","x":0,"y":0,"z":0.5,"behavior":"takeoff"}',
  '{"t":4.0,"drone":"drone_0","type":"behavior","event":"finished","id":1,"behavior":"takeoff","result":{"result":"succeeded"}}',
  '{"t":4.1,"drone":"drone_0","type":"behavior","event":"started","id":2,"behavior":"go_to","goal":{}}',
  '{"t":5.0,"drone":"drone_0","type":"behavior","event":"paused","id":2,"behavior":"go_to"}',
  '{"t":6.0,"drone":"drone_0","type":"behavior","event":"resumed","id":2,"behavior":"go_to"}',
  '{"t":9.0,"drone":"drone_0","type":"behavior","event":"finished","id":2,"behavior":"go_to","result":{"result":"failed","reason":"no progress"}}',
  '{"t":9.5,"drone":"drone_1","type":"behavior","event":"started","id":1,"behavior":"land","goal":{}}',
  'not json',
  '',
].join('\n');

describe('flight log', () => {
  const log = parseFlightLog(LOG);
  it('reads poses, behaviors and mission commands', () => {
    expect(log.poses.get('drone_0')).toHaveLength(2);
    expect(log.behaviors).toHaveLength(7);
    expect(log.markers).toEqual([
      { t: 0.5, drone: 'drone_0', label: 'LOAD' },
      { t: 1.0, drone: 'drone_0', label: 'START' },
    ]);
    expect(log.badLines).toBe(1);
  });

  it('builds segments per activation, split by pause, open while running', () => {
    const tl = buildTimeline(log.behaviors, log.markers, 12);
    expect(tl.segments.map((s) => [s.drone, s.behavior, s.start, s.end, s.result])).toEqual([
      ['drone_0', 'takeoff', 1.1, 4.0, 'succeeded'],
      ['drone_0', 'go_to', 4.1, 5.0, 'paused'],
      ['drone_0', 'go_to', 6.0, 9.0, 'failed: no progress'],
      ['drone_1', 'land', 9.5, null, null],
    ]);
    expect(tl.rows).toEqual([
      { drone: 'drone_0', behavior: 'takeoff' },
      { drone: 'drone_0', behavior: 'go_to' },
      { drone: 'drone_1', behavior: 'land' },
    ]);
    expect(tl.drones).toEqual(['drone_0', 'drone_1']);
    expect([tl.t0, tl.t1]).toEqual([0.5, 12]);
  });

  it('lists no line for map cells and frontiers', () => {
    const maps = parseFlightLog([
      '{"t":2.0,"drone":"drone_0","type":"map","map":"own","region":[0,0,1,1],"cells":"eJwDAAAAAAE="}',
      '{"t":2.0,"drone":null,"type":"frontiers","frontiers":[],"claims":[]}',
      '{"t":2.5,"drone":"drone_0","type":"safety","reason":"geofence"}',
    ].join('\n'));
    expect(maps.lines.map((l) => l.kind)).toEqual(['safety']);
    expect(maps.badLines).toBe(0);
  });

  it('an empty log gives an empty timeline with a usable axis', () => {
    const tl = buildTimeline([], []);
    expect(tl.segments).toEqual([]);
    expect(tl.t1).toBeGreaterThan(tl.t0);
  });
});

describe('event log lines', () => {
  it('describes behavior events, statustext and rejected commands', () => {
    expect(describeEvent(1, 'd', { event: 'finished', behavior: 'land', id: 3, result: { result: 'succeeded' } }).text).toBe('land finished (succeeded)');
    const st = describeEvent(2, 'd', { type: 'statustext', severity: 'warning', text: 'Low battery' });
    expect(st).toMatchObject({ kind: 'statustext', level: 'warn', text: 'Low battery' });
    const rej = describeEvent(3, 'd', { type: 'rejected_command', action: 2, reason: 'no mission loaded' });
    expect(rej).toMatchObject({ level: 'error', text: 'START: no mission loaded' });
    expect(resultText({ result: 'aborted', reason: 'stop' })).toBe('aborted: stop');
    const refused = { kind: 'mission_update', action: 3, mission_id: 2, accepted: false, reason: 'no mission is running' };
    expect(describeEvent(4, 'd', refused)).toMatchObject({ level: 'error', text: 'PAUSE mission #2 refused: no mission is running' });
    expect(describeEvent(5, 'd', { kind: 'alert', message: 'link lost' })).toMatchObject({ kind: 'alert', level: 'error', text: 'link lost' });
    expect(describeEvent(6, 'd', { kind: 'autopilot', text: 'Takeoff detected' })).toMatchObject({ kind: 'autopilot', level: 'info' });
    expect(describeEvent(7, null, { kind: 'lagged', missed: 12 })).toMatchObject({ level: 'warn', text: 'page too slow: 12 event(s) missed' });
  });

  it('accepted mission updates become timeline markers', () => {
    expect(updateMarker(7, 'd', { kind: 'mission_update', action: 1, accepted: true })).toEqual({ t: 7, drone: 'd', label: 'LOAD' });
    expect(updateMarker(7, 'd', { kind: 'mission_update', action: 2, accepted: false })).toBeNull();
    expect(updateMarker(7, 'd', { kind: 'behavior', event: 'started' })).toBeNull();
  });
});

describe('helpers', () => {
  it('cuts a trail into runs sharing their joints', () => {
    const runs = trailRuns([
      { behavior: 'a', i: 0 },
      { behavior: 'a', i: 1 },
      { behavior: 'b', i: 2 },
    ]);
    expect(runs.map((r) => [r.behavior, r.points.map((p) => p.i)])).toEqual([
      ['a', [0, 1]],
      ['b', [1, 2]],
    ]);
  });
  it('chooses round tick steps', () => {
    expect(tickStep(60)).toBe(10);
    expect(tickStep(7)).toBe(2);
  });
  it('shortcuts ignore typing in fields', () => {
    expect(shortcutFor({ key: ' ' })).toBe('pause');
    expect(shortcutFor({ key: 'H' })).toBe('hold');
    expect(shortcutFor({ key: 'h', targetTag: 'input' })).toBeNull();
    expect(shortcutFor({ key: 'h', ctrlKey: true })).toBeNull();
  });
});
