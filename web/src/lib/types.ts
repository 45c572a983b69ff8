// JSON shapes of the Kestrel API (docs/API.md). Units are in the field names, ENU world frame.

export type Vec3 = [number, number, number];
export type Vec2 = [number, number];

export type LinkState = 'ok' | 'connecting' | 'lost';
export type FlightState =
  | 'disarmed'
  | 'landed'
  | 'taking_off'
  | 'flying'
  | 'landing'
  | 'crashed';

export interface ActiveBehavior {
  id: number;
  behavior: string;
  state: string;
  goal?: unknown;
  feedback?: Record<string, unknown>;
}

export interface MissionItem {
  behavior: string;
  method?: string;
  args: Record<string, unknown>;
}

export interface Mission {
  target: string;
  plan: MissionItem[];
}

export interface DoneResult {
  item: number;
  behavior: string;
  result: string;
}

/** Mission executor status; `state` 0 idle, 1 running, 2 paused. */
export interface MissionStatus {
  state: number;
  pending_items: number;
  done_items: number;
  current_item: MissionItem | null;
  feedback_current: Record<string, unknown> | null;
  mission_id: number | null;
  item_index: number | null;
  done_results: DoneResult[];
  last_error: string | null;
  /** Stable failure code behind `last_error` (older servers omit it), e.g. `pilot_takeover`. */
  last_error_code?: string | null;
}

export interface DroneStatus {
  drone: string;
  link: LinkState;
  armed: boolean;
  offboard: boolean;
  mode: string;
  flight: FlightState | string;
  ready_to_fly: boolean;
  battery: { voltage_v: number; remaining_fraction: number } | null;
  last_error: string | null;
  /** `null` until the autopilot has given a position, as are yaw, velocity and geo. */
  position_enu_m: Vec3 | null;
  /** False until the autopilot has reported a position (older servers omit it). */
  has_position?: boolean;
  /** Seconds since the autopilot last reported (older servers omit it). */
  age_s?: number | null;
  /** True when the data is older than the link timeout (older servers omit it). */
  stale?: boolean;
  yaw_rad: number | null;
  velocity_enu_mps: Vec3 | null;
  geo: { lat_deg: number; lon_deg: number; alt_m: number } | null;
  active_behaviors: ActiveBehavior[];
  mission?: MissionStatus | null;
  /** The address the autopilot's link is pinned to, `null` before it is heard or on links
   * without one (older servers omit it). */
  autopilot_address?: string | null;
  /** How often the pin moved to another address (older servers omit it). */
  autopilot_address_changes?: number;
}

/** A status with a position the autopilot gave (see `hasPosition`). */
export type PlacedStatus = DroneStatus & { position_enu_m: Vec3; yaw_rad: number };

export interface BehaviorInfo {
  name: string;
  description: string;
  resource: string;
  args_schema: JsonSchema;
  methods: string[];
}

export interface JsonSchema {
  type?: string | string[];
  properties?: Record<string, JsonSchema>;
  required?: string[];
  description?: string;
  default?: unknown;
  enum?: unknown[];
  const?: unknown;
  oneOf?: JsonSchema[];
  anyOf?: JsonSchema[];
  allOf?: JsonSchema[];
  items?: JsonSchema | JsonSchema[];
  minItems?: number;
  maxItems?: number;
  format?: string;
  $ref?: string;
  definitions?: Record<string, JsonSchema>;
  $defs?: Record<string, JsonSchema>;
  title?: string;
  minimum?: number;
  maximum?: number;
  exclusiveMinimum?: number;
  exclusiveMaximum?: number;
}

export interface ErrorDetail {
  pointer: string;
  message: string;
}

export interface ApiErrorBody {
  code: string;
  message: string;
  details: ErrorDetail[];
}

/** MissionUpdate actions, numbered as the thesis's table. */
export const ACTIONS = {
  EXECUTE: 0,
  LOAD: 1,
  START: 2,
  PAUSE: 3,
  RESUME: 4,
  STOP: 5,
  NEXT_ITEM: 6,
  JUMP_TO: 7,
  INSERT: 8,
  MODIFY: 9,
  REMOVE: 10,
  RESET: 11,
} as const;
export type ActionName = keyof typeof ACTIONS;

