// A behavior's `args_schema` (JSON Schema, as schemars writes it) turned into form fields, and
// field text turned back into argument values. The API stays the judge of validity: the page only
// refuses text it cannot turn into JSON.

import type { JsonSchema } from './types';

export type FieldKind = 'number' | 'integer' | 'string' | 'boolean' | 'enum' | 'json';

export interface FieldSpec {
  name: string;
  kind: FieldKind;
  required: boolean;
  nullable: boolean;
  description: string;
  default: unknown;
  options: string[];
}

function resolveRef(schema: JsonSchema, root: JsonSchema): JsonSchema {
  let s = schema;
  for (let guard = 0; s.$ref && guard < 16; guard++) {
    const name = s.$ref.split('/').pop() ?? '';
    const target = root.$defs?.[name] ?? root.definitions?.[name];
    if (!target) break;
    s = { ...target, ...withoutRef(s) };
  }
  return s;
}

function withoutRef(s: JsonSchema): JsonSchema {
  const { $ref: _ref, ...rest } = s;
  return rest;
}

function typesOf(s: JsonSchema): string[] {
  if (Array.isArray(s.type)) return s.type;
  return s.type ? [s.type] : [];
}

/** Merges `allOf` members and collects properties of a flattened struct. */
function collectObject(
  schema: JsonSchema,
  root: JsonSchema,
): { properties: Record<string, JsonSchema>; required: Set<string> } {
  const s = resolveRef(schema, root);
  const properties: Record<string, JsonSchema> = { ...(s.properties ?? {}) };
  const required = new Set(s.required ?? []);
  for (const part of s.allOf ?? []) {
    const sub = collectObject(part, root);
    Object.assign(properties, sub.properties);
    sub.required.forEach((r) => required.add(r));
  }
  return { properties, required };
}

function enumOptions(s: JsonSchema, root: JsonSchema): string[] | null {
  if (s.enum && s.enum.every((v) => typeof v === 'string')) return s.enum as string[];
  const alts = s.oneOf ?? s.anyOf;
  if (alts && alts.length > 0) {
    const out: string[] = [];
    for (const alt of alts) {
      const a = resolveRef(alt, root);
      if (typeof a.const === 'string') out.push(a.const);
      else if (a.enum && a.enum.every((v) => typeof v === 'string')) out.push(...(a.enum as string[]));
      else return null;
    }
    return out;
  }
  return null;
}

function fieldFor(name: string, raw: JsonSchema, required: boolean, root: JsonSchema): FieldSpec {
  let s = resolveRef(raw, root);
  let nullable = false;
  const alts = s.anyOf ?? s.oneOf;
  if (alts && alts.some((a) => typesOf(a).includes('null'))) {
    nullable = true;
    const rest = alts.filter((a) => !typesOf(a).includes('null'));
    if (rest.length === 1) s = { ...resolveRef(rest[0], root), description: s.description };
  }
  const types = typesOf(s);
  if (types.includes('null')) nullable = true;
  const base = {
    name,
    required,
    nullable,
    description: s.description ?? raw.description ?? '',
    default: raw.default ?? s.default,
  };
  const options = enumOptions(s, root);
  if (options) return { ...base, kind: 'enum', options };
  const kind: FieldKind = types.includes('integer')
    ? 'integer'
    : types.includes('number')
      ? 'number'
      : types.includes('boolean')
        ? 'boolean'
        : types.includes('string')
          ? 'string'
          : 'json';
  return { ...base, kind, options: [] };
}

/** The fields of a behavior's arguments, required ones first, in schema order otherwise. */
export function fieldsOf(schema: JsonSchema | null | undefined): FieldSpec[] {
  if (!schema) return [];
  const { properties, required } = collectObject(schema, schema);
  const fields = Object.entries(properties).map(([name, s]) =>
    fieldFor(name, s, required.has(name), schema),
  );
  return [...fields.filter((f) => f.required), ...fields.filter((f) => !f.required)];
}

/** Turns a field's text into its value: `undefined` means "leave the argument out". */
export function parseField(
  field: FieldSpec,
  text: string,
): { value: unknown } | { error: string } {
  const t = text.trim();
  if (t === '') return { value: undefined };
  switch (field.kind) {
    case 'number':
    case 'integer': {
      const n = Number(t);
      if (!Number.isFinite(n)) return { error: `${field.name}: not a number` };
      return { value: n };
    }
    case 'boolean':
      if (t === 'true' || t === 'false') return { value: t === 'true' };
      return { error: `${field.name}: true or false` };
    case 'string':
    case 'enum':
      return { value: t };
    case 'json':
      try {
        return { value: JSON.parse(t) };
      } catch {
        return { error: `${field.name}: not valid JSON (e.g. [1, 2, 3])` };
      }
  }
}

/** The text a field shows for an argument value. */
export function formatField(value: unknown): string {
  if (value === undefined || value === null) return '';
  if (typeof value === 'object') return JSON.stringify(value);
  return String(value);
}

/** Arguments a new item starts with: the schema's defaults, then the page's own defaults. */
export function defaultArgs(
  schema: JsonSchema | null | undefined,
  preferred: Record<string, unknown> = {},
): Record<string, unknown> {
  const args: Record<string, unknown> = {};
  for (const f of fieldsOf(schema)) {
    if (f.name in preferred) args[f.name] = preferred[f.name];
    else if (f.default !== undefined && f.default !== null) args[f.name] = f.default;
  }
  return args;
}
