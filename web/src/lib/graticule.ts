// Graticule for the geographic view without a basemap: latitude and longitude lines at a round
// step (1, 2 or 5 × 10^k degrees) that gives a few lines across the visible area, with labels.
//
// In: the visible bounds in degrees. Out: the line positions and their labels ("47.3978° N").

export interface GraticuleLine {
  value_deg: number;
  label: string;
}

export interface Graticule {
  step_deg: number;
  lats: GraticuleLine[];
  lons: GraticuleLine[];
}

/** Most lines drawn in one direction, whatever the bounds (a bound on the work per redraw). */
const MAX_LINES = 40;

/** The round step giving about `want` lines over `span_deg` (never below 1e-6°, about 10 cm). */
export function graticuleStep(span_deg: number, want = 5): number {
  const raw = Math.max(1e-6, Math.abs(span_deg) / Math.max(1, want));
  const k = Math.floor(Math.log10(raw));
  const base = 10 ** k;
  for (const m of [1, 2, 5]) if (m * base >= raw * (1 - 1e-9)) return Number((m * base).toPrecision(6));
  return Number((10 * base).toPrecision(6));
}

/** Decimals needed to tell lines `step_deg` apart. */
export function stepDecimals(step_deg: number): number {
  return Math.max(0, Math.ceil(-Math.log10(step_deg) - 1e-9));
}

export function formatLat(lat_deg: number, decimals: number): string {
  return `${Math.abs(lat_deg).toFixed(decimals)}° ${lat_deg < 0 ? 'S' : 'N'}`;
}

export function formatLon(lon_deg: number, decimals: number): string {
  return `${Math.abs(lon_deg).toFixed(decimals)}° ${lon_deg < 0 ? 'W' : 'E'}`;
}

function lines(from: number, to: number, step: number, format: (v: number) => string): GraticuleLine[] {
  const out: GraticuleLine[] = [];
  const first = Math.ceil(from / step);
  for (let i = first; i * step <= to && out.length < MAX_LINES; i++) {
    const v = i * step;
    out.push({ value_deg: v, label: format(v) });
  }
  return out;
}

/** Lines inside the bounds, one step for both directions (the smaller span decides). */
export function graticule(south: number, west: number, north: number, east: number): Graticule {
  const span = Math.min(north - south, east - west);
  const step_deg = graticuleStep(span, 4);
  const d = stepDecimals(step_deg);
  return {
    step_deg,
    lats: lines(south, north, step_deg, (v) => formatLat(v, d)),
    lons: lines(west, east, step_deg, (v) => formatLon(v, d)),
  };
}
