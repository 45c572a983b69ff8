import { describe, expect, it } from 'vitest';
import { attachmentName } from '../src/lib/api';
import { defaultChoice, duration, exploringDrones, progressText, runningText, stopNeedsConfirm } from '../src/lib/exploration';
import type { ExplorationProgress } from '../src/lib/types';

const progress = (over: Partial<ExplorationProgress> = {}): ExplorationProgress => ({
  started_at_s: 10,
  elapsed_s: 125,
  finished: false,
  area_rate_pct_per_min: 1.5,
  remaining_s: 3725,
  drones: [
    { drone: 'drone_0', mission_id: 1, phase: 'navigating', goal_enu_m: [1, 2], path_m: 3 },
    { drone: 'drone_1', mission_id: 2, phase: 'stopped', goal_enu_m: null, path_m: 1 },
  ],
  ...over,
});

describe('exploration panel', () => {
  it('ticks the selected drone only, and none when nothing is selected', () => {
    expect([...defaultChoice('drone_1', ['drone_0', 'drone_1'])]).toEqual(['drone_1']);
    expect(defaultChoice(null, ['drone_0', 'drone_1']).size).toBe(0);
    expect(defaultChoice('gone', ['drone_0']).size).toBe(0);
  });

  it('names the drones the server has exploring', () => {
    expect(runningText([])).toBe('no drone is exploring');
    expect(runningText(['drone_2'])).toBe('1 drone exploring: drone_2');
    expect(runningText(['drone_0', 'drone_1', 'drone_2'])).toBe('3 drones exploring: drone_0, drone_1, drone_2');
  });

  it('asks before stopping several drones, not one', () => {
    expect(stopNeedsConfirm(['drone_0'])).toBe(false);
    expect(stopNeedsConfirm(['drone_0', 'drone_1'])).toBe(true);
  });

  it('writes durations and the estimate as an upper bound', () => {
    expect(duration(12.4)).toBe('12 s');
    expect(duration(245)).toBe('4 min 05 s');
    expect(duration(3725)).toBe('1 h 02 min');
    expect(duration(null)).toBe('—');
    expect(progressText(progress())).toEqual({ elapsed: '2 min 05 s', remaining: '≤ 1 h 02 min', state: 'exploring · 1.50 %/min' });
    expect(progressText(progress({ remaining_s: null, area_rate_pct_per_min: null })).remaining).toBe('estimating…');
    expect(progressText(progress({ finished: true, remaining_s: 0 })).remaining).toBe('0 s');
    expect(progressText(null).state).toBe('no exploration started');
  });

  it('knows which drones still explore', () => {
    expect(exploringDrones(progress())).toEqual(['drone_0']);
    expect(exploringDrones(null)).toEqual([]);
  });

  it('reads the report file name from Content-Disposition', () => {
    expect(attachmentName('attachment; filename="kestrel-exploration-15.json"')).toBe('kestrel-exploration-15.json');
    expect(attachmentName(null)).toBeNull();
  });
});
