// HTTP client for one Kestrel instance. No DOM: `fetch` is injected so tests can fake it.

import type {
  ApiErrorBody,
  BehaviorInfo,
  CoverageAnswer,
  CoverageRequest,
  DroneStatus,
  ExplorationStarted,
  ExplorationView,
  FrameInfo,
  LogEntry,
  Mission,
  MissionUpdate,
  MissionUpdateAnswer,
  StatusAnswer,
} from './types';

export type FetchFn = (input: string, init?: RequestInit) => Promise<Response>;

/** A failed call: HTTP status (0 when the server could not be reached) and the API's error. */
export class ApiError extends Error {
  constructor(
    readonly status: number,
    readonly body: ApiErrorBody,
  ) {
    super(body.message);
  }
}

/** Reads the API's `{"error": {...}}` body, or makes one from whatever came back. */
export function parseErrorBody(status: number, text: string): ApiErrorBody {
  try {
    const json = JSON.parse(text) as { error?: Partial<ApiErrorBody>; reason?: string };
    if (json.error && typeof json.error === 'object') {
      return {
        code: json.error.code ?? `http_${status}`,
        message: json.error.message ?? `HTTP ${status}`,
        details: Array.isArray(json.error.details) ? json.error.details : [],
      };
    }
    if (typeof json.reason === 'string') {
      return { code: `http_${status}`, message: json.reason, details: [] };
    }
  } catch {
    // Not JSON: fall through to the raw text.
  }
  const message = text.trim() || (status === 401 ? 'wrong or missing token' : `HTTP ${status}`);
  return { code: status === 401 ? 'unauthorized' : `http_${status}`, message, details: [] };
}

/** The file name of a `Content-Disposition: attachment; filename="..."` header. */
export function attachmentName(header: string | null): string | null {
  const m = /filename="?([^";]+)"?/i.exec(header ?? '');
  return m ? m[1] : null;
}

/** `http://host:port` (or '' for the page's own origin) to its WebSocket URL with the token. */
export function wsUrl(base: string, token: string, pageHref: string): string {
  const url = new URL(`${base.replace(/\/$/, '')}/api/ws`, pageHref);
  url.protocol = url.protocol === 'https:' ? 'wss:' : 'ws:';
  url.searchParams.set('token', token);
  return url.toString();
}

export class ApiClient {
  constructor(
    readonly base: string,
    private token: string,
    private readonly fetchFn: FetchFn = (i, r) => fetch(i, r),
  ) {}

  setToken(token: string): void {
    this.token = token;
  }

  getToken(): string {
    return this.token;
  }

  private async request(method: string, path: string, body?: unknown): Promise<Response> {
    const headers: Record<string, string> = { Authorization: `Bearer ${this.token}` };
    if (body !== undefined) headers['Content-Type'] = 'application/json';
    let res: Response;
    try {
      res = await this.fetchFn(`${this.base.replace(/\/$/, '')}${path}`, {
        method,
        headers,
        body: body === undefined ? undefined : JSON.stringify(body),
      });
    } catch (e) {
      throw new ApiError(0, {
        code: 'unreachable',
        message: `cannot reach ${this.base || 'the server'}: ${String(e)}`,
        details: [],
      });
    }
    return res;
  }

  private async json<T>(method: string, path: string, body?: unknown): Promise<T> {
    const res = await this.request(method, path, body);
    const text = await res.text();
    if (!res.ok) throw new ApiError(res.status, parseErrorBody(res.status, text));
    return (text ? JSON.parse(text) : null) as T;
  }

  async status(): Promise<DroneStatus[]> {
    return (await this.statusAll()).drones;
  }

  /** The whole status: this Kestrel's drones, and on a fleet bus the remote drones and the bus. */
  statusAll(): Promise<StatusAnswer> {
    return this.json('GET', '/api/status');
  }

  behaviors(): Promise<BehaviorInfo[]> {
    return this.json('GET', '/api/behaviors');
  }

  /** The geofence (the config's `[geofence]`); older servers answer 404. */
  geofence(): Promise<unknown> {
    return this.json('GET', '/api/geofence');
  }

  frames(): Promise<FrameInfo[]> {
    return this.json('GET', '/api/frames');
  }

