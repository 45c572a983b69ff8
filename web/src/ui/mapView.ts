// Leaflet glue: the local ENU map (simple CRS, x east = lng, y north = lat) or, in geographic
// mode, Web Mercator around the ENU origin. Drones, behavior-coloured trails, planned paths, the
// plan being drawn, occupancy grid (the explored area), exploration frontiers and goals, frames,
// geofence and the drones other Kestrels fly (remoteLayer.ts) are layers; clicks go to the active
// tool.

import L from 'leaflet';
import 'leaflet/dist/leaflet.css';
import { behaviorColor, trailRuns } from '../lib/colors';
import { hasPosition, type DroneView, type LinkView } from '../lib/fleet';
import { enuToGeo, geoToEnu, type GeoOrigin } from '../lib/geo';
import { graticule } from '../lib/graticule';
import { gridBounds, gridPixels, type Grid } from '../lib/grid';
import type { FrameInfo, FrontierView, Vec2, Vec3 } from '../lib/types';
import { RemoteLayer, type RemoteDraw } from './remoteLayer';

export type Tool = 'pan' | 'waypoint' | 'path' | 'polygon';

export interface MapCallbacks {
  waypoint(p: Vec2): void;
  finish(tool: 'path' | 'polygon', points: Vec2[]): void;
  drawingChanged(tool: Tool, points: Vec2[]): void;
  frameClicked(frameId: string): void;
  /** A plan target dragged to ENU `p`: item `item`, point `sub` of its path (0 for one point). */
  waypointMoved(item: number, sub: number, p: Vec2): void;
  /** The pointer moved over the map: ENU metres, and latitude/longitude in geographic mode. */
  cursor?(enu: Vec2, latLon: [number, number] | null): void;
}

export interface DroneDraw {
  key: string;
  name: string;
  view: DroneView;
  link: LinkView;
  color: string;
}

const DRONE_COLORS = ['#0b3d91', '#b30059', '#006d2c', '#7a4100', '#4b0082', '#00607a'];
export const droneColor = (i: number): string => DRONE_COLORS[i % DRONE_COLORS.length];

export class MapView {
  readonly map: L.Map;
  private readonly layers = {
    axes: L.layerGroup(),
    grid: L.layerGroup(),
    geofence: L.layerGroup(),
    frames: L.layerGroup(),
    past: L.layerGroup(),
    planned: L.layerGroup(),
    exploration: L.layerGroup(),
    trails: L.layerGroup(),
    draft: L.layerGroup(),
    drawing: L.layerGroup(),
    remote: L.layerGroup(),
    drones: L.layerGroup(),
  };
  private readonly remote = new RemoteLayer(this.layers.remote, (x, y) => this.ll(x, y));
  private markers = new Map<string, L.Marker>();
  private trailDrawn = new Map<string, { n: number; group: L.LayerGroup }>();
  private gridUrl: string | null = null;
  private draftKey = '';
  private draggingTarget = false;
  tool: Tool = 'pan';
  drawing: Vec2[] = [];

  constructor(
    el: HTMLElement,
    private readonly cb: MapCallbacks,
    readonly origin: GeoOrigin | null,
    basemapUrl: string | null,
  ) {
    const geo = origin !== null;
    this.map = L.map(el, {
      crs: geo ? L.CRS.EPSG3857 : L.CRS.Simple,
      minZoom: geo ? 3 : -3,
      maxZoom: geo ? 22 : 6,
      zoomSnap: 0.25,
      attributionControl: geo && !!basemapUrl,
      doubleClickZoom: false,
    });
    if (geo && basemapUrl) {
      L.tileLayer(basemapUrl, { maxZoom: 22, maxNativeZoom: 19, attribution: 'basemap' }).addTo(this.map);
    }
    for (const layer of Object.values(this.layers)) layer.addTo(this.map);
    if (!geo) this.drawAxes();
    L.control
      .layers(undefined, {
        'Occupancy grid': this.layers.grid,
        Geofence: this.layers.geofence,
        Frames: this.layers.frames,
        Trails: this.layers.trails,
        'Planned paths': this.layers.planned,
        Exploration: this.layers.exploration,
        'Past flight': this.layers.past,
        'Other Kestrels\' drones': this.layers.remote,
        'Grid lines': this.layers.axes,
      }, { collapsed: true })
      .addTo(this.map);
    L.control.scale({ imperial: false }).addTo(this.map);
    this.map.setView(this.ll(0, 0), geo ? 19 : 3);
    // Without a basemap the geographic view would be blank: lat/lon lines and labels instead.
    if (geo && !basemapUrl) {
      this.map.on('moveend', () => this.drawGraticule());
      this.drawGraticule();
    }
    this.map.on('click', (e: L.LeafletMouseEvent) => this.onClick(e.latlng));
    this.map.on('dblclick', () => this.finishDrawing());
    this.map.on('mousemove', (e: L.LeafletMouseEvent) => this.cb.cursor?.(this.enu(e.latlng), this.origin ? [e.latlng.lat, e.latlng.lng] : null));
  }

