import { describe, expect, it } from 'vitest';
import { defaultArgs, fieldsOf, parseField } from '../src/lib/schema';
import { parseErrorBody, wsUrl } from '../src/lib/api';
import { gridPixels, mergePatch, readGrid } from '../src/lib/grid';
import type { JsonSchema } from '../src/lib/types';

// What schemars writes for go_to's goal (flattened yaw args, Option fields, an enum by $ref).
const GO_TO: JsonSchema = {
  type: 'object',
  required: ['x', 'y', 'z', 'speed'],
  properties: {
    frame_id: { description: 'Frame of the target', type: ['string', 'null'], default: null },
    speed: { description: 'Cruise speed (m/s).', type: 'number' },
    x: { type: 'number' },
    y: { type: 'number' },
    z: { type: 'number' },
    yaw_mode: { default: 'keep', allOf: [{ $ref: '#/$defs/YawMode' }] },
    face_point: { anyOf: [{ type: 'array', items: { type: 'number' } }, { type: 'null' }] },
  },
  $defs: { YawMode: { type: 'string', enum: ['keep', 'path_facing', 'fixed', 'face_point'] } },
};

describe('schema to form fields', () => {
  const fields = fieldsOf(GO_TO);
  it('puts required fields first and reads kinds', () => {
    expect(fields.map((f) => `${f.name}:${f.kind}${f.required ? '!' : ''}`)).toEqual([
      'speed:number!', 'x:number!', 'y:number!', 'z:number!', 'frame_id:string', 'yaw_mode:json', 'face_point:json',
    ]);
    expect(fields.find((f) => f.name === 'frame_id')?.nullable).toBe(true);
  });
  it('reads an enum behind $ref', () => {
    const f = fieldsOf({ type: 'object', properties: { m: { $ref: '#/$defs/YawMode' } }, $defs: GO_TO.$defs })[0];
    expect(f.kind).toBe('enum');
    expect(f.options).toEqual(['keep', 'path_facing', 'fixed', 'face_point']);
  });
  it('parses field text, leaving the API to judge values', () => {
    const speed = fields[0];
    expect(parseField(speed, '-1')).toEqual({ value: -1 });
    expect(parseField(speed, 'fast')).toEqual({ error: 'speed: not a number' });
    expect(parseField(speed, ' ')).toEqual({ value: undefined });
    const fp = fields.find((f) => f.name === 'face_point')!;
    expect(parseField(fp, '[1, 2, 3]')).toEqual({ value: [1, 2, 3] });
    expect(parseField(fp, '[1,')).toHaveProperty('error');
  });
  it('default args take the page defaults over schema defaults', () => {
    expect(defaultArgs(GO_TO, { speed: 1, z: 3 })).toEqual({ speed: 1, z: 3, yaw_mode: 'keep' });
  });
});

describe('api helpers', () => {
  it('reads the API error body, or makes one', () => {
    expect(parseErrorBody(422, '{"error":{"code":"invalid_mission","message":"bad","details":[{"pointer":"/plan/0","message":"x"}]}}'))
      .toEqual({ code: 'invalid_mission', message: 'bad', details: [{ pointer: '/plan/0', message: 'x' }] });
    expect(parseErrorBody(401, '')).toEqual({ code: 'unauthorized', message: 'wrong or missing token', details: [] });
    expect(parseErrorBody(409, '{"accepted":false,"reason":"busy"}').message).toBe('busy');
  });
  it('builds the WebSocket URL with the token', () => {
    expect(wsUrl('', 'a b', 'http://127.0.0.1:8080/')).toBe('ws://127.0.0.1:8080/api/ws?token=a+b');
    expect(wsUrl('https://k.example:9/', 't', 'http://x/')).toBe('wss://k.example:9/api/ws?token=t');
  });
});

describe('occupancy grid', () => {
  const grid = readGrid({ spec: { resolution_m: 0.5, width: 2, height: 2, origin_m: [-1, -1] }, data: [0, 100, -1, 50] })!;
  it('reads the spec and paints the north row first', () => {
    expect(grid.spec).toEqual({ originX_m: -1, originY_m: -1, resolution_m: 0.5, width: 2, height: 2 });
    const px = gridPixels(grid);
    expect(px[3]).toBe(0); // north-west cell unknown: transparent
    expect([...px.slice(8, 12)]).toEqual([175, 208, 240, 160]); // south-west free: pale blue
    expect(px[12]).toBe(20); // south-east occupied: dark
  });
  it('merges a patch that fits and refuses one that does not', () => {
    const patch = readGrid({ spec: { resolution_m: 0.5, width: 1, height: 1, origin_m: [-0.5, -0.5] }, data: [7] })!;
    expect(mergePatch(grid, patch)).toBe(true);
    expect(grid.data[3]).toBe(7);
    const outside = readGrid({ spec: { resolution_m: 0.5, width: 1, height: 1, origin_m: [5, 5] }, data: [7] })!;
    expect(mergePatch(grid, outside)).toBe(false);
  });
});

import { enuToGeo, geoToEnu, originFrom, readGeofence } from '../src/lib/geo';

describe('local tangent plane', () => {
  it('round-trips ENU through lat/lon and finds the origin from a drone', () => {
    const o = { lat_deg: 40.44, lon_deg: -3.69 };
    const [lat, lon] = enuToGeo(o, 120, -80);
    const [x, y] = geoToEnu(o, lat, lon);
    expect(x).toBeCloseTo(120, 6);
    expect(y).toBeCloseTo(-80, 6);
    const back = originFrom([120, -80, 5], { lat_deg: lat, lon_deg: lon })!;
    expect(back.lat_deg).toBeCloseTo(40.44, 7);
    expect(back.lon_deg).toBeCloseTo(-3.69, 7);
    expect(originFrom([0, 0, 0], null)).toBeNull();
  });
});

describe('geofence', () => {
  it('reads the [geofence] section and ignores what is not one', () => {
    expect(readGeofence({ max_altitude_m: 120, min_altitude_m: 0, radius_m: null, polygon_enu_m: [[0, 0], [10, 0], [10, 10]] })).toEqual({
      polygon_enu_m: [[0, 0], [10, 0], [10, 10]],
      max_altitude_m: 120,
      radius_m: null,
    });
    expect(readGeofence({ polygon_enu_m: [[0, 0]] })).toBeNull();
    expect(readGeofence(null)).toBeNull();
  });
});
