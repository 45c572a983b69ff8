// Entry point: asks the token once per session, connects to the kestrel that serves the page, and
// wires the views (fleet, plan, control, explore, monitor, timeline, logs) to the map and to each other.

import './style.css';
import { ApiError } from './lib/api';
import { behaviorColor } from './lib/colors';
import { enuToGeo, originFrom, type GeoOrigin } from './lib/geo';
import { formatLat, formatLon } from './lib/graticule';
import { mergePatch, readGrid, type Grid } from './lib/grid';
import { feedbackPaths, hasPosition } from './lib/fleet';
import { SHORTCUT_HELP, shortcutFor } from './lib/keyboard';
import { plannedPath } from './lib/mission';
import type { Vec2, Vec3 } from './lib/types';
import { AltitudeView } from './ui/altitudeView';
import { App } from './ui/app';
import { ControlView } from './ui/controlView';
import { byId, h, setOptions } from './ui/dom';
import { ExplorationPanel } from './ui/explorationView';
import { act, onRejected, toast } from './ui/feedback';
import { FleetView, restoreInstances } from './ui/fleetView';
import { disconnectReason } from './ui/instance';
import { LogsView } from './ui/logsView';
import { droneColor, MapView, type Tool } from './ui/mapView';
import { MonitorView } from './ui/monitorView';
import { PlanView } from './ui/planView';
import { remoteCommandNote } from './lib/remote';
import { TimelineView } from './ui/timelineView';

const TOKEN_KEY = 'kestrel.token';
const BASEMAP_KEY = 'kestrel.basemap';

const app = new App();
const fleet = new FleetView(app);
const plan = new PlanView(app);
const control = new ControlView(app, plan);
const exploration = new ExplorationPanel(app);
const monitor = new MonitorView(app);
const timeline = new TimelineView(app);
const logs = new LogsView(app);
let mapView: MapView;
const altitude = new AltitudeView(byId('alt-view'));
let grid: Grid | null = null;

onRejected((text) => app.log({ t: null, drone: null, kind: 'rejected', level: 'error', text }));

// ---- token, asked once per session ----------------------------------------------------------

function askToken(error: string | null): Promise<string> {
  const dialog = byId<HTMLDialogElement>('token-dialog');
  const input = byId<HTMLInputElement>('token-input');
  const err = byId('token-error');
  err.hidden = !error;
  err.textContent = error ?? '';
  input.value = '';
  dialog.showModal();
  return new Promise((resolve) => {
    byId('token-form').addEventListener('submit', () => resolve(input.value.trim()), { once: true });
  });
}

async function connect(): Promise<void> {
  let token = sessionStorage.getItem(TOKEN_KEY) ?? '';
  for (;;) {
    try {
      await app.addInstance(location.host || 'local', '', token);
      sessionStorage.setItem(TOKEN_KEY, token);
      return;
    } catch (e) {
      if (e instanceof ApiError && e.status === 401) {
        token = await askToken(token ? 'That token was refused (401).' : null);
        continue;
      }
      byId('conn-status').textContent = `${disconnectReason(e)}; retrying`;
      await new Promise((r) => setTimeout(r, 2000));
    }
  }
}

// ---- map -------------------------------------------------------------------------------------

function geoOrigin(): GeoOrigin | null {
  for (const ref of app.drones()) {
    const s = app.view(ref).status;
    const o = hasPosition(s) && originFrom(s.position_enu_m, s.geo);
    if (o) return o;
  }
  return null;
}

function makeMap(origin: GeoOrigin | null): void {
  const center = mapView?.map.getCenter();
  const centerEnu = center && mapView ? mapView.enu(center) : null;
  mapView?.destroy();
  const el = byId('map');
  el.replaceChildren();
  mapView = new MapView(
    el,
    {
      waypoint: (p) => plan.addWaypoint(p),
      waypointMoved: (item, sub, p) => plan.moveWaypoint(item, sub, p),
      finish: (tool, points) => {
        setTool('pan');
        if (tool === 'path') plan.addPath(points);
        else plan.setPolygon(points);
      },
      drawingChanged: (tool, points) => toolState(tool, points),
      frameClicked: (f) => {
        control.selectFrame(f);
        showTab('control');
      },
      cursor: ([x, y], latLon) => {
        // In the local view too, once a drone has told where the ENU origin is on Earth.
        const o = latLon ? null : geoOrigin();
        const ll = latLon ?? (o ? enuToGeo(o, x, y) : null);
        const geo = ll ? ` · ${formatLat(ll[0], 6)}, ${formatLon(ll[1], 6)}` : '';
        byId('cursor-readout').textContent = `cursor: east ${x.toFixed(1)} m, north ${y.toFixed(1)} m${geo}`;
      },
    },
    origin,
    origin ? localStorage.getItem(BASEMAP_KEY) : null,
  );
  if (centerEnu) mapView.fitTo([centerEnu]);
  setTool('pan');
  byId('btn-geo').textContent = origin ? 'Local ENU view' : 'Geographic view';
  plan.geoOrigin = origin;
  mapView.setGrid(grid);
  drawOverlays();
}

