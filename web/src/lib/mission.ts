// Mission building: items from map clicks, paths and coverage answers; the path a mission will
// fly (for the map); the API's validation errors sorted by item and argument.

import { enuToGeo, geoToEnu, type GeoOrigin } from './geo';
import type { CoverageAnswer, ErrorDetail, Mission, MissionItem, Vec2, Vec3 } from './types';

export const CALL = '__call__';

export interface PlanDefaults {
  height_m: number;
  speed_mps: number;
}

export const DEFAULTS: PlanDefaults = { height_m: 3, speed_mps: 1 };

const round = (v: number, digits = 2): number => {
  const k = 10 ** digits;
  return Math.round(v * k) / k;
};

export function item(behavior: string, args: Record<string, unknown>): MissionItem {
  return { behavior, method: CALL, args };
}

export const takeoffItem = (height_m: number, speed_mps: number): MissionItem =>
  item('takeoff', { height: height_m, speed: speed_mps });

export const goToItem = ([x, y, z]: Vec3, speed_mps: number): MissionItem =>
  item('go_to', { x: round(x), y: round(y), z: round(z), speed: speed_mps });

export const followPathItem = (path: Vec3[], speed_mps: number): MissionItem =>
  item('follow_path', {
    path: path.map(([x, y, z]) => [round(x), round(y), round(z)]),
    speed: speed_mps,
  });

export const landItem = (speed_mps: number): MissionItem => item('land', { speed: speed_mps });

export function emptyMission(target: string): Mission {
  return { target, plan: [] };
}

const isLand = (it: MissionItem | undefined): boolean => it?.behavior === 'land' || it?.behavior === 'rtl';

/** Adds an item at the end of the plan, but before a final land/rtl so the plan still ends landed. */
export function appendBeforeLanding(mission: Mission, it: MissionItem): Mission {
  const plan = [...mission.plan];
  if (isLand(plan[plan.length - 1])) plan.splice(plan.length - 1, 0, it);
  else plan.push(it);
  return { ...mission, plan };
}

/** A map click in waypoint mode: a go_to at the clicked point and the planning height. */
export function addWaypoint(mission: Mission, [x, y]: Vec2, d: PlanDefaults = DEFAULTS): Mission {
  return appendBeforeLanding(mission, goToItem([x, y, d.height_m], d.speed_mps));
}

/** A map click in the geographic view: a go_to_gps at the clicked lat/lon, `height_m` above the origin. */
export function addGpsWaypoint(
  mission: Mission,
  [lat_deg, lon_deg]: Vec2,
  originAlt_m: number,
  d: PlanDefaults = DEFAULTS,
): Mission {
  const r7 = (v: number) => Math.round(v * 1e7) / 1e7;
  const it = item('go_to_gps', { lat: r7(lat_deg), lon: r7(lon_deg), alt: round(originAlt_m + d.height_m), speed: d.speed_mps });
  return appendBeforeLanding(mission, it);
}

/** A drawn path: one follow_path item through the clicked points at the planning height. */
export function addPath(mission: Mission, points: Vec2[], d: PlanDefaults = DEFAULTS): Mission {
  if (points.length === 0) return mission;
  const path: Vec3[] = points.map(([x, y]) => [x, y, d.height_m]);
  return appendBeforeLanding(mission, followPathItem(path, d.speed_mps));
}

/** One full mission per drone from a coverage answer: takeoff, reach the first point, sweep, land. */
export function coverageMissions(
  answer: CoverageAnswer,
  d: PlanDefaults = DEFAULTS,
): Record<string, Mission> {
  const out: Record<string, Mission> = {};
  for (const [drone, path] of Object.entries(answer.per_drone)) {
    if (path.length === 0) continue;
    const height = path[0][2] ?? d.height_m;
    out[drone] = {
      target: drone,
      plan: [
        takeoffItem(height, d.speed_mps),
        goToItem(path[0], d.speed_mps),
        followPathItem(path, d.speed_mps),
        landItem(Math.min(d.speed_mps, 0.5)),
      ],
    };
  }
  return out;
}

