// The TypeScript API types (src/shared/api-types.ts) against the schemas of the same name in the
// server's openapi.yaml: the same properties, optional exactly where the schema does not require
// them, and the same kinds of value (null where the schema allows it, literals for enums, arrays of
// the same items, references to the same schemas). Adding a field on one side only fails here.
import { readFileSync } from 'node:fs';
import { resolve } from 'node:path';
import ts from 'typescript';
import { describe as group, expect, it } from 'vitest';
import { parse } from 'yaml';
import { ROOT } from './global-setup';

type Schema = {
  $ref?: string;
  allOf?: Schema[];
  type?: string | string[];
  oneOf?: Schema[];
  anyOf?: Schema[];
  enum?: unknown[];
  const?: unknown;
  items?: Schema;
  minItems?: number;
  maxItems?: number;
  properties?: Record<string, Schema>;
  required?: string[];
};

interface Prop {
  optional: boolean;
  kinds: string;
}

const TYPES_FILE = resolve(ROOT, 'web/src/shared/api-types.ts');
const SCHEMAS = (
  parse(readFileSync(resolve(ROOT, 'backend/omninav/server/openapi.yaml'), 'utf8')) as {
    components: { schemas: Record<string, Schema> };
  }
).components.schemas;

const join = (kinds: Set<string>): string => [...kinds].sort().join(' | ');
const PRIMITIVE: Record<string, string> = { integer: 'number', number: 'number', string: 'string', boolean: 'boolean' };

/** The kinds of value a schema allows, in the words kindsOfNode uses for TypeScript. */
function kindsOfSchema(s: Schema, checked: Set<string>, schemas: Record<string, Schema>): Set<string> {
  if (s.$ref) {
    const name = s.$ref.split('/').pop()!;
    // a schema with its own interface must be referenced by name; any other is checked by shape only
    return checked.has(name) ? new Set([`ref:${name}`]) : kindsOfSchema(schemas[name], checked, schemas);
  }
  const out = new Set<string>();
  // an alternative that only names required properties (anyOf [{required: [frame]}, ...]) says
  // nothing of the value's kind
  const typed = (alt: Schema): boolean => Object.keys(alt).some((k) => k !== 'required' && k !== 'description');
  for (const alt of [...(s.oneOf ?? []), ...(s.anyOf ?? [])].filter(typed))
    for (const k of kindsOfSchema(alt, checked, schemas)) out.add(k);
  if (s.const !== undefined) out.add(JSON.stringify(s.const));
  for (const v of s.enum ?? []) out.add(JSON.stringify(v));
  for (const t of s.type === undefined ? [] : [s.type].flat()) {
    if (t === 'null') out.add('null');
    else if (t === 'object') out.add('object');
    else if (t === 'array') {
      const items = join(kindsOfSchema(s.items ?? {}, checked, schemas));
      const fixed = s.minItems !== undefined && s.minItems === s.maxItems ? `[${s.minItems}]` : '';
      out.add(`array<${items}>${fixed}`);
    } else out.add(PRIMITIVE[t] ?? t);
  }
  if (out.size === 0) out.add('unknown'); // a schema that says nothing of its type
  return out;
}

/** The kinds of value a TypeScript type allows. */
function kindsOfNode(n: ts.TypeNode, local: Set<string>): Set<string> {
  if (ts.isUnionTypeNode(n)) return new Set(n.types.flatMap((t) => [...kindsOfNode(t, local)]));
  if (ts.isParenthesizedTypeNode(n)) return kindsOfNode(n.type, local);
  if (ts.isLiteralTypeNode(n)) {
    if (n.literal.kind === ts.SyntaxKind.NullKeyword) return new Set(['null']);
    if (ts.isStringLiteral(n.literal)) return new Set([JSON.stringify(n.literal.text)]);
    if (ts.isNumericLiteral(n.literal)) return new Set([n.literal.text]);
    return new Set([n.literal.getText()]);
  }
  if (ts.isArrayTypeNode(n)) return new Set([`array<${join(kindsOfNode(n.elementType, local))}>`]);
  if (ts.isTupleTypeNode(n)) {
    const items = new Set(n.elements.flatMap((e) => [...kindsOfNode(e as ts.TypeNode, local)]));
    return new Set([`array<${join(items)}>[${n.elements.length}]`]);
  }
  if (ts.isTypeReferenceNode(n)) {
    const name = n.typeName.getText();
    return new Set([local.has(name) ? `ref:${name}` : 'object']); // Record<..>, Lens, VenueFeatures
  }
  if (ts.isTypeLiteralNode(n)) return new Set(['object']);
  const keyword: Partial<Record<ts.SyntaxKind, string>> = {
    [ts.SyntaxKind.StringKeyword]: 'string',
    [ts.SyntaxKind.NumberKeyword]: 'number',
    [ts.SyntaxKind.BooleanKeyword]: 'boolean',
  };
  return new Set([keyword[n.kind] ?? `unsupported:${n.getText()}`]);
}

