// Behavior-activation timeline (the thesis's figures 5.4 and 5.12): one bar per activation, rows
// per drone and behavior, mission commands (LOAD, START ...) as markers. Built from behavior
// records, live or from a flight log.

import type { BehaviorRecord, Marker } from './events';

export interface Segment {
  drone: string;
  behavior: string;
  start: number;
  /** null while it still runs */
  end: number | null;
  /** how it ended: succeeded, failed: ..., aborted: ..., paused */
  result: string | null;
}

export interface Timeline {
  segments: Segment[];
  markers: Marker[];
  drones: string[];
  /** (drone, behavior) rows in order of first activation */
  rows: { drone: string; behavior: string }[];
  t0: number;
  t1: number;
}

const ENDS = new Set(['finished', 'succeeded', 'failed', 'aborted', 'cancelled', 'canceled', 'stopped']);

export function buildTimeline(records: BehaviorRecord[], markers: Marker[], now: number | null = null): Timeline {
  const sorted = [...records].sort((a, b) => a.t - b.t);
  const open = new Map<string, Segment>();
  const segments: Segment[] = [];
  const keyOf = (r: BehaviorRecord) => `${r.drone}\u0000${r.id ?? r.behavior}`;
  const close = (key: string, t: number, result: string | null) => {
    const s = open.get(key);
    if (!s) return;
    s.end = t;
    s.result = result;
    open.delete(key);
  };
  const openSegment = (r: BehaviorRecord) => {
    const s: Segment = { drone: r.drone, behavior: r.behavior, start: r.t, end: null, result: null };
    segments.push(s);
    open.set(keyOf(r), s);
  };
  for (const r of sorted) {
    const key = keyOf(r);
    if (r.event === 'started' || r.event === 'resumed') {
      close(key, r.t, r.event === 'started' ? 'replaced' : null);
      openSegment(r);
    } else if (r.event === 'paused') {
      close(key, r.t, 'paused');
    } else if (ENDS.has(r.event)) {
      close(key, r.t, r.result ?? r.event);
    }
  }
  const times = [...segments.flatMap((s) => [s.start, s.end ?? s.start]), ...markers.map((m) => m.t)];
  if (now !== null) times.push(now);
  const t0 = times.length ? Math.min(...times) : 0;
  const t1 = times.length ? Math.max(...times) : 1;
  const drones = [...new Set([...segments.map((s) => s.drone), ...markers.map((m) => m.drone)])].sort();
  const rows: Timeline['rows'] = [];
  const seen = new Set<string>();
  for (const s of [...segments].sort((a, b) => a.drone.localeCompare(b.drone) || a.start - b.start)) {
    const k = `${s.drone}\u0000${s.behavior}`;
    if (!seen.has(k)) {
      seen.add(k);
      rows.push({ drone: s.drone, behavior: s.behavior });
    }
  }
  return { segments, markers: [...markers].sort((a, b) => a.t - b.t), drones, rows, t0, t1: Math.max(t1, t0 + 1) };
}

/** Seconds per tick for an axis spanning `span` seconds with about `ticks` labels. */
export function tickStep(span: number, ticks = 6): number {
  const raw = span / ticks;
  const mag = 10 ** Math.floor(Math.log10(raw));
  for (const m of [1, 2, 5, 10]) if (m * mag >= raw) return m * mag;
  return 10 * mag;
}
