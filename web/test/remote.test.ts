import { describe, expect, it } from 'vitest';
import { ApiClient, ApiError } from '../src/lib/api';
import { applyRemote, busSummary, joinBanner, newRemoteState, peersHeard, remoteLabel, remoteLink } from '../src/lib/remote';
import type { BusReport, RemoteDrone } from '../src/lib/types';

function remote(id: string, over: Partial<RemoteDrone> = {}): RemoteDrone {
  return {
    id,
    node: 'node_1',
    position_enu_m: [1, 2, 3],
    velocity_enu_mps: [0, 0, 0],
    yaw_rad: 0,
    flying: true,
    link: 'ok',
    battery_pct: 80,
    behavior: 'go_to',
    mission: 'running',
    age_s: 0.1,
    silent: false,
    ...over,
  };
}

const BUS: BusReport = {
  fleet: 'farm-7',
  node: 'node_0',
  state_sent: 10,
  received: 20,
  refused: 2,
  dropped: 0,
  latency_samples: 5,
  latency_p50_ms: 10.14,
  latency_p99_ms: 11,
  joined: true,
  join_required: true,
  refused_joins: 0,
  waiting_for: [],
};

describe('remote drones', () => {
  it('a telemetry frame without `remote` empties the list', () => {
    const s = newRemoteState();
    applyRemote(s, [remote('drone_1')], 0);
    expect([...s.drones.keys()]).toEqual(['drone_1']);
    applyRemote(s, undefined, 100);
    expect(s.drones.size).toBe(0);
  });

  it('is silent when its node says so, counting the page time since', () => {
    const s = newRemoteState();
    applyRemote(s, [remote('drone_1', { silent: true, age_s: 2.2 })], 1000);
    const r = s.drones.get('drone_1')!;
    expect(remoteLink(r, s, 2000, true)).toEqual({ state: 'silent', reason: 'silent 3 s' });
    expect(remoteLabel(r, remoteLink(r, s, 2000, true))).toBe('drone_1 · node_1 · silent 3 s');
  });

  it('is never live when this kestrel stopped reporting or the socket closed', () => {
    const s = newRemoteState();
    applyRemote(s, [remote('drone_1')], 0);
    const r = s.drones.get('drone_1')!;
    expect(remoteLink(r, s, 500, true).state).toBe('live');
    expect(remoteLink(r, s, 5000, true).state).toBe('silent');
    expect(remoteLink(r, s, 500, false).state).toBe('silent');
  });

  it('labels a live drone whose autopilot is not linked as such', () => {
    const s = newRemoteState();
    applyRemote(s, [remote('drone_1', { link: 'connecting' })], 0);
    const r = s.drones.get('drone_1')!;
    expect(remoteLabel(r, remoteLink(r, s, 0, true))).toBe('drone_1 · node_1 · autopilot connecting');
  });

  it('the bus line counts only peers heard lately', () => {
    const s = newRemoteState();
    expect(busSummary(s)).toBeNull();
    s.bus = BUS;
    applyRemote(s, [remote('a'), remote('b', { node: 'node_2', silent: true }), remote('c')], 0);
    expect(peersHeard(s)).toEqual(['node_1']);
    expect(busSummary(s)).toBe('fleet farm-7 · node node_0 · peers heard 1 (node_1) · latency p50 10.1 ms / p99 11.0 ms · refused 2');
  });

  it('a Kestrel not joined shows a banner naming the peers it waits for, none once joined', () => {
    const s = newRemoteState();
    expect(joinBanner(s)).toBeNull();
    s.bus = BUS;
    expect(joinBanner(s)).toBeNull();
    const waiting = '127.0.0.1:7447 (refused this node: credentials do not match)';
    s.bus = { ...BUS, joined: false, refused_joins: 3, waiting_for: [waiting] };
    expect(joinBanner(s)).toBe(
      `Not joined to fleet farm-7 (node node_0): waiting for ${waiting}. Missions and explorations are refused until it joins: flying now, its drones would be unseen by the others.`,
    );
    expect(busSummary(s)).toMatch(/ · refused 2 · refused joins 3$/);
    s.bus = { ...BUS, joined: false, join_required: false };
    expect(joinBanner(s)).toMatch(/no peer heard yet\. Its drones fly unseen by the rest of the fleet until it joins\.$/);
  });
});

describe('a command naming a remote drone', () => {
  const reason = 'drone_1 is flown by the Kestrel `node_1` of the fleet, not this one: send the command to that Kestrel\'s API';

  it('a MissionUpdate is refused as an answer carrying the reason', async () => {
    const body = { accepted: false, code: 'remote_drone', details: [], reason };
    const client = new ApiClient('', 't', async () => new Response(JSON.stringify(body), { status: 409 }));
    const answer = await client.missionUpdate({ drone_id: 'drone_1', mission_id: null, item_id: null, action: 5, mission: null });
    expect(answer).toMatchObject({ accepted: false, reason });
  });

  it('any other route throws the error with its message and code', async () => {
    const body = { error: { code: 'remote_drone', message: reason } };
    const client = new ApiClient('', 't', async () => new Response(JSON.stringify(body), { status: 409 }));
    const err = await client.postMission({ target: 'drone_1', plan: [] }).catch((e) => e);
    expect(err).toBeInstanceOf(ApiError);
    expect(err.body.code).toBe('remote_drone');
    expect(err.message).toContain('flown by the Kestrel `node_1`');
  });
});