const HINTS: Record<Tool, string> = {
  pan: '',
  waypoint: 'click the map: a go_to per click',
  path: 'click points, then Finish (or double-click)',
  polygon: 'click 3+ vertices, then Finish (or double-click)',
};

function setTool(tool: Tool): void {
  document.querySelectorAll<HTMLElement>('#map-tools .tool').forEach((x) => x.classList.toggle('active', x.dataset.tool === tool));
  mapView.setTool(tool);
}

function toolState(tool: Tool, points: Vec2[]): void {
  byId<HTMLButtonElement>('tool-finish').disabled = !(tool === 'path' || tool === 'polygon') || points.length < (tool === 'path' ? 1 : 3);
  byId<HTMLButtonElement>('tool-undo').disabled = points.length === 0;
  byId('tool-hint').textContent = HINTS[tool] + (points.length ? ` (${points.length} point${points.length > 1 ? 's' : ''})` : '');
}

function drawOverlays(): void {
  const target = plan.targetRef();
  const start: Vec3 = target ? (app.view(target).status?.position_enu_m ?? [0, 0, 0]) : [0, 0, 0];
  const draft = plannedPath(plan.draft, [start[0], start[1], 0], mapView.origin);
  mapView.setDraft(draft);
  const paths: { color: string; points: Vec3[]; label: string }[] = [];
  app.drones().forEach((ref, i) => {
    const p = app.planOf(ref);
    const ms = app.view(ref).mission;
    if (p && ms && (ms.state !== 0 || ms.pending_items > 0)) {
      const v = app.view(ref);
      const t0 = v.trail[0];
      const from: Vec3 = t0 ? [t0.x, t0.y, t0.z] : (v.status?.position_enu_m ?? [0, 0, 0]);
      paths.push({ color: droneColor(i), points: plannedPath({ target: ref.drone, plan: p }, from, mapView.origin).points, label: `${ref.name} mission #${ms.mission_id}` });
    }
  });
  app.drones().forEach((ref, i) => {
    for (const f of feedbackPaths(app.view(ref).status)) paths.push({ color: droneColor(i), points: f.points, label: `${ref.name} ${f.behavior} planned path` });
  });
  for (const [drone, pts] of Object.entries(plan.coverage?.answer?.per_drone ?? {})) {
    const i = app.drones().findIndex((d) => d.drone === drone);
    paths.push({ color: droneColor(Math.max(0, i)), points: pts, label: `${drone} coverage` });
  }
  if (plan.coverage) paths.push({ color: '#0050d0', points: [...plan.coverage.polygon, plan.coverage.polygon[0]].map(([x, y]) => [x, y, 0]), label: 'coverage area' });
  mapView.setPlanned(paths);
  mapView.setFrames(app.instances.flatMap((i) => i.frames));
  mapView.setGeofence(app.instances[0]?.geofence?.polygon_enu_m ?? null);
  drawExploration();
}

/** Frontiers and each exploring drone's goal, from the last GET /api/exploration of each instance. */
function drawExploration(): void {
  const refs = app.drones();
  const frontiers = app.instances.flatMap((i) => exploration.views.get(i.id)?.frontiers ?? []);
  const goals = app.instances.flatMap((inst) =>
    (exploration.views.get(inst.id)?.progress?.drones ?? []).flatMap((d) => {
      if (!d.goal_enu_m) return [];
      const i = refs.findIndex((r) => r.inst === inst && r.drone === d.drone);
      const p = i >= 0 ? app.view(refs[i]).status?.position_enu_m : undefined;
      return [{ drone: d.drone, from: p ? ([p[0], p[1]] as Vec2) : null, to: d.goal_enu_m, color: droneColor(Math.max(0, i)) }];
    }),
  );
  mapView.setExploration(frontiers, goals);
}

async function refreshGrid(): Promise<void> {
  const inst = app.instances[0];
  if (!inst) return;
  try {
    grid = readGrid(await inst.client.map());
    mapView.setGrid(grid);
  } catch {
    // No map yet (no mapping configured): the layer stays empty.
  }
}

let gridFetchDue = 0;

/** Merges a map_update patch into the grid; refetches the whole map (at most every 2 s) otherwise. */
function onMapUpdate(): void {
  const u = app.lastMapUpdate;
  const patch = u ? readGrid({ spec: u.spec, data: u.data }) : null;
  if (grid && patch && mergePatch(grid, patch)) {
    mapView.setGrid(grid);
    return;
  }
  const now = Date.now();
  if (now < gridFetchDue) return;
  gridFetchDue = now + 2000;
  void refreshGrid();
}

