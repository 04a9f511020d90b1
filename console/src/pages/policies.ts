// Policies: every exported policy, one policy's detail, two side by side; downloads.

import { h, fmt, pct, localName, download } from '../dom';
import { getBlob, getJson, showError, type PolicySummary } from '../api';
import * as data from '../data';
import type { PageContext, Cleanup } from '../main';

export async function mount(root: HTMLElement, ctx: PageContext): Promise<Cleanup> {
  if (ctx.args[0] === 'compare' && ctx.args[1] && ctx.args[2]) return compare(root, ctx.args[1], ctx.args[2]);
  if (ctx.args[0]) return detail(root, ctx.args[0]);
  return list(root, ctx);
}

function evalCell(e: Record<string, unknown> | undefined, key: string): string {
  const v = e?.[key];
  return key.endsWith('rate') ? pct(v) : fmt(v);
}

async function list(root: HTMLElement, ctx: PageContext): Promise<void> {
  root.append(h('h1', { id: 'page-title' }, 'Policies'));
  const err = h('div', { hidden: true });
  root.append(err);
  data.forget('policies');
  let ps: PolicySummary[];
  try {
    ps = await data.policies();
  } catch (e) {
    showError(err, e);
    return;
  }
  if (!ps.length) {
    root.append(h('p', null, 'No policy exported yet: a succeeded ', h('a', { href: '#/jobs' }, 'training job'), ' exports one.'));
    return;
  }
  const picked: string[] = [];
  const compareBtn = h('button', { type: 'button', disabled: true, id: 'compare' }, 'Compare the two selected');
  const hint = h('p', { class: 'hint', 'aria-live': 'polite' }, 'Select two policies to compare them side by side.');
  compareBtn.addEventListener('click', () => ctx.navigate(`#/policies/compare/${picked[0]}/${picked[1]}`));
  root.append(
    h('table', { id: 'policy-list' },
      h('thead', null, h('tr', null, ['compare', 'policy', 'robot', 'place', 'floor', 'created', 'success', 'collision', 'timeout', 'episodes'].map((t) => h('th', null, t)))),
      h('tbody', null, ps.map((p) => {
        const cb = h('input', { type: 'checkbox', 'aria-label': `Compare policy ${p.id}` });
        cb.addEventListener('change', () => {
          if (cb.checked) picked.push(p.id);
          else picked.splice(picked.indexOf(p.id), 1);
          while (picked.length > 2) {
            const drop = picked.shift()!;
            root.querySelectorAll<HTMLInputElement>('tbody input[type=checkbox]').forEach((c) => {
              if (c.getAttribute('aria-label') === `Compare policy ${drop}`) c.checked = false;
            });
          }
          compareBtn.disabled = picked.length !== 2;
          hint.textContent = picked.length === 2 ? `Selected ${picked.join(' and ')}.` : 'Select two policies to compare them side by side.';
        });
        return h('tr', null,
          h('td', null, cb),
          h('td', null, h('a', { href: `#/policies/${encodeURIComponent(p.id)}` }, p.id)),
          h('td', null, localName(p.robot)), h('td', null, p.place ?? '—'), h('td', null, localName(p.floor)),
          h('td', null, p.created ?? '—'),
          h('td', null, evalCell(p.eval, 'success_rate')), h('td', null, evalCell(p.eval, 'collision_rate')),
          h('td', null, evalCell(p.eval, 'timeout_rate')), h('td', null, evalCell(p.eval, 'episodes')),
        );
      })),
    ),
    h('div', { class: 'buttons' }, compareBtn),
    hint,
  );
}

interface Full { summary: PolicySummary; meta: Record<string, unknown> | null }

async function load(id: string): Promise<Full> {
  const one = await getJson<Record<string, unknown>>(`/v1/policies/${encodeURIComponent(id)}`);
  let meta: Record<string, unknown> | null = null;
  try {
    meta = await getJson<Record<string, unknown>>(`/v1/policies/${encodeURIComponent(id)}/policy.json`);
  } catch {
    meta = (one.metadata as Record<string, unknown>) ?? null;
  }
  const summary = ((one.summary as PolicySummary) ?? (one as unknown as PolicySummary));
  return { summary, meta };
}

function downloads(id: string, box: HTMLElement): HTMLElement {
  const err = h('div', { hidden: true });
  const btn = (file: string) => h('button', { type: 'button', onclick: async () => {
    try {
      download(await getBlob(`/v1/policies/${encodeURIComponent(id)}/${file}`), `${id}-${file}`);
    } catch (e) {
      showError(err, e, `${file}: `);
    }
  } }, `Download ${file}`);
  box.append(h('div', { class: 'buttons' }, btn('policy.safetensors'), btn('policy.json')), err);
  return box;
}

