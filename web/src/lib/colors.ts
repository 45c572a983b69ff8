// One colour per behavior, the same on the map's trails, the timeline and the legend. Chosen to
// stay distinct on a white background in daylight.

const FIXED: Record<string, string> = {
  takeoff: '#1f77b4',
  go_to: '#d62728',
  follow_path: '#2ca02c',
  navigate_to: '#9467bd',
  land: '#ff7f0e',
  rtl: '#8c564b',
  hover: '#7f7f7f',
  rotate: '#e377c2',
  follow_reference: '#17becf',
  point_gimbal: '#000000',
  take_photo: '#bcbd22',
};

const EXTRA = ['#393b79', '#637939', '#8c6d31', '#843c39', '#7b4173', '#3182bd', '#e6550d'];

export const IDLE_COLOR = '#9a9a9a';

export function behaviorColor(behavior: string | null): string {
  if (!behavior) return IDLE_COLOR;
  const fixed = FIXED[behavior];
  if (fixed) return fixed;
  let h = 0;
  for (const c of behavior) h = (h * 31 + c.charCodeAt(0)) >>> 0;
  return EXTRA[h % EXTRA.length];
}

/** A trail cut into runs of one behavior; consecutive runs share their joining point. */
export function trailRuns<P extends { behavior: string | null }>(points: P[]): { behavior: string | null; points: P[] }[] {
  const runs: { behavior: string | null; points: P[] }[] = [];
  for (const p of points) {
    const last = runs[runs.length - 1];
    if (last && last.behavior === p.behavior) last.points.push(p);
    else {
      const joint = last ? [last.points[last.points.length - 1]] : [];
      runs.push({ behavior: p.behavior, points: [...joint, p] });
    }
  }
  return runs;
}