export interface MissionUpdate {
  drone_id: string;
  mission_id: number | null;
  item_id: number | null;
  action: number;
  mission: Mission | null;
}

export interface MissionUpdateAnswer {
  accepted: boolean;
  status?: MissionStatus;
  reason?: string;
}

export interface FrameInfo {
  frame_id: string;
  parent: string;
  translation_m?: Vec3;
  yaw_rad?: number;
  drone_id?: string | null;
  [key: string]: unknown;
}

export interface CoverageRequest {
  polygon_enu_m: Vec2[];
  street_spacing_m: number;
  angle_deg: number | null;
  drones: string[];
  height_m: number;
}

export interface CoverageAnswer {
  angle_deg: number;
  per_drone: Record<string, Vec3[]>;
  lengths_m: Record<string, number>;
}

/** A drone another Kestrel of the fleet flies, heard over the fleet bus (docs/API.md). */
export interface RemoteDrone {
  id: string;
  /** The Kestrel (bus node) that flies it. */
  node: string;
  /** `null` (all three) until its autopilot has given a position. */
  position_enu_m: Vec3 | null;
  velocity_enu_mps: Vec3 | null;
  yaw_rad: number | null;
  flying: boolean;
  /** Its node's link to its autopilot. */
  link: LinkState | string;
  battery_pct: number | null;
  behavior: string | null;
  mission: string | null;
  /** Seconds since its node was last heard. */
  age_s: number;
  /** Not heard for longer than the bus's `peer_timeout_s`. */
  silent: boolean;
}

/** The fleet bus of this Kestrel, as `GET /api/status` reports it (refreshed once a second). */
export interface BusReport {
  fleet: string;
  node: string;
  state_sent: number;
  received: number;
  refused: number;
  dropped: number;
  latency_samples: number;
  latency_p50_ms: number | null;
  latency_p99_ms: number | null;
  /** Joined its fleet: every peer of `[fleet] connect` answered once (latched). */
  joined: boolean;
  /** Missions and explorations are refused (`409 fleet_not_joined`) until joined. */
  join_required: boolean;
  /** Handshakes refused for their credentials, by a peer or by this Kestrel. */
  refused_joins: number;
  /** The listed peers not joined yet, each with why. */
  waiting_for: string[];
}

/** `GET /api/status`: `remote` and `fleet_bus` only on a fleet bus. */
export interface StatusAnswer {
  t?: number;
  drones: DroneStatus[];
  remote?: RemoteDrone[];
  fleet_bus?: BusReport | null;
}

/** WebSocket messages from the server. */
export type ServerMessage =
  | { type: 'telemetry'; t: number; drones: DroneStatus[]; remote?: RemoteDrone[] }
  | { type: 'mission_status'; drone: string; status: MissionStatus }
  | { type: 'event'; drone: string | null; t: number; event: Record<string, unknown> }
  | {
      type: 'map_update';
      drone: string | null;
      bbox: [number, number, number, number];
      spec: Record<string, unknown>;
      data: number[];
    }
  | { type: 'reply'; request_id: number; accepted: boolean; reason?: string | null };

/** `GET /api/exploration`: frontiers, goals held, known share and the run's progress. */
export interface FrontierView {
  centroid_enu_m: Vec2;
  goal_enu_m: Vec2;
  size_m: number;
  orientation_rad: number;
}

export interface RunDroneView {
  drone: string;
  mission_id: number;
  phase: string;
  goal_enu_m: Vec2 | null;
  path_m: number;
}

export interface ExplorationProgress {
  started_at_s: number;
  elapsed_s: number;
  finished: boolean;
  area_rate_pct_per_min: number | null;
  remaining_s: number | null;
  drones: RunDroneView[];
}

export interface ExplorationView {
  frontiers: FrontierView[];
  goals: { drone: string; goal_enu_m: Vec2 }[];
  known_pct: number | null;
  progress: ExplorationProgress | null;
}

export interface ExplorationStarted {
  started_at_s: number;
  drones: { drone: string; mission_id: number }[];
}

/** One flight log as `GET /api/logs` lists it. */
export interface LogEntry {
  name: string;
  size_bytes: number;
  /** Wall-clock start (RFC 3339, UTC); null for a log named by `--log FILE`. */
  start_time: string | null;
  /** The log this run is writing. */
  current: boolean;
}
