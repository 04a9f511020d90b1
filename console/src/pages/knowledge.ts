// Knowledge: YASGUI bound to /sparql (loaded only here), example queries for the TOSM model,
// and a browser for one place, object or robot part: its explicit, implicit and symbolic
// properties (tosm:belongsToModel says which) and its links, entailed ones marked.

import { h, clear, field, localName } from '../dom';
import { request, showError, clearError, token } from '../api';
import * as data from '../data';
import type { PageContext, Cleanup } from '../main';

const TOSM = 'https://mentalsim.dev/ontology/tosm#';
const INFERRED = 'https://mentalsim.dev/graph/inferred';
const PREFIXES: Record<string, string> = {
  tosm: TOSM,
  rdf: 'http://www.w3.org/1999/02/22-rdf-syntax-ns#',
  rdfs: 'http://www.w3.org/2000/01/rdf-schema#',
  owl: 'http://www.w3.org/2002/07/owl#',
  xsd: 'http://www.w3.org/2001/XMLSchema#',
  skos: 'http://www.w3.org/2004/02/skos/core#',
  dcterms: 'http://purl.org/dc/terms/',
  qudt: 'http://qudt.org/schema/qudt/',
  unit: 'http://qudt.org/vocab/unit/',
  sosa: 'http://www.w3.org/ns/sosa/',
  building: 'https://mentalsim.dev/data/buildings/',
  robot: 'https://mentalsim.dev/data/robots/',
};
const PROLOGUE = Object.entries(PREFIXES).map(([p, iri]) => `PREFIX ${p}: <${iri}>`).join('\n');

// The store keeps every dataset in its own named graph (bundled data, imported maps, robots'
// reports, entailments): the examples match inside GRAPH patterns.
export const EXAMPLES: { title: string; query: string }[] = [
  {
    title: 'Floors and their rooms',
    query: `SELECT ?floor ?floorName ?place ?kind ?name WHERE {
  GRAPH ?g1 { ?floor a tosm:Floor ; tosm:name ?floorName . }
  GRAPH ?g2 { ?place tosm:isDirectlyInsideOf ?floor ; a ?k ; tosm:name ?name . }
  VALUES ?k { tosm:Room tosm:Corridor tosm:Hall }
  BIND(STRAFTER(STR(?k), "#") AS ?kind)
}
ORDER BY ?floorName ?kind ?name`,
  },
  {
    title: 'Objects by class',
    query: `SELECT ?class (COUNT(DISTINCT ?object) AS ?objects) (GROUP_CONCAT(DISTINCT ?name; separator=", ") AS ?names) WHERE {
  GRAPH ?g { ?object a ?class ; tosm:name ?name . }
  GRAPH ?o { ?class rdfs:subClassOf* tosm:Object . }
  FILTER(?class != tosm:Object)
}
GROUP BY ?class
ORDER BY DESC(?objects)`,
  },
  {
    title: 'Objects with pose, shape and colour',
    query: `SELECT ?name ?x ?y ?yaw ?length ?width ?height ?colour WHERE {
  GRAPH ?g {
    ?object tosm:name ?name ; tosm:hasPose ?pose ; tosm:hasShape ?shape .
    ?pose tosm:xM ?x ; tosm:yM ?y .
    OPTIONAL { ?pose tosm:yawRad ?yaw }
    OPTIONAL { ?shape tosm:lengthM ?length ; tosm:widthM ?width ; tosm:heightM ?height }
    OPTIONAL { ?object tosm:colourName ?colour }
  }
  FILTER NOT EXISTS { GRAPH ?r { ?object a ?t . ?t rdfs:subClassOf* tosm:RobotPart } }
}
ORDER BY ?name`,
  },
  {
    title: 'Robots and their lasers',
    query: `SELECT ?robot ?robotName ?laser ?min ?max ?samples ?angle ?hz WHERE {
  GRAPH ?g {
    ?robot tosm:name ?robotName ; tosm:hasSensor ?laser .
    ?laser a tosm:LaserRangeFinder ; tosm:rangeMinM ?min ; tosm:rangeMaxM ?max .
    OPTIONAL { ?laser tosm:sampleCount ?samples }
    OPTIONAL { ?laser tosm:viewAngleRad ?angle }
    OPTIONAL { ?laser tosm:frameRateHz ?hz }
  }
}`,
  },
  {
    title: 'Which places connect to which',
    query: `SELECT DISTINCT ?a ?b WHERE {
  GRAPH ?g { ?p tosm:isConnectedTo ?q . ?p tosm:name ?a . }
  GRAPH ?h { ?q tosm:name ?b . }
  FILTER(STR(?a) < STR(?b))
}
ORDER BY ?a ?b`,
  },
  {
    title: 'Properties by TOSM model',
    query: `SELECT ?model ?property ?label WHERE {
  GRAPH ?g { ?property tosm:belongsToModel ?model . OPTIONAL { ?property rdfs:label ?label } }
}
ORDER BY ?model ?property`,
  },
  {
    title: 'Named graphs and their sizes',
    query: `SELECT ?graph (COUNT(*) AS ?triples) WHERE { GRAPH ?graph { ?s ?p ?o } }
GROUP BY ?graph
ORDER BY DESC(?triples)`,
  },
  {
    title: 'Entailed containment (isInsideOf, from the inferred graph)',
    query: `SELECT ?inner ?outer WHERE {
  GRAPH <${INFERRED}> { ?i tosm:isInsideOf ?o . }
  GRAPH ?g1 { ?i tosm:name ?inner . }
  GRAPH ?g2 { ?o tosm:name ?outer . }
}
ORDER BY ?outer ?inner
LIMIT 200`,
  },
];

