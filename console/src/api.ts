// Same-origin API calls with the session's bearer token, and errors shown in place.

import { h, clear } from './dom';
import type { components as KnowledgeDoc } from './wire/knowledge';
import type { components as FleetDoc } from './wire/fleet';

const TOKEN_KEY = 'mentalsim.token';

export function token(): string | null {
  return sessionStorage.getItem(TOKEN_KEY);
}
export function setToken(t: string | null): void {
  if (t) sessionStorage.setItem(TOKEN_KEY, t);
  else sessionStorage.removeItem(TOKEN_KEY);
}

/** An HTTP error: the service's `{"error": {"code", "message", "field"?, "details"?}}` body
 *  (`ErrorBody`), or a failure to reach the service (`code` "network", status 0). */
export class ApiError extends Error {
  constructor(
    public status: number,
    /** The body's `code` (an `ErrorCode`), else `http_<status>` or `network`. */
    public code: string,
    message: string,
    public details: ErrorDetail['details'] = null,
    /** The request field at fault, as a dotted path into the request's JSON (`payload.minutes`,
     *  `options.people_hour`, `goal`), when the service names one: forms point at it by this. */
    public field: string | null = null,
  ) {
    super(message);
  }
}

export interface RequestOptions {
  method?: string;
  body?: unknown;
  headers?: Record<string, string>;
  signal?: AbortSignal;
  /** No Authorization header (public endpoints). */
  anonymous?: boolean;
}

function headersFor(opts: RequestOptions): Headers {
  const headers = new Headers(opts.headers);
  const t = token();
  if (t && !opts.anonymous) headers.set('Authorization', `Bearer ${t}`);
  if (opts.body !== undefined && !(opts.body instanceof FormData) && typeof opts.body !== 'string') {
    headers.set('Content-Type', 'application/json');
  }
  return headers;
}

export async function request(path: string, opts: RequestOptions = {}): Promise<Response> {
  let body: BodyInit | undefined;
  if (opts.body instanceof FormData || typeof opts.body === 'string') body = opts.body;
  else if (opts.body !== undefined) body = JSON.stringify(opts.body);
  let res: Response;
  try {
    res = await fetch(path, { method: opts.method ?? 'GET', headers: headersFor(opts), body, signal: opts.signal });
  } catch (e) {
    if ((e as Error).name === 'AbortError') throw e;
    throw new ApiError(0, 'network', `the service cannot be reached: ${(e as Error).message}`);
  }
  if (!res.ok) throw await errorOf(res);
  return res;
}

export async function errorOf(res: Response): Promise<ApiError> {
  let code = `http_${res.status}`;
  let message = res.statusText || `HTTP ${res.status}`;
  let details: ErrorDetail['details'] = null;
  let field: string | null = null;
  try {
    const text = await res.text();
    try {
      const body = JSON.parse(text) as Partial<ErrorBody> | null;
      const e = body && typeof body === 'object' ? body.error : undefined;
      if (e && typeof e === 'object') {
        code = e.code ?? code;
        message = e.message ?? message;
        details = e.details ?? null;
        field = typeof e.field === 'string' && e.field ? e.field : null;
      } else if (text) message = text.slice(0, 500);
    } catch {
      if (text) message = text.slice(0, 500);
    }
  } catch {
    /* no body */
  }
  if (res.status === 401) onUnauthorized?.();
  return new ApiError(res.status, code, message, details, field);
}

/** Called on any 401 (the app signs out). */
export let onUnauthorized: (() => void) | null = null;
export function setOnUnauthorized(f: () => void): void {
  onUnauthorized = f;
}

export async function getJson<T>(path: string, opts: RequestOptions = {}): Promise<T> {
  const res = await request(path, { ...opts, headers: { Accept: 'application/json', ...opts.headers } });
  return (await res.json()) as T;
}

