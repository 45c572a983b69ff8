import { describe, expect, it } from 'vitest';
import { ApiError } from '../src/lib/api';
import { formatBytes, formatStart, logFailure, logSummary } from '../src/lib/logs';

describe('logs panel', () => {
  it('gives sizes in binary units', () => {
    expect(formatBytes(0)).toBe('0 B');
    expect(formatBytes(1023)).toBe('1023 B');
    expect(formatBytes(1536)).toBe('1.5 KiB');
    expect(formatBytes(5 * 1024 * 1024)).toBe('5.0 MiB');
    expect(formatBytes(-1)).toBe('—');
  });

  it('reads the start time as UTC and says when a log has none', () => {
    expect(formatStart('2026-01-01T09:30:00Z')).toBe('2026-01-01 09:30:00 UTC');
    expect(formatStart(null)).toMatch(/--log/);
  });

  it('marks the log this run writes as live', () => {
    const e = { name: 'kestrel-sim-2026-01-01T09-30-00Z.jsonl', size_bytes: 2048, start_time: '2026-01-01T09:30:00Z', current: true };
    expect(logSummary(e)).toBe('2026-01-01 09:30:00 UTC · 2.0 KiB · live (this run)');
    expect(logSummary({ ...e, current: false })).not.toMatch(/live/);
  });

  it('words a refused token, a missing log and an unreachable kestrel for the operator', () => {
    const err = (status: number, message: string) => new ApiError(status, { code: `http_${status}`, message, details: [] });
    expect(logFailure('report of a', err(401, 'missing token'))).toMatch(/token was refused \(401\)/);
    expect(logFailure('report of a', err(404, 'no flight log named `a`'))).toBe('report of a: not found (404): no flight log named `a`');
    expect(logFailure('download of a', err(0, 'cannot reach'))).toMatch(/kestrel unreachable/);
    expect(logFailure('download of a', err(400, 'a line over 1 MiB'))).toMatch(/answered 400: a line over 1 MiB/);
  });
});