interface Binding { type: 'uri' | 'literal' | 'bnode' | 'triple'; value: string; datatype?: string; 'xml:lang'?: string }
type Row = Record<string, Binding | undefined>;

async function select(query: string): Promise<Row[]> {
  const res = await request('/sparql', {
    method: 'POST',
    body: `${PROLOGUE}\n${query}`,
    headers: { 'Content-Type': 'application/sparql-query', Accept: 'application/sparql-results+json' },
  });
  const j = await res.json();
  return j.results.bindings as Row[];
}

interface YasguiLike { getTab(): { setQuery(q: string): unknown; query(): Promise<unknown> } | undefined; destroy(): void; on(e: string, f: (...a: unknown[]) => void): void }
interface YasguiClass {
  new (el: HTMLElement, cfg: unknown): YasguiLike;
  Yasqe: { defaults: { autocompleters: string[] } };
}

export async function mount(root: HTMLElement, ctx: PageContext): Promise<Cleanup> {
  root.append(h('h1', { id: 'page-title' }, 'Knowledge'));
  const browser = h('section', { class: 'card', 'aria-labelledby': 'browse-title' });
  const sparql = h('section', { class: 'card', 'aria-labelledby': 'sparql-title' });
  root.append(browser, sparql);
  browserSection(browser, ctx);
  const editor = new SparqlEditor(sparql);
  await editor.load();
  return () => editor.destroy();
}

