// A tiny element builder: h('button', {class: 'x', onclick: f}, 'Label').

type Child = Node | string | number | null | undefined | false;
export type Attrs = Record<string, unknown>;

const PROPS = new Set(['value', 'checked', 'selected', 'disabled', 'hidden', 'textContent', 'indeterminate']);

export function h<K extends keyof HTMLElementTagNameMap>(
  tag: K,
  attrs?: Attrs | null,
  ...children: (Child | Child[])[]
): HTMLElementTagNameMap[K] {
  const el = document.createElement(tag);
  if (attrs) {
    for (const [k, v] of Object.entries(attrs)) {
      if (v === undefined || v === null || v === false) continue;
      if (k.startsWith('on') && typeof v === 'function') {
        el.addEventListener(k.slice(2), v as EventListener);
      } else if (PROPS.has(k)) {
        (el as unknown as Record<string, unknown>)[k] = v;
      } else {
        el.setAttribute(k, v === true ? '' : String(v));
      }
    }
  }
  append(el, children);
  return el;
}

export function svg<K extends keyof SVGElementTagNameMap>(tag: K, attrs?: Attrs | null, ...children: Child[]): SVGElementTagNameMap[K] {
  const el = document.createElementNS('http://www.w3.org/2000/svg', tag);
  if (attrs) for (const [k, v] of Object.entries(attrs)) if (v !== undefined && v !== null) el.setAttribute(k, String(v));
  append(el, children);
  return el;
}

function append(el: Element, children: (Child | Child[])[]): void {
  for (const c of children.flat()) {
    if (c === null || c === undefined || c === false) continue;
    el.append(c instanceof Node ? c : String(c));
  }
}

export function clear(el: Element): void {
  el.replaceChildren();
}

let uid = 0;
/** A fresh id for label/for and aria-describedby pairs. */
export function id(prefix = 'c'): string {
  uid += 1;
  return `${prefix}-${uid}`;
}

/** A labelled control: <div class="field"><label for>…</label>control<p class="field-error"></p></div>. */
export function field(label: string, control: HTMLElement, hint?: string): HTMLDivElement {
  const cid = control.id || id('f');
  control.id = cid;
  const err = h('p', { class: 'field-error', id: `${cid}-err`, 'aria-live': 'polite' });
  const described = [`${cid}-err`];
  let hintEl: HTMLElement | null = null;
  if (hint) {
    hintEl = h('p', { class: 'hint', id: `${cid}-hint` }, hint);
    described.push(`${cid}-hint`);
  }
  control.setAttribute('aria-describedby', described.join(' '));
  return h('div', { class: 'field' }, h('label', { for: cid }, label), control, hintEl, err);
}

export function fmt(n: unknown, digits = 2): string {
  if (typeof n !== 'number' || !Number.isFinite(n)) return n === null || n === undefined ? '—' : String(n);
  return Math.abs(n) >= 1e5 || Number.isInteger(n) ? n.toLocaleString('en') : n.toFixed(digits);
}

export function pct(n: unknown): string {
  return typeof n === 'number' && Number.isFinite(n) ? `${(n * 100).toFixed(1)}%` : '—';
}

/** Short local name of an IRI (after the last # or /). */
export function localName(iri: string | null | undefined): string {
  if (!iri) return '—';
  const m = /[#/]([^#/]+)\/?$/.exec(iri);
  return m ? m[1] : iri;
}

export function download(blob: Blob, name: string): void {
  const url = URL.createObjectURL(blob);
  const a = h('a', { href: url, download: name, hidden: true });
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10_000);
}

/** Element.append that skips null/undefined/false. */
export function add(el: Element, ...children: Child[]): void {
  append(el, children);
}
