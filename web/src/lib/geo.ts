// Local tangent plane around a geodetic origin: ENU metres <-> latitude/longitude, accurate to
// centimetres over the few hundred metres a mission spans.

const R_M = 6_378_137;
const RAD = Math.PI / 180;

export interface GeoOrigin {
  lat_deg: number;
  lon_deg: number;
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
  geo: { lat_deg: number; lon_deg: number } | null,
): GeoOrigin | null {
  if (!geo || !Number.isFinite(geo.lat_deg) || !Number.isFinite(geo.lon_deg)) return null;
  const lat_deg = geo.lat_deg - position_enu_m[1] / R_M / RAD;
  const lon_deg = geo.lon_deg - position_enu_m[0] / (R_M * Math.cos(lat_deg * RAD)) / RAD;
  return { lat_deg, lon_deg };
}
