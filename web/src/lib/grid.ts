// Occupancy grids from `GET /api/map` and `map_update` messages: the spec read tolerantly, patches
// merged, and cells turned into RGBA pixels (row 0 of the image is the grid's northern row).

export interface GridSpec {
  originX_m: number;
  originY_m: number;
  resolution_m: number;
  width: number;
  height: number;
}

export interface Grid {
  spec: GridSpec;
  /** row-major from the south-west cell; -1 unknown, else occupancy 0..100 */
  data: number[];
}

type Obj = Record<string, unknown>;
const n = (...vals: unknown[]): number | null => {
  for (const v of vals) if (typeof v === 'number' && Number.isFinite(v)) return v;
  return null;
};

/** Reads `{resolution_m, width, height, origin_m: [x, y]}` and the usual variants of those names. */
export function readSpec(raw: Obj): GridSpec | null {
  const origin = (raw.origin_m ?? raw.origin ?? raw.origin_enu_m) as unknown;
  const o = Array.isArray(origin) ? origin : [];
  const oo = origin && typeof origin === 'object' && !Array.isArray(origin) ? (origin as Obj) : {};
  const spec = {
    originX_m: n(o[0], oo.x, raw.origin_x_m, raw.origin_x) ?? 0,
    originY_m: n(o[1], oo.y, raw.origin_y_m, raw.origin_y) ?? 0,
    resolution_m: n(raw.resolution_m, raw.resolution, raw.cell_m, raw.cell_size_m),
    width: n(raw.width, raw.width_cells, raw.cols, raw.size_x),
    height: n(raw.height, raw.height_cells, raw.rows, raw.size_y),
  };
  if (!spec.resolution_m || !spec.width || !spec.height || spec.resolution_m <= 0) return null;
  return spec as GridSpec;
}

export function readGrid(raw: { spec: Obj; data: number[] }): Grid | null {
  const spec = readSpec(raw.spec ?? {});
  if (!spec || !Array.isArray(raw.data) || raw.data.length !== spec.width * spec.height) return null;
  return { spec, data: raw.data };
}

/** Writes a patch into the grid; false when the patch does not fit (then refetch the whole map). */
export function mergePatch(grid: Grid, patch: Grid): boolean {
  const g = grid.spec;
  const p = patch.spec;
  if (Math.abs(g.resolution_m - p.resolution_m) > 1e-9) return false;
  const dx = Math.round((p.originX_m - g.originX_m) / g.resolution_m);
  const dy = Math.round((p.originY_m - g.originY_m) / g.resolution_m);
  if (dx < 0 || dy < 0 || dx + p.width > g.width || dy + p.height > g.height) return false;
  for (let r = 0; r < p.height; r++) {
    for (let c = 0; c < p.width; c++) {
      grid.data[(dy + r) * g.width + dx + c] = patch.data[r * p.width + c];
    }
  }
  return true;
}

const FREE_RGBA = [175, 208, 240, 160];

/** RGBA pixels, north row first: unknown transparent, free pale blue, occupied dark. */
export function gridPixels(grid: Grid): Uint8ClampedArray {
  const { width, height } = grid.spec;
  const px = new Uint8ClampedArray(width * height * 4);
  const scale = grid.data.some((v) => v > 1) ? 100 : 1;
  for (let r = 0; r < height; r++) {
    const out = (height - 1 - r) * width;
    for (let c = 0; c < width; c++) {
      const v = grid.data[r * width + c];
      const i = (out + c) * 4;
      if (v < 0) continue;
      const occ = Math.min(1, v / scale);
      if (occ < 0.5) {
        // Explored free space: pale blue, so the explored area stands out as it grows.
        px.set(FREE_RGBA, i);
        continue;
      }
      const shade = Math.round(235 - 215 * occ);
      px[i] = shade;
      px[i + 1] = shade;
      px[i + 2] = shade;
      px[i + 3] = 230;
    }
  }
  return px;
}

/** The grid's extent in ENU metres: [[south, west], [north, east]] as Leaflet's simple CRS wants. */
export function gridBounds(spec: GridSpec): [[number, number], [number, number]] {
  return [
    [spec.originY_m, spec.originX_m],
    [spec.originY_m + spec.height * spec.resolution_m, spec.originX_m + spec.width * spec.resolution_m],
  ];
}
