// Local tangent plane around a geodetic origin: ENU metres <-> latitude/longitude, accurate to
// centimetres over the few hundred metres a mission spans.

const R_M = 6_378_137;
const RAD = Math.PI / 180;

export interface GeoOrigin {
  lat_deg: number;
  lon_deg: number;
  /** Altitude (m AMSL) of the ENU origin, when known. */
  alt_m?: number;
}

export function enuToGeo(o: GeoOrigin, x_m: number, y_m: number): [number, number] {
  return [o.lat_deg + y_m / R_M / RAD, o.lon_deg + x_m / (R_M * Math.cos(o.lat_deg * RAD)) / RAD];
}

export function geoToEnu(o: GeoOrigin, lat_deg: number, lon_deg: number): [number, number] {
  return [(lon_deg - o.lon_deg) * RAD * R_M * Math.cos(o.lat_deg * RAD), (lat_deg - o.lat_deg) * RAD * R_M];
}

/** The ENU origin in lat/lon, from a drone that reports both its ENU position and its fix. */
export function originFrom(
  position_enu_m: [number, number, number],
  geo: { lat_deg: number; lon_deg: number; alt_m?: number } | null,
): GeoOrigin | null {
  if (!geo || !Number.isFinite(geo.lat_deg) || !Number.isFinite(geo.lon_deg)) return null;
  const lat_deg = geo.lat_deg - position_enu_m[1] / R_M / RAD;
  const lon_deg = geo.lon_deg - position_enu_m[0] / (R_M * Math.cos(lat_deg * RAD)) / RAD;
  const alt_m = typeof geo.alt_m === 'number' ? geo.alt_m - position_enu_m[2] : undefined;
  return alt_m === undefined ? { lat_deg, lon_deg } : { lat_deg, lon_deg, alt_m };
}

export interface Geofence {
  polygon_enu_m: [number, number][] | null;
  max_altitude_m: number | null;
  radius_m: number | null;
}

/** Reads the config's `[geofence]` section as the API returns it; null when there is none. */
export function readGeofence(raw: unknown): Geofence | null {
  if (!raw || typeof raw !== 'object') return null;
  const g = raw as Record<string, unknown>;
  const n = (v: unknown) => (typeof v === 'number' && Number.isFinite(v) ? v : null);
  const poly = Array.isArray(g.polygon_enu_m)
    ? g.polygon_enu_m.filter((p): p is [number, number] => Array.isArray(p) && n(p[0]) !== null && n(p[1]) !== null)
    : null;
  const fence = { polygon_enu_m: poly && poly.length >= 3 ? poly : null, max_altitude_m: n(g.max_altitude_m), radius_m: n(g.radius_m) };
  return fence.polygon_enu_m || fence.max_altitude_m !== null || fence.radius_m !== null ? fence : null;
}