  /** ENU metres to the map's coordinates. */
  ll(x: number, y: number): L.LatLng {
    if (this.origin) {
      const [lat, lon] = enuToGeo(this.origin, x, y);
      return L.latLng(lat, lon);
    }
    return L.latLng(y, x);
  }

  enu(ll: L.LatLng): Vec2 {
    if (this.origin) return geoToEnu(this.origin, ll.lat, ll.lng);
    return [ll.lng, ll.lat];
  }

  setTool(tool: Tool): void {
    this.tool = tool;
    this.drawing = [];
    this.map.getContainer().classList.toggle('drawing', tool !== 'pan');
    this.renderDrawing();
    this.cb.drawingChanged(tool, this.drawing);
  }

  private onClick(ll: L.LatLng): void {
    const [x, y] = this.enu(ll);
    const p: Vec2 = [Math.round(x * 100) / 100, Math.round(y * 100) / 100];
    if (this.tool === 'waypoint') this.cb.waypoint(p);
    else if (this.tool === 'path' || this.tool === 'polygon') {
      this.drawing.push(p);
      this.renderDrawing();
      this.cb.drawingChanged(this.tool, this.drawing);
    }
  }

  finishDrawing(): void {
    if (this.tool !== 'path' && this.tool !== 'polygon') return;
    const need = this.tool === 'path' ? 1 : 3;
    if (this.drawing.length < need) return;
    const points = this.drawing;
    const tool = this.tool;
    this.drawing = [];
    this.renderDrawing();
    this.cb.finish(tool, points);
    this.cb.drawingChanged(this.tool, this.drawing);
  }

  undoPoint(): void {
    this.drawing.pop();
    this.renderDrawing();
    this.cb.drawingChanged(this.tool, this.drawing);
  }

  private renderDrawing(): void {
    const g = this.layers.drawing;
    g.clearLayers();
    const lls = this.drawing.map(([x, y]) => this.ll(x, y));
    if (lls.length > 1) {
      const style = { color: '#0050d0', weight: 3, dashArray: '6 4' };
      (this.tool === 'polygon' ? L.polygon(lls, { ...style, fillOpacity: 0.15 }) : L.polyline(lls, style)).addTo(g);
    }
    lls.forEach((ll) => L.circleMarker(ll, { radius: 5, color: '#0050d0', fillOpacity: 1 }).addTo(g));
  }

  private drawAxes(): void {
    const g = this.layers.axes;
    const span = 200;
    for (let v = -span; v <= span; v += 10) {
      const major = v === 0;
      const style = { color: major ? '#555' : '#d0d0d0', weight: major ? 1.5 : 1, interactive: false };
      L.polyline([this.ll(v, -span), this.ll(v, span)], style).addTo(g);
      L.polyline([this.ll(-span, v), this.ll(span, v)], style).addTo(g);
    }
    L.marker(this.ll(0, 0), {
      interactive: false,
      icon: L.divIcon({ className: 'axis-label', html: 'origin (0, 0) · x east, y north', iconSize: [220, 16], iconAnchor: [-4, 18] }),
    }).addTo(g);
  }

  /** Latitude/longitude lines over the visible area, labelled at the left and top edges. */
  private drawGraticule(): void {
    const g = this.layers.axes;
    g.clearLayers();
    const b = this.map.getBounds();
    const size = this.map.getSize();
    if (size.x === 0 || size.y === 0) return;
    const grat = graticule(b.getSouth(), b.getWest(), b.getNorth(), b.getEast());
    const style = { color: '#9a9a9a', weight: 1, interactive: false };
    const label = (ll: L.LatLng, cls: string, text: string, value: number, anchor: [number, number]) =>
      L.marker(ll, {
        interactive: false,
        keyboard: false,
        icon: L.divIcon({ className: 'grat-label', html: `<span class="${cls}" data-deg="${value}">${text}</span>`, iconSize: [110, 16], iconAnchor: anchor }),
      }).addTo(g);
    for (const lat of grat.lats) {
      L.polyline([L.latLng(lat.value_deg, b.getWest()), L.latLng(lat.value_deg, b.getEast())], style).addTo(g);
      const at = this.map.containerPointToLatLng([52, 0]);
      label(L.latLng(lat.value_deg, at.lng), 'grat-lat', lat.label, lat.value_deg, [0, 17]);
    }
    for (const lon of grat.lons) {
      L.polyline([L.latLng(b.getSouth(), lon.value_deg), L.latLng(b.getNorth(), lon.value_deg)], style).addTo(g);
      const at = this.map.containerPointToLatLng([0, size.y - 34]);
      label(L.latLng(at.lat, lon.value_deg), 'grat-lon', lon.label, lon.value_deg, [-3, 16]);
    }
  }

