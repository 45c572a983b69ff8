// Events from the WebSocket and records from a flight log, read into one shape: behavior records
// (for the timeline) and log lines (for the event log).

import { ACTIONS } from './types';

export interface BehaviorRecord {
  t: number;
  drone: string;
  /** started, paused, resumed, modified, finished */
  event: string;
  behavior: string;
  id: number | null;
  /** succeeded / failed / aborted, with the reason when there is one. */
  result: string | null;
}

export type Level = 'info' | 'warn' | 'error';

export interface LogLine {
  t: number | null;
  drone: string | null;
  kind: string;
  level: Level;
  text: string;
}

type Obj = Record<string, unknown>;
const str = (v: unknown): string | null => (typeof v === 'string' ? v : null);

/** `{"result":"failed","reason":"x"}` (Kestrel's tagged form) or a plain string, as text. */
export function resultText(v: unknown): string | null {
  if (typeof v === 'string') return v;
  if (v && typeof v === 'object') {
    const o = v as Obj;
    const r = str(o.result) ?? str(o.status);
    if (r) return o.reason ? `${r}: ${String(o.reason)}` : r;
  }
  return null;
}

/** A behavior event (from the WebSocket's `event` or a log's `behavior` record), else null. */
export function behaviorRecord(t: number, drone: string | null, e: Obj): BehaviorRecord | null {
  const event = str(e.event);
  const behavior = str(e.behavior);
  if (!event || !behavior || !drone) return null;
  return {
    t,
    drone,
    event,
    behavior,
    id: typeof e.id === 'number' ? e.id : null,
    result: resultText(e.result),
  };
}

const ACTION_NAMES = Object.fromEntries(Object.entries(ACTIONS).map(([k, v]) => [v, k]));

/** A MissionUpdate action as its name, from a number or a string. */
export function actionName(v: unknown): string | null {
  if (typeof v === 'number') return ACTION_NAMES[v] ?? `action ${v}`;
  if (typeof v === 'string') return v.toUpperCase();
  return null;
}

const SEVERITY_LEVEL: Record<string, Level> = {
  emergency: 'error',
  alert: 'error',
  critical: 'error',
  error: 'error',
  warning: 'warn',
  notice: 'info',
  info: 'info',
  debug: 'info',
};

function levelOf(e: Obj, kind: string): Level {
  const sev = str(e.severity)?.toLowerCase();
  if (typeof e.severity === 'number') return e.severity <= 3 ? 'error' : e.severity === 4 ? 'warn' : 'info';
  if (sev && SEVERITY_LEVEL[sev]) return SEVERITY_LEVEL[sev];
  if (str(e.level) === 'error' || str(e.level) === 'warn') return str(e.level) as Level;
  if (/reject|error|collision|alert|fail|lost|crash/.test(kind)) return 'error';
  return 'info';
}

/** One line of the event log for any event the server sends. */
export function describeEvent(t: number | null, drone: string | null, e: Obj): LogLine {
  const b = behaviorRecord(t ?? 0, drone, e);
  if (b) {
    const failed = b.result && !b.result.startsWith('succeeded');
    return {
      t,
      drone,
      kind: 'behavior',
      level: failed ? 'warn' : 'info',
      text: `${b.behavior} ${b.event}${b.result ? ` (${b.result})` : ''}`,
    };
  }
  const kind = str(e.type) ?? str(e.kind) ?? 'event';
  if (kind === 'lagged') {
    return { t, drone, kind, level: 'warn', text: `page too slow: ${String(e.missed ?? '?')} event(s) missed` };
  }
  const said = str(e.text) ?? str(e.message) ?? str(e.reason);
  const action = e.action !== undefined ? actionName(e.action) : null;
  if (action && typeof e.accepted === 'boolean') {
    const mission = typeof e.mission_id === 'number' ? ` mission #${e.mission_id}` : '';
    const text = `${action}${mission} ${e.accepted ? 'accepted' : 'refused'}${said ? `: ${said}` : ''}`;
    return { t, drone, kind, level: e.accepted ? 'info' : 'error', text };
  }
  const text = action ? `${action}${said ? `: ${said}` : ''}` : (said ?? JSON.stringify(e));
  return { t, drone, kind, level: levelOf(e, kind), text };
}

/** An accepted MissionUpdate event (`kind: mission_update`) as a timeline marker, else null. */
export function updateMarker(t: number, drone: string | null, e: Obj): Marker | null {
  if (e.kind !== 'mission_update' || e.accepted !== true || !drone) return null;
  const label = actionName(e.action);
  return label ? { t, drone, label } : null;
}

export interface Marker {
  t: number;
  drone: string;
  label: string;
}

export interface ParsedLog {
  behaviors: BehaviorRecord[];
  markers: Marker[];
  poses: Map<string, { t: number; x: number; y: number; z: number; behavior: string | null }[]>;
  lines: LogLine[];
  badLines: number;
}

/** Reads a flight log (JSON lines): behavior records, mission commands as markers, poses. */
export function parseFlightLog(text: string): ParsedLog {
  const out: ParsedLog = { behaviors: [], markers: [], poses: new Map(), lines: [], badLines: 0 };
  for (const line of text.split('\n')) {
    if (!line.trim()) continue;
    let r: Obj;
    try {
      r = JSON.parse(line) as Obj;
    } catch {
      out.badLines++;
      continue;
    }
    const t = typeof r.t === 'number' ? r.t : 0;
    const drone = str(r.drone) ?? 'drone';
    switch (r.type) {
      case 'pose': {
        const list = out.poses.get(drone) ?? [];
        out.poses.set(drone, list);
        list.push({ t, x: Number(r.x), y: Number(r.y), z: Number(r.z), behavior: str(r.behavior) });
        break;
      }
      case 'behavior': {
        const b = behaviorRecord(t, drone, r);
        if (b) out.behaviors.push(b);
        out.lines.push(describeEvent(t, drone, r));
        break;
      }
      case 'command': {
        const fields = (r.fields ?? {}) as Obj;
        const action = actionName(fields.action);
        const label = action ?? str(r.command) ?? 'command';
        if (action) out.markers.push({ t, drone, label });
        out.lines.push({ t, drone, kind: 'command', level: 'info', text: `${str(r.command) ?? ''} ${action ?? ''}`.trim() });
        break;
      }
      case 'map':
      case 'frontiers':
        // Map cells and frontiers (drawn by Foxglove from an MCAP log): no line to list.
        break;
      default:
        out.lines.push(describeEvent(t, drone, r));
    }
  }
  return out;
}
