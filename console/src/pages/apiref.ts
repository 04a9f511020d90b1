// API: GET /openapi.json (both documents merged) rendered as a reference, $refs resolved.

import { h, add } from '../dom';
import { getJson, showError } from '../api';
import type { PageContext, Cleanup } from '../main';

type Json = Record<string, unknown>;
const METHODS = ['get', 'put', 'post', 'delete', 'patch', 'head', 'options'];

export async function mount(root: HTMLElement, _ctx: PageContext): Promise<Cleanup> {
  root.append(h('h1', { id: 'page-title' }, 'API reference'));
  const err = h('div', { hidden: true });
  root.append(err);
  let doc: Json;
  try {
    doc = await getJson<Json>('/openapi.json', { anonymous: true });
  } catch (e) {
    showError(err, e, 'GET /openapi.json: ');
    return;
  }
  const info = (doc.info ?? {}) as Json;
  add(root,
    h('p', null, h('strong', null, String(info.title ?? '')), ` ${info.version ?? ''} · OpenAPI ${doc.openapi ?? ''}`),
    info.description ? h('p', { class: 'pre-line' }, String(info.description)) : null,
  );
  const paths = (doc.paths ?? {}) as Record<string, Json>;
  const groups = new Map<string, { path: string; method: string; op: Json }[]>();
  for (const [path, item] of Object.entries(paths)) {
    for (const m of METHODS) {
      const op = item[m] as Json | undefined;
      if (!op) continue;
      const tags = (op.tags as string[] | undefined)?.filter(Boolean);
      const tag = tags?.length ? tags[0].replace(/^crate::/, '').replace(/_api$/, '') : groupOf(path);
      if (!groups.has(tag)) groups.set(tag, []);
      groups.get(tag)!.push({ path, method: m, op: { ...op, parameters: [...((item.parameters as unknown[]) ?? []), ...((op.parameters as unknown[]) ?? [])] } });
    }
  }
  const toc = h('nav', { class: 'toc', 'aria-label': 'Operations' });
  const body = h('div', { class: 'api-ops' });
  const sorted = [...groups.entries()].sort(([a], [b]) => a.localeCompare(b));
  for (const [tag, ops] of sorted) {
    const gid = `tag-${slug(tag)}`;
    toc.append(h('h2', null, h('a', { href: `#/api`, onclick: (e: Event) => { e.preventDefault(); document.getElementById(gid)?.scrollIntoView(); } }, tag)));
    body.append(h('h2', { id: gid }, tag));
    for (const { path, method, op } of ops) body.append(operation(doc, path, method, op));
  }
  root.append(h('div', { class: 'split' }, toc, body));
  root.dataset.operations = String([...groups.values()].reduce((s, g) => s + g.length, 0));
  const schemas = ((doc.components as Json | undefined)?.schemas ?? {}) as Record<string, Json>;
  root.append(h('h2', null, 'Schemas'), h('div', null, Object.entries(schemas).sort(([a], [b]) => a.localeCompare(b)).map(([name, s]) =>
    h('details', { id: `schema-${slug(name)}` }, h('summary', null, name), schemaView(doc, s, new Set([name]), 0)))));
}

function groupOf(path: string): string {
  const parts = path.split('/').filter(Boolean);
  if (parts[0] === 'v1') return parts[1] ?? 'v1';
  return parts[0] ?? '/';
}

function slug(s: string): string {
  return s.toLowerCase().replace(/[^a-z0-9]+/g, '-');
}

function resolve(doc: Json, ref: string): Json | null {
  if (!ref.startsWith('#/')) return null;
  let cur: unknown = doc;
  for (const part of ref.slice(2).split('/')) {
    cur = (cur as Json | undefined)?.[part.replace(/~1/g, '/').replace(/~0/g, '~')];
  }
  return (cur as Json) ?? null;
}

function deref(doc: Json, x: Json): Json {
  let cur = x;
  for (let i = 0; i < 10 && typeof cur?.$ref === 'string'; i++) {
    const r = resolve(doc, cur.$ref as string);
    if (!r) break;
    cur = { ...r, ...Object.fromEntries(Object.entries(cur).filter(([k]) => k !== '$ref')) };
  }
  return cur;
}

function operation(doc: Json, path: string, method: string, op: Json): HTMLElement {
  const params = ((op.parameters as Json[]) ?? []).map((p) => deref(doc, p));
  const rb = op.requestBody ? deref(doc, op.requestBody as Json) : null;
  const responses = (op.responses ?? {}) as Record<string, Json>;
  const security = op.security as unknown[] | undefined;
  const pub = Array.isArray(security) && security.length === 0;
  return h('details', { class: 'op', 'data-path': path, 'data-method': method },
    h('summary', null, h('span', { class: `method m-${method}` }, method.toUpperCase()), ' ', h('code', null, path), ' ', h('span', { class: 'muted' }, firstLine(op.summary as string | undefined)), pub ? h('span', { class: 'badge' }, 'public') : null),
    op.summary ? h('p', { class: 'pre-line' }, String(op.summary)) : null,
    op.description ? h('p', { class: 'pre-line' }, String(op.description)) : null,
    params.length ? h('div', null, h('h4', null, 'Parameters'), h('table', null,
      h('thead', null, h('tr', null, ['name', 'in', 'required', 'schema', 'description'].map((t) => h('th', null, t)))),
      h('tbody', null, params.map((p) => h('tr', null,
        h('td', null, h('code', null, String(p.name))), h('td', null, String(p.in)), h('td', null, p.required ? 'yes' : 'no'),
        h('td', null, p.schema ? typeName(doc, p.schema as Json) : ''), h('td', { class: 'pre-line' }, String(p.description ?? '')),
      ))))) : null,
    rb ? h('div', null, h('h4', null, `Request body${rb.required ? ' (required)' : ''}`), rb.description ? h('p', null, String(rb.description)) : null, content(doc, rb.content as Json | undefined)) : null,
    h('h4', null, 'Responses'),
    h('dl', { class: 'responses' }, Object.entries(responses).flatMap(([code, r0]) => {
      const r = deref(doc, r0);
      return [h('dt', null, h('span', { class: `status s${code[0]}` }, code)), h('dd', null, h('span', { class: 'pre-line' }, String(r.description ?? '')), content(doc, r.content as Json | undefined))];
    })),
  );
}