/** The form that browses an IRI (from the address's `?iri=`), its result, links browsing in place. */
function browserSection(browser: HTMLElement, ctx: PageContext): void {
  const iriIn = h('input', { type: 'url', name: 'iri', list: 'known-iris', size: 60, autocomplete: 'off', value: ctx.query.get('iri') ?? '' });
  const known = h('datalist', { id: 'known-iris' });
  const out = h('div', { id: 'browse-result', 'aria-live': 'polite' });
  const err = h('div', { hidden: true });
  const form = h('form', { class: 'inline', 'aria-label': 'Browse an IRI' }, field('IRI of a place, object, robot or part', iriIn), known, h('button', { type: 'submit' }, 'Show'));
  browser.append(h('h2', { id: 'browse-title' }, 'Browse a place or object'), form, err, out);
  void Promise.all([data.places(), data.robots()]).then(([ps, rs]) => {
    for (const p of [...ps, ...rs]) known.append(h('option', { value: p.iri }, p.name));
    if (!iriIn.value && ps[0]) iriIn.value = (ps.find((p) => p.kind === 'room') ?? ps[0]).iri;
  }, () => undefined);
  form.addEventListener('submit', (e) => {
    e.preventDefault();
    history.pushState(null, '', `#/knowledge?iri=${encodeURIComponent(iriIn.value.trim())}`);
    void browse(iriIn.value.trim(), out, err);
  });
  if (ctx.query.get('iri')) void browse(ctx.query.get('iri')!, out, err);
  // Links between resources browse in place (the editor stays); the address follows.
  out.addEventListener('click', (e) => {
    const a = (e.target as Element).closest('a');
    const m = a && /^#\/knowledge\?iri=(.*)$/.exec(a.getAttribute('href') ?? '');
    if (!m) return;
    e.preventDefault();
    history.pushState(null, '', a!.getAttribute('href')!);
    iriIn.value = decodeURIComponent(m[1]);
    void browse(iriIn.value, out, err);
    browser.scrollIntoView();
  });
}

/** YASGUI bound to /sparql with the session's token, loaded on demand, and the example queries. */
class SparqlEditor {
  private readonly host = h('div', { id: 'yasgui', class: 'yasgui-host' });
  private readonly yErr = h('div', { hidden: true });
  private yasgui: YasguiLike | null = null;
  private alive = true;

  constructor(sparql: HTMLElement) {
    const examples = h('ul', { class: 'examples' });
    sparql.append(
      h('h2', { id: 'sparql-title' }, 'SPARQL'),
      h('p', { class: 'hint' }, 'Queries go to ', h('code', null, '/sparql'), ' (POST, with your token); the data lives in named graphs, entailments in ', h('code', null, INFERRED), '.'),
      h('h3', null, 'Example queries'), examples, this.yErr, h('p', { class: 'status', id: 'yasgui-status', 'aria-live': 'polite' }, 'Loading the editor…'), this.host,
    );
    for (const ex of EXAMPLES) {
      examples.append(h('li', null, h('button', { type: 'button', class: 'link', onclick: () => void this.run(ex.query) }, ex.title)));
    }
  }

  private async run(query: string): Promise<void> {
    const tab = this.yasgui?.getTab();
    if (!tab) return;
    tab.setQuery(`${PROLOGUE}\n\n${query}\n`);
    try {
      await tab.query();
    } catch {
      /* YASR shows it */
    }
  }

  async load(): Promise<void> {
    const { host } = this;
    try {
      const [{ default: Yasgui }] = await Promise.all([import('@zazuko/yasgui'), import('@zazuko/yasgui/build/yasgui.min.css')]);
      if (!this.alive) return;
      const yasgui = this.create(Yasgui as unknown as YasguiClass);
      this.yasgui = yasgui;
      yasgui.on('queryResponse', () => {
        host.dataset.responses = String(Number(host.dataset.responses ?? '0') + 1);
      });
      // Tab and Shift+Tab leave the editor (keyboard users could not get out of it otherwise);
      // indentation is still Ctrl+] / Ctrl+[.
      const freeTab = () => {
        const yq = (yasgui.getTab() as unknown as { getYasqe?: () => { getOption(k: string): unknown; setOption(k: string, v: unknown): void } } | undefined)?.getYasqe?.();
        if (yq) yq.setOption('extraKeys', { ...((yq.getOption('extraKeys') as object) ?? {}), Tab: false, 'Shift-Tab': false });
      };
      freeTab();
      yasgui.on('tabSelect', () => setTimeout(freeTab));
      yasgui.on('tabAdd', () => setTimeout(freeTab));
      host.dataset.ready = '1';
      const st = document.getElementById('yasgui-status');
      if (st) st.textContent = 'Ctrl+Enter or the ▶ button runs the query.';
      labelYasgui(host);
    } catch (e) {
      showError(this.yErr, e, 'YASGUI: ');
    }
  }