/**
 * Each exported interface of a source file: its properties, their optionality and kinds. With
 * `only`, just the interfaces of those names, and a reference to any other local interface (a
 * part of a schema that has no schema of its own) counts as an object.
 */
function interfacesOf(source: string, only?: Set<string>): Map<string, Map<string, Prop>> {
  const file = ts.createSourceFile('api-types.ts', source, ts.ScriptTarget.ES2022, true);
  const decls = file.statements.filter(ts.isInterfaceDeclaration).filter((d) => !only || only.has(d.name.text));
  const local = new Set(decls.map((d) => d.name.text));
  return new Map(
    decls.map((d) => [
      d.name.text,
      new Map(
        d.members
          .filter(ts.isPropertySignature)
          .map((m) => [
            m.name.getText(),
            { optional: m.questionToken !== undefined, kinds: join(kindsOfNode(m.type!, local)) },
          ]),
      ),
    ]),
  );
}

/** What differs between an interface and the schema of its name, one line per difference. */
function differences(source: string, schemas: Record<string, Schema>, only?: Set<string>): string[] {
  const ifaces = interfacesOf(source, only);
  const checked = new Set(ifaces.keys());
  const out: string[] = [];
  for (const [name, props] of ifaces) {
    let s = schemas[name];
    // allOf [{$ref: Base}, {...own}]: the interface extends Base (checked on its own) and adds its own
    if (s?.allOf) s = Object.assign({}, ...s.allOf.filter((p) => !p.$ref)) as Schema;
    if (!s?.properties) {
      out.push(`${name}: no schema of that name with properties in openapi.yaml`);
      continue;
    }
    const required = new Set(s.required ?? []);
    for (const [p, ps] of Object.entries(s.properties)) {
      const t = props.get(p);
      if (!t) {
        out.push(`${name}.${p}: in the schema, not in the TypeScript type`);
        continue;
      }
      if (t.optional === required.has(p))
        out.push(`${name}.${p}: ${required.has(p) ? 'required' : 'optional'} in the schema, not in TypeScript`);
      const want = join(kindsOfSchema(ps, checked, schemas));
      if (t.kinds !== want) out.push(`${name}.${p}: TypeScript ${t.kinds}, schema ${want}`);
    }
    for (const p of props.keys())
      if (!(p in s.properties)) out.push(`${name}.${p}: in the TypeScript type, not in the schema`);
  }
  return out;
}

group('the API types', () => {
  const source = readFileSync(TYPES_FILE, 'utf8');

  it('cover the answer, the venue, its floors and places', () => {
    expect([...interfacesOf(source).keys()]).toEqual(expect.arrayContaining(['Answer', 'Venue', 'Floor', 'Place']));
  });

  it('match openapi.yaml', () => {
    expect(differences(source, SCHEMAS)).toEqual([]);
  });

  it("the admin page's types match openapi.yaml where a schema has their name", () => {
    const admin = readFileSync(resolve(ROOT, 'web/src/admin/types.ts'), 'utf8');
    const named = new Set(['AdminVenue', 'Video', 'WalkPath', 'Job', 'Suggestions', 'Quality', 'Evaluation']);
    expect([...interfacesOf(admin, named).keys()].sort()).toEqual([...named].sort());
    expect(differences(admin, SCHEMAS, named)).toEqual([]);
  });

  it('a field added on one side only, a changed optionality or kind, is found', () => {
    const schemas: Record<string, Schema> = {
      ...SCHEMAS,
      Floor: {
        ...SCHEMAS.Floor,
        properties: { ...SCHEMAS.Floor.properties, level: { type: 'integer' } },
        required: [...(SCHEMAS.Floor.required ?? []), 'level'],
      },
    };
    const changed = source
      .replace('export interface Place {', 'export interface Place {\n  colour?: string;')
      .replace('  plan_url: string | null;', '  plan_url?: string;');
    expect(differences(changed, schemas)).toEqual([
      'Place.colour: in the TypeScript type, not in the schema',
      'Floor.plan_url: required in the schema, not in TypeScript',
      'Floor.plan_url: TypeScript string, schema null | string',
      'Floor.level: in the schema, not in the TypeScript type',
    ]);
  });
});