  renderDrones(drones: DroneDraw[]): void {
    const seen = new Set<string>();
    for (const d of drones) {
      const s = d.view.status;
      // No marker until the autopilot has given a position: the fleet card says "no position".
      if (!hasPosition(s)) continue;
      seen.add(d.key);
      const [x, y, z] = s.position_enu_m;
      const ll = s.geo && this.origin ? L.latLng(s.geo.lat_deg, s.geo.lon_deg) : this.ll(x, y);
      let m = this.markers.get(d.key);
      if (!m) {
        m = L.marker(ll, {
          icon: L.divIcon({
            className: 'drone-icon',
            html: `<div class="drone-glyph" data-drone="${d.name}" style="--c:${d.color}"><svg viewBox="-12 -12 24 24" width="28" height="28"><path d="M11 0 L-8 -8 L-4 0 L-8 8 Z"/></svg><span class="drone-label"></span></div>`,
            iconSize: [28, 28],
            iconAnchor: [14, 14],
          }),
          keyboard: false,
        }).addTo(this.layers.drones);
        this.markers.set(d.key, m);
      }
      m.setLatLng(ll);
      const el = m.getElement()?.querySelector<HTMLElement>('.drone-glyph');
      if (el) {
        el.dataset.x = x.toFixed(2);
        el.dataset.y = y.toFixed(2);
        el.classList.toggle('lost', d.link.state !== 'ok');
        el.querySelector('svg')?.setAttribute('style', `transform: rotate(${(-s.yaw_rad * 180) / Math.PI}deg)`);
        const label = el.querySelector('.drone-label');
        if (label) label.textContent = `${d.name}${d.link.state === 'lost' ? ' STALE' : ''} ${z.toFixed(1)} m`;
      }
    }
    for (const [key, m] of this.markers) {
      if (!seen.has(key)) {
        m.remove();
        this.markers.delete(key);
      }
    }
    this.renderTrails(drones);
  }

  /** Drones other Kestrels of the fleet fly. */
  renderRemote(drones: RemoteDraw[]): void {
    this.remote.render(drones);
  }

  private renderTrails(drones: DroneDraw[]): void {
    for (const d of drones) {
      const trail = d.view.trail;
      let drawn = this.trailDrawn.get(d.key);
      if (drawn && drawn.n === trail.length) continue;
      if (!drawn) {
        drawn = { n: 0, group: L.layerGroup().addTo(this.layers.trails) };
        this.trailDrawn.set(d.key, drawn);
      }
      drawn.group.clearLayers();
      for (const run of trailRuns(trail)) {
        L.polyline(run.points.map((p) => this.ll(p.x, p.y)), {
          color: behaviorColor(run.behavior),
          weight: 4,
          opacity: 0.9,
          interactive: false,
        }).addTo(drawn.group);
      }
      drawn.n = trail.length;
    }
  }

  clearTrails(): void {
    this.layers.trails.clearLayers();
    this.trailDrawn.clear();
  }

  /** The plan being edited: dashed black line with numbered points; targets (`movable`) are
   * dragged to move them. */
  setDraft(draft: { points: Vec3[]; items: number[]; sub: number[]; movable: boolean[] }): void {
    // Redrawn at telemetry rate: not while a target is being dragged (its marker would go), nor
    // when nothing changed.
    const key = JSON.stringify(draft);
    if (this.draggingTarget || key === this.draftKey) return;
    this.draftKey = key;
    const g = this.layers.draft;
    g.clearLayers();
    const { points, items, sub, movable } = draft;
    if (points.length < 2) return;
    const lls = points.map(([x, y]) => this.ll(x, y));
    L.polyline(lls, { color: '#111', weight: 3, dashArray: '8 6', interactive: false }).addTo(g);
    lls.forEach((ll, i) => {
      const drag = movable[i] === true;
      if (items[i] < 0 || (!drag && items[i] === items[i + 1])) return;
      const m = L.marker(ll, {
        interactive: drag,
        draggable: drag,
        keyboard: false,
        title: drag ? `item ${items[i]}: drag to move` : '',
        icon: L.divIcon({
          className: `wp-icon${drag ? ' wp-movable' : ''}`,
          html: `<span data-item="${items[i]}" data-sub="${sub[i]}">${items[i]}</span>`,
          iconSize: [22, 22],
          iconAnchor: [11, 11],
        }),
      });
      if (drag) {
        m.on('dragstart', () => (this.draggingTarget = true));
        m.on('dragend', () => {
          this.draggingTarget = false;
          const [x, y] = this.enu(m.getLatLng());
          this.cb.waypointMoved(items[i], sub[i], [Math.round(x * 100) / 100, Math.round(y * 100) / 100]);
        });
      }
      m.addTo(g);
    });
  }