export function replaceItem(mission: Mission, index: number, it: MissionItem): Mission {
  return { ...mission, plan: mission.plan.map((old, i) => (i === index ? it : old)) };
}

export function removeItem(mission: Mission, index: number): Mission {
  return { ...mission, plan: mission.plan.filter((_, i) => i !== index) };
}

export function moveItem(mission: Mission, index: number, delta: -1 | 1): Mission {
  const j = index + delta;
  if (j < 0 || j >= mission.plan.length) return mission;
  const plan = [...mission.plan];
  [plan[index], plan[j]] = [plan[j], plan[index]];
  return { ...mission, plan };
}

const num = (v: unknown): number | null => (typeof v === 'number' && Number.isFinite(v) ? v : null);

const MOVABLE = new Set(['go_to', 'navigate_to', 'go_to_gps']);

function asPoint(v: unknown): Vec3 | null {
  if (!Array.isArray(v) || v.length < 2) return null;
  const [x, y, z] = v.map(num);
  return x === null || y === null ? null : [x, y, z ?? 0];
}

/**
 * The ENU points the plan visits from `start`, for drawing it, with the index of the item that
 * reaches each point (-1 for the start). go_to_gps targets are drawn when the ENU origin's
 * lat/lon is known. Only earth-frame targets are drawn;
 * items in another frame (a panel, the nacelle) are listed in `framed` for the frames layer.
 * `sub` is each point's index in its item's `path` (follow_path), 0 otherwise; `movable` says
 * whether the point is a target the operator may drag (go_to, navigate_to, go_to_gps and
 * follow_path points, not takeoff, land or rtl).
 */
export function plannedPath(
  mission: Mission,
  start: Vec3 = [0, 0, 0],
  origin: GeoOrigin | null = null,
): { points: Vec3[]; items: number[]; sub: number[]; movable: boolean[]; framed: string[] } {
  let here: Vec3 = start;
  const points: Vec3[] = [start];
  const items: number[] = [-1];
  const sub: number[] = [0];
  const movable: boolean[] = [false];
  const framed: string[] = [];
  for (const [index, it] of mission.plan.entries()) {
    const a = it.args ?? {};
    const frame = typeof a.frame_id === 'string' ? a.frame_id : 'earth';
    if (frame !== 'earth') {
      framed.push(frame);
      continue;
    }
    switch (it.behavior) {
      case 'takeoff': {
        const h = num(a.height) ?? num(a.height_m) ?? num(a.z);
        if (h !== null) here = [here[0], here[1], h];
        break;
      }
      case 'go_to':
      case 'navigate_to': {
        const x = num(a.x);
        const y = num(a.y);
        if (x !== null && y !== null) here = [x, y, num(a.z) ?? here[2]];
        break;
      }
      case 'follow_path': {
        const path = Array.isArray(a.path) ? a.path.map(asPoint) : [];
        for (const [j, p] of path.entries()) {
          if (!p) continue;
          points.push((here = p));
          items.push(index);
          sub.push(j);
          movable.push(true);
        }
        continue;
      }
      case 'go_to_gps': {
        const lat = num(a.lat);
        const lon = num(a.lon);
        if (lat === null || lon === null || !origin) continue;
        const [x, y] = geoToEnu(origin, lat, lon);
        const alt = num(a.alt);
        here = [x, y, alt !== null && origin.alt_m !== undefined ? alt - origin.alt_m : here[2]];
        break;
      }
      case 'land':
        here = [here[0], here[1], 0];
        break;
      case 'rtl':
        here = [start[0], start[1], 0];
        break;
      default:
        continue;
    }
    points.push(here);
    items.push(index);
    sub.push(0);
    movable.push(MOVABLE.has(it.behavior));
  }
  return { points, items, sub, movable, framed };
}

