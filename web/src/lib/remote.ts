// Remote drones: the drones other Kestrels of the fleet fly, as one Kestrel hears them over its
// fleet bus (`remote` of the telemetry frame and of GET /api/status), and that bus's report.
// In: those lists and the page clock. Out: what the operator must see — live or silent (and for
// how long), which node flies it, and the one-line bus summary. No DOM.

import { STALE_AFTER_MS } from './fleet';
import type { BusReport, RemoteDrone } from './types';

export interface RemoteState {
  /** By drone id, as last heard by this Kestrel. */
  drones: Map<string, RemoteDrone>;
  /** Page clock (ms) of the last list this Kestrel sent (null: none yet). */
  lastSeenMs: number | null;
  bus: BusReport | null;
}

export function newRemoteState(): RemoteState {
  return { drones: new Map(), lastSeenMs: null, bus: null };
}

/**
 * Replaces the remote drones with a list the server sent (`undefined`: the field was absent,
 * which the telemetry frame means as "none").
 */
export function applyRemote(state: RemoteState, list: RemoteDrone[] | undefined, nowMs: number): void {
  state.drones = new Map((list ?? []).map((r) => [r.id, r]));
  state.lastSeenMs = nowMs;
}

export type RemoteLink = { state: 'live' | 'silent'; reason: string };

/**
 * Live only when its node was heard lately AND this Kestrel's own reports are fresh: a page that
 * stopped hearing this Kestrel cannot vouch for the drones it relays.
 */
export function remoteLink(
  r: RemoteDrone,
  state: RemoteState,
  nowMs: number,
  socketOpen: boolean,
  staleAfterMs = STALE_AFTER_MS,
): RemoteLink {
  const pageAgeS = state.lastSeenMs === null ? 0 : Math.max(0, nowMs - state.lastSeenMs) / 1000;
  const ageS = r.age_s + pageAgeS;
  if (!socketOpen) return { state: 'silent', reason: `silent ${ageS.toFixed(0)} s (no connection to this kestrel)` };
  if (pageAgeS * 1000 > staleAfterMs) return { state: 'silent', reason: `silent ${ageS.toFixed(0)} s (this kestrel stopped reporting)` };
  if (r.silent) return { state: 'silent', reason: `silent ${ageS.toFixed(0)} s` };
  return { state: 'live', reason: 'live' };
}

/** The map label: `drone_1 · node_1`, then what is wrong with it, if anything. */
export function remoteLabel(r: RemoteDrone, link: RemoteLink): string {
  const parts = [`${r.id} · ${r.node}`];
  if (link.state === 'silent') parts.push(link.reason);
  else if (r.link !== 'ok') parts.push(`autopilot ${r.link}`);
  return parts.join(' · ');
}

/** Why no command is offered for a remote drone (a tooltip). */
export function remoteCommandNote(r: RemoteDrone): string {
  return `flown by ${r.node}: use that Kestrel's ground station`;
}

/** Nodes heard lately (a silent drone's node is not counted), sorted. */
export function peersHeard(state: RemoteState): string[] {
  return [...new Set([...state.drones.values()].filter((r) => !r.silent).map((r) => r.node))].sort();
}

const ms = (v: number | null): string => (v === null ? '—' : `${v.toFixed(1)} ms`);

/** One line for the Fleet panel; null without a bus. */
export function busSummary(state: RemoteState): string | null {
  const b = state.bus;
  if (!b) return null;
  const peers = peersHeard(state);
  const latency = b.latency_samples > 0 ? `latency p50 ${ms(b.latency_p50_ms)} / p99 ${ms(b.latency_p99_ms)}` : 'latency — (no state received yet)';
  return [
    `fleet ${b.fleet}`,
    `node ${b.node}`,
    `peers heard ${peers.length}${peers.length ? ` (${peers.join(', ')})` : ''}`,
    latency,
    `refused ${b.refused}`,
    ...(b.refused_joins > 0 ? [`refused joins ${b.refused_joins}`] : []),
  ].join(' · ');
}

/**
 * The banner shown while this Kestrel has not joined its fleet (null once joined, or without a
 * bus): which peers it waits for and why, and whether it may take off meanwhile.
 */
export function joinBanner(state: RemoteState): string | null {
  const b = state.bus;
  if (!b || b.joined) return null;
  const waiting = b.waiting_for.length ? `waiting for ${b.waiting_for.join(', ')}` : 'no peer heard yet';
  const consequence = b.join_required
    ? 'Missions and explorations are refused until it joins: flying now, its drones would be unseen by the others.'
    : 'Its drones fly unseen by the rest of the fleet until it joins.';
  return `Not joined to fleet ${b.fleet} (node ${b.node}): ${waiting}. ${consequence}`;
}
