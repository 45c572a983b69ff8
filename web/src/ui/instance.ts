// One Kestrel instance the page talks to: its HTTP client, its WebSocket (reconnecting), the
// reduced state of its drones, and the drones other Kestrels of its fleet bus fly (polled with
// its bus report every 2 s, and carried by each telemetry frame).

import { ApiClient, ApiError, wsUrl } from '../lib/api';
import { applyMessage, applyStatus, newInstanceState, type InstanceState } from '../lib/fleet';
import { readGeofence, type Geofence } from '../lib/geo';
import { applyRemote, newRemoteState, type RemoteState } from '../lib/remote';
import type { BehaviorInfo, FrameInfo, ServerMessage } from '../lib/types';

/** How often the status (remote drones and the fleet bus report) is polled (ms). */
const STATUS_POLL_MS = 2000;

export type InstanceListener = (inst: Instance, msg: ServerMessage | null) => void;

export class Instance {
  readonly client: ApiClient;
  readonly state: InstanceState = newInstanceState();
  /** Drones other Kestrels fly, heard over this one's fleet bus, and the bus report. */
  readonly remote: RemoteState = newRemoteState();
  behaviors: BehaviorInfo[] = [];
  frames: FrameInfo[] = [];
  geofence: Geofence | null = null;
  socketOpen = false;
  /** Why the last connection attempt failed (shown in the header), null when connected. */
  problem: string | null = 'connecting';
  private ws: WebSocket | null = null;
  private retryMs = 1000;
  private closed = false;
  private statusTimer: ReturnType<typeof setInterval> | null = null;

  constructor(
    readonly id: number,
    readonly label: string,
    base: string,
    token: string,
    private readonly listener: InstanceListener,
  ) {
    this.client = new ApiClient(base, token);
  }

  /** Checks the token and loads what the page needs once; throws ApiError (401 included). */
  async start(): Promise<void> {
    const status = await this.client.statusAll();
    applyStatus(this.state, status.drones, Date.now());
    this.applyFleet(status.remote, status.fleet_bus);
    this.problem = null;
    this.behaviors = await this.client.behaviors().catch(() => []);
    this.geofence = readGeofence(await this.client.geofence().catch(() => null));
    await this.refreshFrames();
    this.connect();
    this.statusTimer = setInterval(() => void this.pollStatus(), STATUS_POLL_MS);
    this.listener(this, null);
  }

  private applyFleet(remote: Parameters<typeof applyRemote>[1], bus: RemoteState['bus'] | undefined): void {
    applyRemote(this.remote, remote, Date.now());
    this.remote.bus = bus ?? null;
  }

  /** The fleet bus report (and the remote drones) from `GET /api/status`; kept when it fails. */
  private async pollStatus(): Promise<void> {
    try {
      const status = await this.client.statusAll();
      this.applyFleet(status.remote, status.fleet_bus);
    } catch {
      // The WebSocket's close handler says why the server is not answering.
    }
  }

  async refreshFrames(): Promise<void> {
    this.frames = await this.client.frames().catch(() => this.frames);
  }

  private connect(): void {
    if (this.closed) return;
    const ws = new WebSocket(wsUrl(this.client.base, this.client.getToken(), location.href));
    this.ws = ws;
    ws.onopen = () => {
      this.socketOpen = true;
      this.problem = null;
      this.retryMs = 1000;
      ws.send(JSON.stringify({ type: 'subscribe', telemetry_rate_hz: 10 }));
      this.listener(this, null);
    };
    ws.onmessage = (ev) => {
      let msg: ServerMessage;
      try {
        msg = JSON.parse(String(ev.data)) as ServerMessage;
      } catch {
        return;
      }
      applyMessage(this.state, msg, Date.now());
      if (msg.type === 'telemetry') applyRemote(this.remote, msg.remote, Date.now());
      this.listener(this, msg);
    };
    ws.onclose = () => {
      this.socketOpen = false;
      this.ws = null;
      this.problem = 'WebSocket closed; finding out why';
      this.listener(this, null);
      if (this.closed) return;
      // A browser does not tell why a WebSocket failed: an HTTP request to the same server does.
      void this.whyClosed().then((why) => {
        this.problem = `${why}; retrying`;
        this.listener(this, null);
        setTimeout(() => this.connect(), this.retryMs);
        this.retryMs = Math.min(this.retryMs * 2, 5000);
      });
    };
  }

  /** Why the WebSocket is not open, from a status request: token refused, server unreachable, ... */
  private async whyClosed(): Promise<string> {
    try {
      await this.client.status();
      return 'WebSocket closed (the server answers HTTP)';
    } catch (e) {
      return disconnectReason(e);
    }
  }

  behaviorNames(): Set<string> {
    return new Set(this.behaviors.map((b) => b.name));
  }

  close(): void {
    this.closed = true;
    if (this.statusTimer !== null) clearInterval(this.statusTimer);
    this.ws?.close();
  }
}

/** The operator's words for a failed request: a refused token, an unreachable server, ... */
export function disconnectReason(e: unknown): string {
  if (e instanceof ApiError && e.status === 401) return 'token refused (401): reload and enter the right token';
  if (e instanceof ApiError && e.status === 0) return 'kestrel unreachable (not running, or the network is down)';
  return `kestrel error: ${describeError(e)}`;
}

export function describeError(e: unknown): string {
  if (e instanceof ApiError) {
    const details = e.body.details.map((d) => `${d.pointer}: ${d.message}`).join('; ');
    return `${e.body.message}${details ? ` (${details})` : ''} [${e.body.code}]`;
  }
  return String(e);
}
