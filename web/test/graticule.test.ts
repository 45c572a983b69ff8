import { describe, expect, it } from 'vitest';
import { formatLat, formatLon, graticule, graticuleStep, stepDecimals } from '../src/lib/graticule';

describe('graticule', () => {
  it('picks a round step giving a few lines', () => {
    expect(graticuleStep(0.001, 5)).toBeCloseTo(0.0002, 12);
    expect(graticuleStep(0.0009, 4)).toBeCloseTo(0.0005, 12);
    expect(graticuleStep(3, 4)).toBe(1);
    expect(graticuleStep(0, 4)).toBeCloseTo(1e-6, 12);
  });

  it('labels with the decimals the step needs, hemispheres spelled out', () => {
    expect(stepDecimals(0.0002)).toBe(4);
    expect(stepDecimals(1)).toBe(0);
    expect(formatLat(47.3978, 4)).toBe('47.3978° N');
    expect(formatLat(-33.85, 2)).toBe('33.85° S');
    expect(formatLon(-0.1278, 4)).toBe('0.1278° W');
    expect(formatLon(8.5456, 4)).toBe('8.5456° E');
  });

  it('puts lines inside the bounds at multiples of the step', () => {
    const g = graticule(47.3975, 8.5450, 47.3985, 8.5470);
    expect(g.lats.length).toBeGreaterThanOrEqual(2);
    expect(g.lons.length).toBeGreaterThan(g.lats.length);
    for (const l of g.lats) {
      expect(l.value_deg).toBeGreaterThanOrEqual(47.3975);
      expect(l.value_deg).toBeLessThanOrEqual(47.3985);
      expect(Math.abs(l.value_deg / g.step_deg - Math.round(l.value_deg / g.step_deg))).toBeLessThan(1e-6);
    }
    expect(g.lats[0].label).toMatch(/^47\.39\d\d° N$/);
  });

  it('stays bounded when the bounds are huge', () => {
    const g = graticule(-85, -1e6, 85, 1e6);
    expect(g.lons.length).toBeLessThanOrEqual(40);
  });
});