/** Validation errors keyed by item index and argument name, plus those about the whole mission. */
export interface SortedErrors {
  general: string[];
  items: Map<number, { item: string[]; args: Map<string, string[]> }>;
}

export function sortErrors(details: ErrorDetail[]): SortedErrors {
  const out: SortedErrors = { general: [], items: new Map() };
  for (const d of details) {
    const parts = (d.pointer ?? '').split('/').slice(1);
    const index = parts[0] === 'plan' ? Number(parts[1]) : NaN;
    if (!Number.isInteger(index)) {
      out.general.push(d.pointer ? `${d.pointer}: ${d.message}` : d.message);
      continue;
    }
    const entry = out.items.get(index) ?? { item: [], args: new Map<string, string[]>() };
    out.items.set(index, entry);
    const arg = parts[2] === 'args' ? parts[3] : undefined;
    if (arg) entry.args.set(arg, [...(entry.args.get(arg) ?? []), d.message]);
    else entry.item.push(parts.length > 2 ? `${parts.slice(2).join('/')}: ${d.message}` : d.message);
  }
  return out;
}

/** Reads a mission file or the JSON editor's text; says what is wrong when it cannot. */
export function parseMission(text: string, fallbackTarget: string): { mission: Mission } | { error: string } {
  let json: unknown;
  try {
    json = JSON.parse(text);
  } catch (e) {
    return { error: `not JSON: ${(e as Error).message}` };
  }
  const raw = (Array.isArray(json) ? { plan: json } : json) as Partial<Mission> | null;
  if (!raw || typeof raw !== 'object' || !Array.isArray(raw.plan)) {
    return { error: 'a mission is {"target": "...", "plan": [{"behavior", "method", "args"}, ...]}' };
  }
  const plan: MissionItem[] = [];
  for (const [i, it] of raw.plan.entries()) {
    if (!it || typeof it !== 'object' || typeof (it as MissionItem).behavior !== 'string') {
      return { error: `plan[${i}] has no "behavior"` };
    }
    const m = it as MissionItem;
    plan.push({ behavior: m.behavior, method: m.method ?? CALL, args: m.args ?? {} });
  }
  const target = typeof raw.target === 'string' && raw.target ? raw.target : fallbackTarget;
  return { mission: { ...raw, target, plan } as Mission };
}

export function missionToJson(mission: Mission): string {
  return JSON.stringify(mission, null, 2);
}

/**
 * A target dragged on the map to ENU `[x, y]` (metres, rounded to cm): the item's x/y (go_to,
 * navigate_to), its lat/lon (go_to_gps, needs the origin), or point `sub` of its path
 * (follow_path). Height and every other argument are kept; anything else is returned unchanged.
 */
export function moveTarget(mission: Mission, index: number, sub: number, [x, y]: Vec2, origin: GeoOrigin | null): Mission {
  const it = mission.plan[index];
  if (!it) return mission;
  const args = { ...(it.args ?? {}) };
  const cm = (v: number) => Math.round(v * 100) / 100;
  switch (it.behavior) {
    case 'go_to':
    case 'navigate_to':
      args.x = cm(x);
      args.y = cm(y);
      break;
    case 'go_to_gps': {
      if (!origin) return mission;
      const [lat, lon] = enuToGeo(origin, x, y);
      args.lat = Math.round(lat * 1e7) / 1e7;
      args.lon = Math.round(lon * 1e7) / 1e7;
      break;
    }
    case 'follow_path': {
      const path = Array.isArray(args.path) ? [...args.path] : [];
      const old = path[sub];
      if (!Array.isArray(old)) return mission;
      path[sub] = [cm(x), cm(y), ...old.slice(2)];
      args.path = path;
      break;
    }
    default:
      return mission;
  }
  return replaceItem(mission, index, { ...it, args });
}