function firstLine(s: string | undefined): string {
  if (!s) return '';
  const line = s.split(/\n|(?<=\.)\s/)[0];
  return line.length > 90 ? `${line.slice(0, 88)}…` : line;
}

function content(doc: Json, c: Json | undefined): HTMLElement | null {
  if (!c) return null;
  return h('div', null, Object.entries(c).map(([type, media]) => {
    const schema = (media as Json).schema as Json | undefined;
    return h('div', { class: 'media' }, h('code', null, type), schema ? schemaView(doc, schema, new Set(), 0) : null);
  }));
}

function typeName(doc: Json, s: Json): HTMLElement | string {
  if (typeof s.$ref === 'string') {
    const name = (s.$ref as string).split('/').pop()!;
    return h('a', { href: '#/api', onclick: (e: Event) => { e.preventDefault(); const d = document.getElementById(`schema-${slug(name)}`) as HTMLDetailsElement | null; if (d) { d.open = true; d.scrollIntoView(); } } }, name);
  }
  const t = s.type;
  if (Array.isArray(t)) return t.join(' | ');
  if (t === 'array' && s.items) {
    const inner = typeName(doc, s.items as Json);
    return typeof inner === 'string' ? `${inner}[]` : h('span', null, inner, '[]');
  }
  if (s.oneOf || s.anyOf) return ((s.oneOf ?? s.anyOf) as Json[]).map((x) => { const n = typeName(doc, x); return typeof n === 'string' ? n : n.textContent; }).join(' | ');
  if (s.enum) return (s.enum as unknown[]).map((v) => JSON.stringify(v)).join(' | ');
  return String(t ?? (s.allOf ? 'allOf' : 'any')) + (s.format ? ` (${s.format})` : '');
}

/** A schema as nested lists, $refs resolved once per path (recursion shown by name). */
function schemaView(doc: Json, s0: Json, seen: Set<string>, depth: number): HTMLElement {
  if (depth > 6) return h('span', { class: 'muted' }, '…');
  if (typeof s0.$ref === 'string') {
    const name = (s0.$ref as string).split('/').pop()!;
    if (seen.has(name)) return h('span', null, typeName(doc, s0), h('span', { class: 'muted' }, ' (recursive)'));
    const next = new Set(seen);
    next.add(name);
    const target = resolve(doc, s0.$ref as string) ?? {};
    return h('div', { class: 'schema' }, h('span', { class: 'schema-name' }, typeName(doc, s0)), schemaView(doc, target, next, depth + 1));
  }
  const s = s0;
  const parts: (HTMLElement | null)[] = [];
  if (s.description && depth > 0) parts.push(h('p', { class: 'muted pre-line' }, String(s.description)));
  for (const k of ['oneOf', 'anyOf', 'allOf'] as const) {
    if (Array.isArray(s[k])) {
      parts.push(h('div', null, h('em', null, k === 'allOf' ? 'all of' : 'one of'), h('ol', null, (s[k] as Json[]).map((x) => h('li', null, schemaView(doc, x, seen, depth + 1))))));
    }
  }
  if (s.properties) {
    const req = new Set((s.required as string[]) ?? []);
    parts.push(h('ul', { class: 'props' }, Object.entries(s.properties as Record<string, Json>).map(([name, p]) =>
      h('li', null, h('code', null, name), req.has(name) ? h('span', { class: 'req', title: 'required' }, ' *') : null, ': ', typeName(doc, p),
        p.description ? h('span', { class: 'muted pre-line' }, ` — ${p.description}`) : null,
        nestedSchema(doc, p, seen, depth)))));
  } else if (!s.oneOf && !s.anyOf && !s.allOf) {
    parts.push(h('span', null, typeName(doc, s)));
    if (s.type === 'array' && s.items) parts.push(nestedSchema(doc, s as Json, seen, depth));
  }
  return h('div', { class: 'schema' }, ...parts);
}

function nestedSchema(doc: Json, p: Json, seen: Set<string>, depth: number): HTMLElement | null {
  const target = p.type === 'array' || (Array.isArray(p.type) && (p.type as string[]).includes('array')) ? (p.items as Json | undefined) : p;
  if (!target) return null;
  if (typeof target.$ref === 'string' || target.properties || target.oneOf || target.allOf) {
    return h('details', null, h('summary', null, 'fields'), schemaView(doc, target, seen, depth + 1));
  }
  return null;
}

