// One Kestrel instance the page talks to: its HTTP client, its WebSocket (reconnecting), and the
// reduced state of its drones.

import { ApiClient, ApiError, wsUrl } from '../lib/api';
import { applyMessage, applyStatus, newInstanceState, type InstanceState } from '../lib/fleet';
import { readGeofence, type Geofence } from '../lib/geo';
import type { BehaviorInfo, FrameInfo, ServerMessage } from '../lib/types';

export type InstanceListener = (inst: Instance, msg: ServerMessage | null) => void;

export class Instance {
  readonly client: ApiClient;
  readonly state: InstanceState = newInstanceState();
  behaviors: BehaviorInfo[] = [];
  frames: FrameInfo[] = [];
  geofence: Geofence | null = null;
  socketOpen = false;
  /** Why the last connection attempt failed (shown in the header), null when connected. */
  problem: string | null = 'connecting';
  private ws: WebSocket | null = null;
  private retryMs = 1000;
  private closed = false;

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
    const drones = await this.client.status();
    applyStatus(this.state, drones, Date.now());
    this.problem = null;
    this.behaviors = await this.client.behaviors().catch(() => []);
    this.geofence = readGeofence(await this.client.geofence().catch(() => null));
    await this.refreshFrames();
    this.connect();
    this.listener(this, null);
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