async function detail(root: HTMLElement, id: string): Promise<void> {
  root.append(h('p', null, h('a', { href: '#/policies' }, '← all policies')), h('h1', { id: 'page-title' }, `Policy ${id}`));
  const err = h('div', { hidden: true });
  root.append(err);
  try {
    const { summary, meta } = await load(id);
    root.append(
      h('dl', { class: 'kv' },
        ...([['robot', summary.robot], ['place', summary.place], ['floor', summary.floor], ['created', summary.created]] as [string, unknown][])
          .flatMap(([k, v]) => [h('dt', null, k), h('dd', null, String(v ?? '—'))]),
        h('dt', null, 'training job'), h('dd', null, summary.job_id ? h('a', { href: `#/jobs/${summary.job_id}` }, summary.job_id) : '—'),
      ),
      h('h2', null, 'Held-out evaluation'),
      kvTable(summary.eval ?? {}),
      downloads(id, h('div')),
      h('h2', null, 'Metadata (policy.json)'),
      meta ? kvTable(flatten(meta)) : h('p', null, '—'),
    );
  } catch (e) {
    showError(err, e);
  }
}

async function compare(root: HTMLElement, a: string, b: string): Promise<void> {
  root.append(h('p', null, h('a', { href: '#/policies' }, '← all policies')), h('h1', { id: 'page-title' }, 'Compare policies'));
  const err = h('div', { hidden: true });
  root.append(err);
  let A: Full, B: Full;
  try {
    [A, B] = await Promise.all([load(a), load(b)]);
  } catch (e) {
    showError(err, e);
    return;
  }
  const rows = (x: Record<string, unknown>, y: Record<string, unknown>) => {
    const keys = [...new Set([...Object.keys(x), ...Object.keys(y)])].sort();
    return keys.map((k) => {
      const f = (v: unknown) => (k.endsWith('rate') && typeof v === 'number' ? pct(v) : show(v));
      const vx = f(x[k]), vy = f(y[k]);
      return h('tr', { class: vx !== vy ? 'differs' : '' }, h('th', { scope: 'row' }, k), h('td', null, vx), h('td', null, vy));
    });
  };
  const head = h('thead', null, h('tr', null, h('th', null, ''), h('th', null, a), h('th', null, b)));
  const fa = flatten(A.meta ?? {}), fb = flatten(B.meta ?? {});
  root.append(
    h('h2', null, 'Summary and held-out evaluation'),
    h('table', { class: 'compare', id: 'compare-eval' }, head,
      h('tbody', null,
        rows({ robot: A.summary.robot, place: A.summary.place, floor: A.summary.floor, created: A.summary.created, job: A.summary.job_id },
          { robot: B.summary.robot, place: B.summary.place, floor: B.summary.floor, created: B.summary.created, job: B.summary.job_id }),
        rows(prefixed('eval.', A.summary.eval ?? {}), prefixed('eval.', B.summary.eval ?? {})),
      ),
    ),
    h('div', { class: 'split two' }, downloads(a, h('div', null, h('h3', null, a))), downloads(b, h('div', null, h('h3', null, b)))),
    h('h2', null, 'Metadata (policy.json); differing rows are marked'),
    h('table', { class: 'compare', id: 'compare-meta' }, head.cloneNode(true), h('tbody', null, rows(fa, fb))),
  );
}

function prefixed(p: string, o: Record<string, unknown>): Record<string, unknown> {
  return Object.fromEntries(Object.entries(o).map(([k, v]) => [p + k, v]));
}

function show(v: unknown): string {
  if (v === undefined) return '';
  if (typeof v === 'number') return Number.isInteger(v) ? String(v) : v.toPrecision(6).replace(/\.?0+$/, '');
  if (typeof v === 'object') return JSON.stringify(v);
  return String(v);
}

/** Nested objects as dotted keys (arrays longer than 8 summarised). */
function flatten(o: Record<string, unknown>, prefix = '', out: Record<string, unknown> = {}): Record<string, unknown> {
  for (const [k, v] of Object.entries(o)) {
    const key = prefix + k;
    if (v && typeof v === 'object' && !Array.isArray(v)) flatten(v as Record<string, unknown>, key + '.', out);
    else if (Array.isArray(v) && v.length > 8) out[key] = `[${v.length} values]`;
    else out[key] = v;
  }
  return out;
}

function kvTable(o: Record<string, unknown>): HTMLElement {
  const t = h('table', { class: 'kv-table' }, h('tbody', null, Object.entries(o).map(([k, v]) =>
    h('tr', null, h('th', { scope: 'row' }, k), h('td', null, k.endsWith('rate') && typeof v === 'number' ? pct(v) : show(v))))));
  return t;
}