export async function postJson<T>(path: string, body: unknown, opts: RequestOptions = {}): Promise<T> {
  const res = await request(path, { ...opts, method: 'POST', body, headers: { Accept: 'application/json', ...opts.headers } });
  const text = await res.text();
  return (text ? JSON.parse(text) : null) as T;
}

export async function getBlob(path: string, opts: RequestOptions = {}): Promise<Blob> {
  const res = await request(path, opts);
  return res.blob();
}

/** Renders an error into `box` (a role=alert element near the control that caused it). */
export function showError(box: HTMLElement, e: unknown, prefix = ''): void {
  clear(box);
  box.hidden = false;
  box.classList.add('error');
  box.setAttribute('role', 'alert');
  delete box.dataset.field;
  if (e instanceof ApiError) {
    if (e.field) box.dataset.field = e.field;
    box.append(
      h('strong', null, prefix, e.status ? `${e.status} ${e.code}` : e.code),
      ': ',
      e.message,
    );
    const list = detailLines(e.details);
    if (list.length) box.append(h('ul', null, list.map((l) => h('li', null, l))));
  } else {
    box.append(h('strong', null, prefix, 'error'), ': ', (e as Error)?.message ?? String(e));
  }
}

export function clearError(box: HTMLElement): void {
  clear(box);
  box.hidden = true;
}

/** An item of an error's `details` (the schema leaves them open): a problem and its field. */
interface DetailItem { field?: string; message?: string; [k: string]: unknown }

function detailLines(d: unknown): string[] {
  if (!d) return [];
  if (Array.isArray(d)) {
    return d.slice(0, 20).map((x) => {
      if (x && typeof x === 'object') {
        const o = x as DetailItem;
        if (o.message) return o.field ? `${o.field}: ${o.message}` : String(o.message);
      }
      return typeof x === 'string' ? x : JSON.stringify(x);
    });
  }
  if (typeof d === 'object') {
    const o = d as Record<string, unknown>;
    if (Array.isArray(o.problems)) return detailLines(o.problems);
    if (typeof o.message === 'string') return [o.field ? `${o.field}: ${o.message}` : o.message];
    return Object.entries(o)
      .filter(([k]) => k !== 'attempts')
      .slice(0, 12)
      .map(([k, v]) => `${k}: ${typeof v === 'object' ? JSON.stringify(v) : String(v)}`);
  }
  return [String(d)];
}

// ---- wire types: the schemas of openapi/*.json, generated into src/wire/ (npm run wire) ----

type Knowledge = KnowledgeDoc['schemas'];
type Fleet = FleetDoc['schemas'];

export type ErrorBody = Fleet['ErrorBody'];
export type ErrorDetail = Fleet['ErrorDetail'];
export type Me = Knowledge['Me'];
export type MapView = Knowledge['MapView'];
export type PlaceView = Knowledge['PlaceView'];
export type RobotView = Knowledge['RobotView'];
export type ObjectView = Knowledge['ObjectView'];
export type Point = Fleet['Point'];
export type Pose = Fleet['Pose'];
export type RoadmapView = Fleet['RoadmapView'];
export type EdgeView = Fleet['EdgeView'];
export type PlanApiRequest = Fleet['PlanApiRequest'];
export type PlanOptions = Fleet['PlanOptions'];
export type PlanApiResponse = Fleet['PlanApiResponse'];
export type AttemptReport = Fleet['AttemptReport'];
export type AttemptTrace = Fleet['AttemptTrace'];
export type LegReport = Fleet['LegReport'];
export type NewJobRequest = Fleet['NewJobRequest'];
export type TrainPayload = Fleet['TrainPayload'];
export type EvaluatePayload = Fleet['EvaluatePayload'];
export type JobView = Fleet['JobView'];
export type PolicySummary = Fleet['PolicySummary'];
export type TimedPose = Fleet['TimedPose'];
export type Itinerary = Fleet['Itinerary'];
export type FloorTraffic = Fleet['FloorTraffic'];