  /** Missions loaded on drones, and coverage sweeps, in each drone's colour. */
  setPlanned(paths: { color: string; points: Vec3[]; label: string }[]): void {
    const g = this.layers.planned;
    g.clearLayers();
    for (const p of paths) {
      if (p.points.length < 2) continue;
      L.polyline(p.points.map(([x, y]) => this.ll(x, y)), { color: p.color, weight: 2, dashArray: '4 6' })
        .bindTooltip(p.label)
        .addTo(g);
    }
  }

  /** Frontiers (a circle at the centroid, its diameter half the frontier's length) and each exploring drone's goal
   * (a line from the drone to it). */
  setExploration(frontiers: FrontierView[], goals: { drone: string; from: Vec2 | null; to: Vec2; color: string }[]): void {
    const g = this.layers.exploration;
    g.clearLayers();
    for (const f of frontiers) {
      const [x, y] = f.centroid_enu_m;
      L.circle(this.ll(x, y), { radius: Math.max(0.15, f.size_m / 4), color: '#e07000', weight: 2, fillOpacity: 0.3, className: 'frontier' })
        .bindTooltip(`frontier ${f.size_m.toFixed(1)} m`)
        .addTo(g);
    }
    for (const goal of goals) {
      const to = this.ll(goal.to[0], goal.to[1]);
      if (goal.from) {
        L.polyline([this.ll(goal.from[0], goal.from[1]), to], { color: goal.color, weight: 3, className: `explore-goal explore-goal-${goal.drone}` })
          .bindTooltip(`${goal.drone} goal`)
          .addTo(g);
      }
      L.circleMarker(to, { radius: 6, color: goal.color, weight: 3, fillOpacity: 0.6, className: `explore-goal-point explore-goal-point-${goal.drone}` })
        .bindTooltip(`${goal.drone} goal (${goal.to[0].toFixed(1)}, ${goal.to[1].toFixed(1)})`)
        .addTo(g);
    }
  }

  setFrames(frames: FrameInfo[]): void {
    const g = this.layers.frames;
    g.clearLayers();
    for (const f of frames) {
      const t = f.translation_m;
      if (!Array.isArray(t) || f.frame_id === 'earth' || f.parent !== 'earth') continue;
      const m = L.marker(this.ll(t[0], t[1]), {
        icon: L.divIcon({ className: 'frame-icon', html: `<span>◆ ${f.frame_id}</span>`, iconSize: [120, 18], iconAnchor: [6, 9] }),
      });
      m.on('click', () => this.cb.frameClicked(f.frame_id));
      m.addTo(g);
    }
  }

  setGeofence(polygon: Vec2[] | null): void {
    const g = this.layers.geofence;
    g.clearLayers();
    if (!polygon || polygon.length < 3) return;
    L.polygon(polygon.map(([x, y]) => this.ll(x, y)), { color: '#c00000', weight: 3, dashArray: '10 6', fill: false, interactive: false }).addTo(g);
  }

  setGrid(grid: Grid | null): void {
    const g = this.layers.grid;
    g.clearLayers();
    if (!grid) return;
    const canvas = document.createElement('canvas');
    canvas.width = grid.spec.width;
    canvas.height = grid.spec.height;
    const ctx = canvas.getContext('2d');
    if (!ctx) return;
    ctx.putImageData(new ImageData(gridPixels(grid) as Uint8ClampedArray<ArrayBuffer>, grid.spec.width, grid.spec.height), 0, 0);
    this.gridUrl = canvas.toDataURL();
    const [[s, w], [n, e]] = gridBounds(grid.spec);
    L.imageOverlay(this.gridUrl, L.latLngBounds(this.ll(w, s), this.ll(e, n)), { className: 'pixelated', interactive: false }).addTo(g);
  }

  /** A past flight's poses, coloured by behavior. */
  setPast(tracks: { x: number; y: number; behavior: string | null }[][]): void {
    const g = this.layers.past;
    g.clearLayers();
    for (const track of tracks) {
      for (const run of trailRuns(track)) {
        L.polyline(run.points.map((p) => this.ll(p.x, p.y)), { color: behaviorColor(run.behavior), weight: 3, opacity: 0.6, dashArray: '2 4' }).addTo(g);
      }
    }
  }

  fitTo(points: Vec2[]): void {
    if (points.length === 0) return;
    const b = L.latLngBounds(points.map(([x, y]) => this.ll(x, y)));
    this.map.fitBounds(b.pad(0.5), { maxZoom: this.origin ? 20 : 4 });
  }

  destroy(): void {
    this.map.remove();
  }
}