  private create(Y: YasguiClass): YasguiLike {
    // Only completions that need no other server (LOV's class and property completers call out).
    Y.Yasqe.defaults.autocompleters = Y.Yasqe.defaults.autocompleters.filter((a) => a === 'prefixes' || a === 'variables');
    const endpoint = `${location.origin}/sparql`;
    return new Y(this.host, {
      requestConfig: {
        endpoint,
        method: 'POST',
        headers: () => ({ Authorization: `Bearer ${token() ?? ''}` }),
        acceptHeaderSelect: 'application/sparql-results+json,*/*;q=0.9',
        acceptHeaderGraph: 'text/turtle,*/*;q=0.9',
      },
      copyEndpointOnNewTab: true,
      persistenceId: null,
      populateFromUrl: false,
      autofocus: false,
      endpointCatalogueOptions: { getData: () => [{ endpoint }], keys: [] },
      yasqe: { value: `${PROLOGUE}\n\n${EXAMPLES[0].query}\n`, resizeable: true, editorHeight: '260px' },
      yasr: { prefixes: PREFIXES, persistencyExpire: 0 },
    });
  }

  destroy(): void {
    this.alive = false;
    this.yasgui?.destroy();
  }
}

/** YASGUI leaves a few controls without accessible names: give them one. */
function labelYasgui(host: HTMLElement): void {
  const fix = () => {
    host.querySelectorAll<HTMLElement>('input, select, textarea, button, [tabindex]').forEach((el) => {
      if (el.getAttribute('aria-label') || el.getAttribute('aria-labelledby') || el.title) return;
      if (el instanceof HTMLButtonElement && el.textContent?.trim()) return;
      const guess = el.getAttribute('placeholder') || el.className.toString().split(/\s+/)[0] || el.tagName.toLowerCase();
      el.setAttribute('aria-label', guess.replace(/[_-]+/g, ' '));
    });
  };
  fix();
  new MutationObserver(fix).observe(host, { childList: true, subtree: true });
}

// ---- browse ----

const MODEL_NAMES: Record<string, string> = {
  [`${TOSM}ExplicitModel`]: 'Explicit model (what sensors perceive)',
  [`${TOSM}ImplicitModel`]: 'Implicit model (known or inferred)',
  [`${TOSM}SymbolicModel`]: 'Symbolic model (names)',
};

