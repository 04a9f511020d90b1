// An API error next to the control it is about: the service names the request field at fault
// (`error.field`, a dotted path into the request's JSON such as `payload.minutes` or
// `options.seed`), and a form maps those paths to its controls (made with dom.field()).

import { ApiError } from './api';

/** A form's controls by the request field each sets. */
export type FieldControls = Record<string, HTMLElement | undefined>;

/** The path and each enclosing one, innermost first: `payload.config.lr`, `payload.config`,
 *  `payload`; `goals[2].x`, `goals[2]`, `goals`. */
export function enclosing(path: string): string[] {
  const out: string[] = [];
  let p = path;
  while (p) {
    out.push(p);
    const cut = Math.max(p.lastIndexOf('.'), p.lastIndexOf('['));
    p = cut > 0 ? p.slice(0, cut) : '';
  }
  return out;
}

export class FieldErrors {
  private marked: HTMLElement[] = [];

  /** `controls` is asked each time: which control sets a field may depend on the form's state
   *  (a job's kind). */
  constructor(private controls: () => FieldControls) {}

  /** The control that sets `field`, or the one of its nearest enclosing field. */
  controlFor(field: string): HTMLElement | null {
    const controls = this.controls();
    for (const p of enclosing(field)) {
      const el = controls[p];
      if (el) return el;
    }
    return null;
  }

  /** Marks the control of `field` invalid and writes `message` beside it; null when the form
   *  has no control for that field. */
  show(field: string, message: string): HTMLElement | null {
    const el = this.controlFor(field);
    if (!el) return null;
    el.setAttribute('aria-invalid', 'true');
    const err = document.getElementById(`${el.id}-err`);
    if (err) err.textContent = message;
    this.marked.push(el);
    return el;
  }

  /** An API error that names a field this form has: marked, with the error's message beside it
   *  (and focused, with `focus`). False when the error names no field of this form. */
  showError(e: unknown, focus = false): boolean {
    if (!(e instanceof ApiError) || !e.field) return false;
    const el = this.show(e.field, e.message);
    if (el && focus) el.focus();
    return el !== null;
  }

  clear(): void {
    for (const el of this.marked) {
      el.removeAttribute('aria-invalid');
      const err = document.getElementById(`${el.id}-err`);
      if (err) err.textContent = '';
    }
    this.marked = [];
  }
}