  /** Validates and loads a mission on its target; a `422` carries the errors with JSON pointers. */
  postMission(mission: Mission): Promise<{ mission_id: number; warnings: string[] }> {
    return this.json('POST', '/api/missions', mission);
  }

  /** A drone's loaded mission with its progress; `plan` is the mission as written. */
  mission(id: number, drone: string): Promise<{ mission_id: number; plan?: Mission | Mission['plan'] }> {
    return this.json('GET', `/api/missions/${id}?drone=${encodeURIComponent(drone)}`);
  }

  /** The executor's answer; a refusal (HTTP 409) is an answer too, not an exception. */
  async missionUpdate(update: MissionUpdate): Promise<MissionUpdateAnswer> {
    const res = await this.request('POST', '/api/mission_update', update);
    const text = await res.text();
    if (res.ok || res.status === 409) {
      try {
        const answer = JSON.parse(text) as MissionUpdateAnswer;
        if (typeof answer.accepted === 'boolean') return answer;
      } catch {
        // Fall through to the error body.
      }
    }
    throw new ApiError(res.status, parseErrorBody(res.status, text));
  }

  coverage(req: CoverageRequest): Promise<CoverageAnswer> {
    return this.json('POST', '/api/coverage', req);
  }

  /** Occupancy grid of one drone, or the merged map when `drone` is absent. */
  map(drone?: string): Promise<{ spec: Record<string, unknown>; data: number[] }> {
    return this.json('GET', `/api/map${drone ? `?drone=${encodeURIComponent(drone)}` : ''}`);
  }

  /** Frontiers, goals, known share and the progress of the exploration run. */
  exploration(): Promise<ExplorationView> {
    return this.json('GET', '/api/exploration');
  }

  /** Starts the explore behavior on `drones` (all or none); a `422` points at `/drones/i` or `/args/..`. */
  startExploration(drones: string[], args: Record<string, unknown>): Promise<ExplorationStarted> {
    return this.json('POST', '/api/exploration/start', { drones, args });
  }

  stopExploration(drones: string[]): Promise<{ stopped: string[] }> {
    return this.json('POST', '/api/exploration/stop', { drones });
  }

  /** The exploration report (an attachment): its file name and JSON text. */
  async explorationReport(): Promise<{ filename: string; text: string }> {
    const res = await this.request('GET', '/api/exploration/report');
    const text = await res.text();
    if (!res.ok) throw new ApiError(res.status, parseErrorBody(res.status, text));
    return { filename: attachmentName(res.headers.get('Content-Disposition')) ?? 'kestrel-exploration.json', text };
  }

  /** The flight log (JSON lines) of the current or last flight. */
  async log(drone?: string): Promise<string> {
    const res = await this.request('GET', `/api/log${drone ? `?drone=${encodeURIComponent(drone)}` : ''}`);
    const text = await res.text();
    if (!res.ok) throw new ApiError(res.status, parseErrorBody(res.status, text));
    return text;
  }

  /** The flight logs beside the current one, newest first. */
  logs(): Promise<LogEntry[]> {
    return this.json('GET', '/api/logs');
  }

  /** The flight report of a listed log: one self-contained HTML page. */
  async logReport(name: string): Promise<string> {
    const res = await this.request('GET', `/api/logs/${encodeURIComponent(name)}/report`);
    const text = await res.text();
    if (!res.ok) throw new ApiError(res.status, parseErrorBody(res.status, text));
    return text;
  }

  /** A listed flight log, whole (JSON lines), and the file name the server gives it. */
  async logFile(name: string): Promise<{ filename: string; blob: Blob }> {
    const res = await this.request('GET', `/api/logs/${encodeURIComponent(name)}`);
    if (!res.ok) throw new ApiError(res.status, parseErrorBody(res.status, await res.text()));
    return { filename: attachmentName(res.headers.get('Content-Disposition')) ?? name, blob: await res.blob() };
  }

  /** Registers (or moves) a frame, e.g. a panel from an alert, relative to `earth`. */
  postFrame(frame: { frame_id: string; parent: string; translation_m: [number, number, number]; yaw_rad: number }): Promise<{ frame_id: string }> {
    return this.json('POST', '/api/frames', frame);
  }
}