// ---- tabs, header, keyboard --------------------------------------------------------------

function showTab(name: string): void {
  document.querySelectorAll<HTMLElement>('#tabs [data-tab]').forEach((b) => b.classList.toggle('active', b.dataset.tab === name));
  document.querySelectorAll<HTMLElement>('.panel').forEach((p) => p.classList.toggle('active', p.id === `panel-${name}`));
  if (name === 'timeline') timeline.render();
  if (name === 'explore') void exploration.poll(true);
  if (name === 'logs') void logs.show();
}

function wireHeader(): void {
  byId('shortcut-help').textContent = SHORTCUT_HELP;
  document.querySelectorAll<HTMLButtonElement>('#tabs [data-tab]').forEach((b) => b.addEventListener('click', () => showTab(b.dataset.tab ?? 'fleet')));
  const select = byId<HTMLSelectElement>('drone-select');
  select.addEventListener('change', () => app.select(select.value));
  const selected = () => {
    const r = app.selected();
    return r ? [r] : [];
  };
  const hold = byId<HTMLButtonElement>('btn-hold');
  const holdAll = byId<HTMLButtonElement>('btn-hold-all');
  const land = byId<HTMLButtonElement>('btn-land');
  const landAll = byId<HTMLButtonElement>('btn-land-all');
  hold.addEventListener('click', () => act(hold, 'HOLD', null, () => app.forAll(selected(), (r) => app.hold(r))));
  holdAll.addEventListener('click', () => act(holdAll, 'HOLD ALL', null, () => app.forAll(app.drones(), (r) => app.hold(r))));
  land.addEventListener('click', () => act(land, 'LAND', null, () => app.forAll(selected(), (r) => app.land(r))));
  landAll.addEventListener('click', () =>
    act(landAll, 'LAND ALL', null, async () => {
      const refs = app.drones();
      if (!window.confirm(`LAND ALL drones (${refs.map((r) => r.name).join(', ')}) now?`)) return { ok: false, text: 'not sent: LAND ALL cancelled' };
      return app.forAll(refs, (r) => app.land(r));
    }),
  );
  document.addEventListener('keydown', (e) => {
    const t = e.target as HTMLElement | null;
    const sc = shortcutFor({ key: e.key, ctrlKey: e.ctrlKey, metaKey: e.metaKey, altKey: e.altKey, targetTag: t?.tagName, targetEditable: t?.isContentEditable });
    if (!sc) return;
    e.preventDefault();
    if (sc === 'hold') holdAll.click();
    else {
      const pause = document.querySelector<HTMLButtonElement>('#ctl-buttons [data-action=PAUSE]');
      act(pause, 'PAUSE (Space)', byId('ctl-answer'), () => app.forAll(selected(), (r) => app.action(r, 'PAUSE', {})));
    }
  });
  document.querySelectorAll<HTMLButtonElement>('#map-tools .tool').forEach((b) =>
    b.addEventListener('click', () => {
      const tool = (b.dataset.tool ?? 'pan') as Tool;
      setTool(tool);
      if (tool !== 'pan') showTab('plan');
    }),
  );
  byId('tool-finish').addEventListener('click', () => mapView.finishDrawing());
  byId('tool-undo').addEventListener('click', () => mapView.undoPoint());
  byId('btn-clear-trails').addEventListener('click', () => {
    for (const inst of app.instances) for (const v of inst.state.drones.values()) v.trail = [];
    mapView.clearTrails();
  });
  byId('btn-fit').addEventListener('click', fitFleet);
  byId('btn-geo').addEventListener('click', () => {
    if (mapView.origin) return makeMap(null);
    const o = geoOrigin();
    if (!o) return toast('no drone reports a GPS fix: the geographic view needs one', false);
    makeMap(o);
  });
}

function renderHeader(): void {
  const refs = app.drones();
  const remote = app.remoteDrones();
  const select = byId<HTMLSelectElement>('drone-select');
  // Other Kestrels' drones are listed, never selectable: they are commanded from their own station.
  setOptions(select, [
    ...refs.map((r) => ({ value: r.key, label: r.name })),
    ...remote.map((r) => ({ value: r.key, label: `${r.name} · remote (${r.drone.node})`, disabled: true, title: remoteCommandNote(r.drone) })),
  ]);
  if (app.selectedKey && select.value !== app.selectedKey) select.value = app.selectedKey;
  const open = app.instances.filter((i) => i.socketOpen).length;
  const status = byId('conn-status');
  const problems = app.instances.filter((i) => !i.socketOpen).map((i) => `${i.label}: ${i.problem ?? 'disconnected'}`);
  const now = Date.now();
  const lost = refs.filter((r) => app.link(r, now).state === 'lost').map((r) => r.name);
  const lostText = lost.length ? ` · LOST: ${lost.join(', ')}` : '';
  const silent = remote.filter((r) => app.remoteLink(r, now).state === 'silent').length;
  const remoteText = remote.length ? ` · ${remote.length} remote${silent ? ` (${silent} silent)` : ''}` : '';
  status.textContent =
    app.instances.length === 0 ? 'connecting…' : problems.length ? problems.join('; ') : `live · ${refs.length} drone(s)${remoteText} · ${open} instance(s)${lostText}`;
  status.className = `conn ${problems.length || app.instances.length === 0 ? 'bad' : lost.length ? 'warn' : 'ok'}`;
}

