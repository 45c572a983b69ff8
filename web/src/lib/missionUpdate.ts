// MissionUpdate messages for the control buttons, hold/land, and the on-demand inspection task.

import { item, takeoffItem } from './mission';
import { ACTIONS, type ActionName, type Mission, type MissionItem, type MissionUpdate } from './types';

/**
 * Actions that need an item index, and those that carry a mission (or one item as a mission).
 * INSERT's index is the item it goes after (-1: at the start; absent: at the end).
 */
export const NEEDS_ITEM: ReadonlySet<ActionName> = new Set(['JUMP_TO', 'MODIFY', 'REMOVE']);
const TAKES_ITEM: ReadonlySet<ActionName> = new Set([...NEEDS_ITEM, 'INSERT']);
export const NEEDS_MISSION: ReadonlySet<ActionName> = new Set(['EXECUTE', 'LOAD', 'INSERT', 'MODIFY']);

/** Control buttons in the order the panel shows them. */
export const CONTROL_ACTIONS: ActionName[] = [
  'LOAD',
  'START',
  'PAUSE',
  'RESUME',
  'STOP',
  'NEXT_ITEM',
  'JUMP_TO',
  'INSERT',
  'MODIFY',
  'REMOVE',
  'RESET',
];

export interface UpdateArgs {
  missionId?: number | null;
  itemId?: number | null;
  mission?: Mission | null;
  /** For INSERT and MODIFY: the single item, sent as a one-item mission. */
  item?: MissionItem | null;
}

/** Builds a MissionUpdate, or says which input the action is missing. */
export function buildUpdate(
  action: ActionName,
  drone: string,
  args: UpdateArgs = {},
): { update: MissionUpdate } | { error: string } {
  const itemId = args.itemId ?? null;
  if (NEEDS_ITEM.has(action) && (itemId === null || !Number.isInteger(itemId) || itemId < 0)) {
    return { error: `${action} needs an item index (0, 1, ...)` };
  }
  if (action === 'INSERT' && itemId !== null && (!Number.isInteger(itemId) || itemId < -1)) {
    return { error: 'INSERT goes after item N (-1: at the start, empty: at the end)' };
  }
  let mission: Mission | null = null;
  if (action === 'INSERT' || action === 'MODIFY') {
    if (!args.item) return { error: `${action} needs an item: select one in the plan editor` };
    mission = { target: drone, plan: [args.item] };
  } else if (NEEDS_MISSION.has(action)) {
    if (!args.mission && args.missionId == null) return { error: `${action} needs a mission` };
    mission = args.mission ? { ...args.mission, target: drone } : null;
  }
  return {
    update: {
      drone_id: drone,
      mission_id: args.missionId ?? null,
      item_id: TAKES_ITEM.has(action) ? itemId : null,
      action: ACTIONS[action],
      mission,
    },
  };
}

/** Hold: pause whatever mission runs; the drone hovers where it is. */
export function holdUpdate(drone: string, missionId: number | null): MissionUpdate {
  return { drone_id: drone, mission_id: missionId, item_id: null, action: ACTIONS.PAUSE, mission: null };
}

/** Land now: execute (replace and start) a one-item `land` mission. */
export function landUpdate(drone: string, speed_mps = 0.5): MissionUpdate {
  return {
    drone_id: drone,
    mission_id: null,
    item_id: null,
    action: ACTIONS.EXECUTE,
    mission: { target: drone, plan: [item('land', { speed: speed_mps })] },
  };
}

export interface InspectOptions {
  frameId: string;
  approachHeight_m: number;
  inspectHeight_m: number;
  speed_mps: number;
  /** Whether the drone is on the ground (a takeoff is added first). */
  landed: boolean;
  /** Behaviors the instance offers; gimbal and photo items are added only when offered. */
  available: ReadonlySet<string>;
}

/**
 * On-demand inspection of a registered frame (a panel): approach above it, descend, point the
 * gimbal at it, take a photo. Built relative to the frame, as the thesis's Code Snippet 5.3.
 */
export function inspectMission(drone: string, o: InspectOptions): Mission {
  const plan: MissionItem[] = [];
  if (o.landed) plan.push(takeoffItem(o.approachHeight_m, o.speed_mps));
  const above = (z: number) =>
    item('go_to', { x: 0, y: 0, z, speed: o.speed_mps, frame_id: o.frameId });
  plan.push(above(o.approachHeight_m), above(o.inspectHeight_m));
  if (o.available.has('point_gimbal')) {
    plan.push(item('point_gimbal', { x: 0, y: 0, z: 0, frame_id: o.frameId }));
  }
  if (o.available.has('take_photo')) plan.push(item('take_photo', {}));
  plan.push(above(o.approachHeight_m));
  return { target: drone, plan };
}
