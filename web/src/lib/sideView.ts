// The altitude (side) view's geometry: east–up extents that hold every drone and trail, and the
// mapping from metres to SVG pixels. No DOM.

export interface SideExtent {
  xMin: number;
  xMax: number;
  zMin: number;
  zMax: number;
}

/** East (x) and up (z) extents around `points`, padded, never smaller than `minSpan_m`. */
export function sideExtent(points: { x: number; z: number }[], minSpan_m = 10): SideExtent {
  const xs = points.map((p) => p.x);
  const zs = points.map((p) => p.z);
  let xMin = Math.min(0, ...xs);
  let xMax = Math.max(0, ...xs);
  const zMin = Math.min(0, ...zs);
  let zMax = Math.max(minSpan_m / 2, ...zs);
  const pad = Math.max(1, (xMax - xMin) * 0.08);
  xMin -= pad;
  xMax += pad;
  if (xMax - xMin < minSpan_m) {
    const mid = (xMin + xMax) / 2;
    xMin = mid - minSpan_m / 2;
    xMax = mid + minSpan_m / 2;
  }
  zMax += Math.max(1, (zMax - zMin) * 0.1);
  return { xMin, xMax, zMin, zMax };
}

/** Metres (east, up) to pixels in a `width` × `height` box with `margin` px for the axes. */
export function sidePixel(e: SideExtent, width: number, height: number, margin: number, x: number, z: number): [number, number] {
  const px = margin + ((x - e.xMin) / (e.xMax - e.xMin)) * (width - 2 * margin);
  const py = height - margin - ((z - e.zMin) / (e.zMax - e.zMin)) * (height - 2 * margin);
  return [px, py];
}