function renderLegend(): void {
  const names = new Set<string>(['takeoff', 'go_to', 'follow_path', 'land']);
  app.instances.forEach((i) => i.behaviors.forEach((b) => names.add(b.name)));
  const fence = app.instances[0]?.geofence;
  const limits = fence
    ? [fence.max_altitude_m !== null ? `ceiling ${fence.max_altitude_m} m` : '', fence.radius_m !== null ? `radius ${fence.radius_m} m from home` : ''].filter(Boolean).join(', ')
    : '';
  byId('legend').replaceChildren(
    ...[...names].map((n) => h('span', {}, h('span', { className: 'swatch', style: `background:${behaviorColor(n)}` }), n)),
    limits ? h('span', { className: 'fence' }, `geofence: ${limits}`) : '',
  );
}

// ---- start -----------------------------------------------------------------------------------

function drawDrones(): void {
  const now = Date.now();
  const drones = app.drones().map((ref, i) => ({ key: ref.key, name: ref.name, view: app.view(ref), link: app.link(ref, now), color: droneColor(i) }));
  mapView.renderDrones(drones);
  mapView.renderRemote(app.remoteDrones().map((ref) => ({ key: ref.key, drone: ref.drone, link: app.remoteLink(ref, now) })));
  altitude.render(drones);
}

/** Zooms the map to every drone that has a position, other Kestrels' too (home when none has). */
function fitFleet(): void {
  const placed = app.drones().map((r) => app.view(r).status).filter(hasPosition);
  const points = [...placed.map((s) => s.position_enu_m), ...app.remoteDrones().flatMap((r) => (r.drone.position_enu_m ? [r.drone.position_enu_m] : []))];
  mapView.fitTo(points.length ? points.map((p): Vec2 => [p[0], p[1]]) : [[0, 0]]);
}

function choicesChanged(): void {
  plan.refreshChoices();
  control.refreshChoices();
  exploration.refreshChoices();
  timeline.refreshChoices();
  renderHeader();
  renderLegend();
}

/** Page coordinates of an ENU point, panning to it first: lets the browser tests click the map. */
function mapPoint(x: number, y: number): { x: number; y: number } {
  const ll = mapView.ll(x, y);
  if (!mapView.map.getBounds().pad(-0.1).contains(ll)) mapView.map.setView(ll, mapView.map.getZoom(), { animate: false });
  const p = mapView.map.latLngToContainerPoint(ll);
  const r = mapView.map.getContainer().getBoundingClientRect();
  return { x: r.left + p.x, y: r.top + p.y };
}
(window as unknown as { __kestrel: unknown }).__kestrel = { mapPoint };

async function main(): Promise<void> {
  wireHeader();
  makeMap(null);
  plan.onChange = drawOverlays;
  exploration.onView = drawExploration;
  timeline.onPast = (log) => mapView.setPast(log ? [...log.poses.values()] : []);
  let dirty = true;
  app.on((topic) => {
    if (topic === 'instances' || topic === 'selection') {
      choicesChanged();
      if (topic === 'selection' && app.selectedKey) {
        control.selectDrone(app.selectedKey);
        exploration.selectDrone(app.selectedKey);
      }
    }
    if (topic === 'map') onMapUpdate();
    dirty = true;
  });
  await connect();
  await restoreInstances(app);
  choicesChanged();
  void refreshGrid();
  fitFleet();
  // Render at 4 Hz; the link staleness check needs the clock even when no message arrives.
  setInterval(() => {
    if (app.drones().length + app.remoteDrones().length !== byId<HTMLSelectElement>('drone-select').options.length) choicesChanged();
    renderHeader();
    fleet.render();
    drawDrones();
    if (dirty) {
      monitor.render();
      drawOverlays();
      dirty = false;
    }
  }, 250);
  setInterval(() => {
    if (byId('panel-timeline').classList.contains('active')) timeline.render();
    void exploration.poll();
  }, 1000);
  setInterval(async () => {
    await Promise.all(app.instances.map((i) => i.refreshFrames()));
    control.refreshChoices();
  }, 5000);
}

void main();
