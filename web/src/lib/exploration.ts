// Exploration as the panel shows it: which drones are ticked by default, what a stop must confirm,
// and the progress in words. No DOM.

import type { ExplorationProgress } from './types';

/** Ticked by default: the selected drone only, never silently all. */
export function defaultChoice(selected: string | null, drones: string[]): Set<string> {
  return new Set(selected && drones.includes(selected) ? [selected] : []);
}

/** Stopping several drones at once asks first; one drone does not. */
export function stopNeedsConfirm(drones: string[]): boolean {
  return drones.length > 1;
}

/** Seconds as `1 h 02 min`, `4 min 05 s` or `12 s`; `—` when unknown. */
export function duration(s: number | null | undefined): string {
  if (typeof s !== 'number' || !Number.isFinite(s) || s < 0) return '—';
  const t = Math.round(s);
  const h = Math.floor(t / 3600);
  const m = Math.floor((t % 3600) / 60);
  const sec = t % 60;
  const pad = (n: number) => String(n).padStart(2, '0');
  if (h > 0) return `${h} h ${pad(m)} min`;
  if (m > 0) return `${m} min ${pad(sec)} s`;
  return `${sec} s`;
}

/** The progress line: elapsed, estimated remaining (an upper bound) and the area rate. */
export function progressText(p: ExplorationProgress | null): { elapsed: string; remaining: string; state: string } {
  if (!p) return { elapsed: '—', remaining: '—', state: 'no exploration started' };
  const remaining = p.finished ? '0 s' : p.remaining_s === null ? 'estimating…' : `≤ ${duration(p.remaining_s)}`;
  const rate = p.area_rate_pct_per_min === null ? '' : ` · ${p.area_rate_pct_per_min.toFixed(2)} %/min`;
  return { elapsed: duration(p.elapsed_s), remaining, state: `${p.finished ? 'finished' : 'exploring'}${rate}` };
}

/** The drones of the run still exploring (not finished, failed or stopped). */
export function exploringDrones(p: ExplorationProgress | null): string[] {
  const ended = new Set(['succeeded', 'failed', 'aborted', 'stopped']);
  return (p?.drones ?? []).filter((d) => !ended.has(d.phase)).map((d) => d.drone);
}

/** The line naming the drones the server says are exploring (after any reload, from its state). */
export function runningText(names: string[]): string {
  if (names.length === 0) return 'no drone is exploring';
  return `${names.length === 1 ? '1 drone' : `${names.length} drones`} exploring: ${names.join(', ')}`;
}