async function browse(iri: string, out: HTMLElement, err: HTMLElement): Promise<void> {
  clear(out);
  clearError(err);
  const esc = iri.replace(/[<>"{}|^`\\\s]/g, '');
  out.append(h('p', { class: 'status' }, 'Querying…'));
  let rows: Row[], nested: Row[];
  try {
    [rows, nested] = await Promise.all([
      select(`SELECT ?dir ?p ?o ?g ?model ?oname WHERE {
  { GRAPH ?g { <${esc}> ?p ?o } BIND("out" AS ?dir) }
  UNION
  { GRAPH ?g { ?o ?p <${esc}> } BIND("in" AS ?dir) }
  OPTIONAL { GRAPH ?mg { ?p tosm:belongsToModel ?model } }
  OPTIONAL { GRAPH ?ng { ?o tosm:name ?oname } }
} LIMIT 2000`),
      // Its descriptors (pose, shape, boundary points, map: IRIs named after it) inline.
      select(`SELECT ?link ?s ?p ?o WHERE {
  VALUES ?link { tosm:hasPose tosm:hasMountingPose tosm:hasShape tosm:hasBoundaryPoint tosm:hasMetricMap }
  GRAPH ?g { <${esc}> ?link ?s . ?s ?p ?o . }
  FILTER(isIRI(?s) && STRSTARTS(STR(?s), "${esc}/") && ?p != rdf:type)
} LIMIT 2000`),
    ]);
  } catch (e) {
    clear(out);
    showError(err, e);
    return;
  }
  clear(out);
  if (!rows.length) {
    out.append(h('p', null, `Nothing is said about ${iri}.`));
    return;
  }
  const name = rows.find((r) => r.dir?.value === 'out' && r.p?.value === `${TOSM}name`)?.o?.value;
  const types = rows.filter((r) => r.dir?.value === 'out' && r.p?.value.endsWith('#type') && r.o?.type === 'uri' && !r.o.value.startsWith(PREFIXES.owl)).map((r) => localName(r.o?.value));
  out.append(h('h3', null, name ?? localName(iri), ' ', h('span', { class: 'muted' }, [...new Set(types)].join(', '))), h('p', { class: 'mono small' }, iri));
  const groups = new Map<string, Row[]>();
  for (const r of rows.filter((r) => r.dir?.value === 'out')) {
    const key = MODEL_NAMES[r.model?.value ?? ''] ?? 'Types and other statements';
    if (!groups.has(key)) groups.set(key, []);
    groups.get(key)!.push(r);
  }
  const nestedBy = new Map<string, Row[]>();
  for (const n of nested) {
    const s = n.s!.value;
    if (!nestedBy.has(s)) nestedBy.set(s, []);
    nestedBy.get(s)!.push(n);
  }
  const order = [...Object.values(MODEL_NAMES), 'Types and other statements'];
  for (const g of order) {
    const list = groups.get(g);
    if (!list) continue;
    out.append(h('h4', null, g), table(dedupe(list), nestedBy));
  }
  const incoming = rows.filter((r) => r.dir?.value === 'in');
  if (incoming.length) out.append(h('h4', null, 'Links to it'), table(dedupe(incoming), new Map(), true));
  out.dataset.rows = String(rows.length);
}

function dedupe(rows: Row[]): Row[] {
  const seen = new Map<string, Row>();
  for (const r of rows) {
    const k = `${r.p?.value}|${r.o?.value}|${r.g?.value}`;
    if (!seen.has(k)) seen.set(k, r);
  }
  return [...seen.values()].sort((a, b) => (a.p!.value < b.p!.value ? -1 : 1));
}

function table(rows: Row[], nested: Map<string, Row[]>, incoming = false): HTMLElement {
  return h('table', { class: 'triples' },
    h('thead', null, h('tr', null, h('th', null, 'property'), h('th', null, incoming ? 'from' : 'value'), h('th', null, 'graph'))),
    h('tbody', null, rows.map((r) => h('tr', null,
      h('td', null, h('span', { title: r.p!.value }, curie(r.p!.value))),
      h('td', null, term(r.o!, r.oname?.value), nestedTable(nested.get(r.o!.value))),
      h('td', null, r.g?.value === INFERRED ? h('span', { class: 'badge busy', title: 'materialised entailment' }, 'entailed') : h('span', { class: 'muted', title: r.g?.value }, localName(r.g?.value))),
    ))),
  );
}

function nestedTable(rows: Row[] | undefined): HTMLElement | null {
  if (!rows?.length) return null;
  return h('dl', { class: 'nested' }, rows.flatMap((r) => [h('dt', null, curie(r.p!.value)), h('dd', null, term(r.o!))]));
}

function curie(iri: string): string {
  for (const [p, ns] of Object.entries(PREFIXES)) if (iri.startsWith(ns)) return `${p}:${iri.slice(ns.length)}`;
  return iri;
}

function term(b: Binding, name?: string): HTMLElement | string {
  if (b.type === 'uri') {
    return h('a', { href: `#/knowledge?iri=${encodeURIComponent(b.value)}`, title: b.value }, name ? `${name} (${curie(b.value)})` : curie(b.value));
  }
  const v = b.value.length > 160 ? `${b.value.slice(0, 120)}… (${b.value.length} characters)` : b.value;
  return b['xml:lang'] ? `"${v}"@${b['xml:lang']}` : v;
}
