// Flight-log list of the Logs panel, without the DOM. In: `GET /api/logs` entries and request
// failures. Out: the text a row shows (size, start time, live) and the operator's words for a
// failure (401, 404, unreachable).

import { ApiError } from './api';
import type { LogEntry } from './types';

/** `1536` → `1.5 KiB`: bytes in binary units, one decimal above 1 KiB. */
export function formatBytes(bytes: number): string {
  if (!Number.isFinite(bytes) || bytes < 0) return '—';
  const units = ['B', 'KiB', 'MiB', 'GiB', 'TiB'];
  let v = bytes;
  let u = 0;
  while (v >= 1024 && u < units.length - 1) {
    v /= 1024;
    u += 1;
  }
  return u === 0 ? `${v} B` : `${v.toFixed(1)} ${units[u]}`;
}

/** `2026-01-01T09:30:00Z` → `2026-01-01 09:30:00 UTC`; a log named by `--log` has none. */
export function formatStart(start: string | null): string {
  if (!start) return 'start unknown (named by --log)';
  const m = /^(\d{4}-\d{2}-\d{2})T(\d{2}:\d{2}:\d{2})Z$/.exec(start);
  return m ? `${m[1]} ${m[2]} UTC` : start;
}

/** The row's summary: start, size and whether this run is still writing it. */
export function logSummary(e: LogEntry): string {
  return `${formatStart(e.start_time)} · ${formatBytes(e.size_bytes)}${e.current ? ' · live (this run)' : ''}`;
}

/** What went wrong with `what` (e.g. `report of X`), in the operator's words. */
export function logFailure(what: string, e: unknown): string {
  if (e instanceof ApiError) {
    if (e.status === 401) return `${what}: the API token was refused (401); reload the page and enter the right token`;
    if (e.status === 404) return `${what}: not found (404): ${e.body.message}`;
    if (e.status === 0) return `${what}: kestrel unreachable (not running, or the network is down)`;
    return `${what}: kestrel answered ${e.status}: ${e.body.message}`;
  }
  return `${what}: ${String(e)}`;
}
