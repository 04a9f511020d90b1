// Same-origin API calls with the session's bearer token, and errors shown in place.

import { h, clear } from './dom';

const TOKEN_KEY = 'mentalsim.token';

export function token(): string | null {
  return sessionStorage.getItem(TOKEN_KEY);
}
export function setToken(t: string | null): void {
  if (t) sessionStorage.setItem(TOKEN_KEY, t);
  else sessionStorage.removeItem(TOKEN_KEY);
}

export interface ErrorDetailItem { field?: string; message?: string; [k: string]: unknown }

/** An HTTP error: the service's `{"error": {"code", "message", "details"?}}` body. */
export class ApiError extends Error {
  constructor(
    public status: number,
    public code: string,
    message: string,
    public details: unknown = null,
  ) {
    super(message);
  }

  /** The request fields this error names: `details.field`, `details[].field`, or a message
   *  that starts with `payload.<field>:` / `<field>:` or quotes serde's `field \`x\``. */
  fields(): string[] {
    const out = new Set<string>();
    const add = (f: unknown) => {
      if (typeof f === 'string' && f) out.add(f.replace(/^payload\./, ''));
    };
    const d = this.details as unknown;
    if (Array.isArray(d)) d.forEach((x) => add((x as ErrorDetailItem)?.field));
    else if (d && typeof d === 'object') {
      add((d as ErrorDetailItem).field);
      const problems = (d as Record<string, unknown>).problems;
      if (Array.isArray(problems)) problems.forEach((x) => add((x as ErrorDetailItem)?.field));
    }
    let m = /^payload\.([A-Za-z_][\w.]*)\s*:/.exec(this.message);
    if (m) add(m[1]);
    m = /(?:missing|unknown) field `([^`]+)`/.exec(this.message);
    if (m) add(m[1]);
    m = /^([a-z_]+):/.exec(this.message);
    if (m && m[1] !== 'payload') add(m[1]);
    return [...out];
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
  let details: unknown = null;
  try {
    const text = await res.text();
    try {
      const j = JSON.parse(text);
      if (j && typeof j === 'object' && j.error) {
        code = j.error.code ?? code;
        message = j.error.message ?? message;
        details = j.error.details ?? null;
      } else if (text) message = text.slice(0, 500);
    } catch {
      if (text) message = text.slice(0, 500);
    }
  } catch {
    /* no body */
  }
  if (res.status === 401) onUnauthorized?.();
  return new ApiError(res.status, code, message, details);
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
  if (e instanceof ApiError) {
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

function detailLines(d: unknown): string[] {
  if (!d) return [];
  if (Array.isArray(d)) {
    return d.slice(0, 20).map((x) => {
      if (x && typeof x === 'object') {
        const o = x as ErrorDetailItem;
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

// ---- wire types (see openapi/*.json) ----

export interface MapView { width: number; height: number; resolution: number; origin: number[]; free_area_m2?: number }
export interface PlaceView {
  iri: string; id: string | null; name: string; kind: string; parent: string | null;
  connected: string[]; boundary: number[][]; map?: MapView | null; complexity?: number | null;
}
export interface RobotView {
  iri: string; id: string | null; name: string; footprint?: number[] | null; wheel_separation?: number | null;
  wheels: number; joints: number; lasers: number; cameras: number;
}
export type Shape =
  | { kind: 'box'; length: number; width: number; height: number }
  | { kind: 'cylinder'; diameter: number; height: number }
  | { kind: 'sphere'; diameter: number };
export interface ObjectView {
  iri: string; id: string | null; name: string; class: string;
  pose: { x: number; y: number; z: number; yaw: number }; shape: Shape;
  colour: { r: number; g: number; b: number; a: number } | null; placeholder: boolean; is_open: boolean | null;
  /** A colour given as "#rrggbb" instead of linear components. */
  colourHex?: string | null;
}
export interface RoadmapEdge { a: number; b: number; length_m: number; success: number | null; mean_time_s: number | null; kept: boolean | null }
export interface Roadmap {
  kind: 'geometric' | 'policy'; samples: number; seed: number; inflation_m: number;
  nodes: number[][]; edges: RoadmapEdge[]; policy: string | null; note: string | null;
}
export interface Pose { x: number; y: number; yaw?: number }
export interface Attempt {
  attempt: number; leg: number; controller: string; roadmap_seed: number; outcome: string; reason: string;
  simulated_time_s: number; distance_m: number; min_clearance_m: number; replans: number;
  waypoints_reached: number; goals_reached: number; prm_path_length_m: number; end_pose: Pose;
  trajectory?: Pose[]; ranges?: number[][]; path?: number[][]; t?: number[];
}
export interface Leg {
  goal_index: number; controller: string; roadmap: string; attempts: number; roadmap_seed: number;
  simulated_time_s: number; distance_m: number; min_clearance_m: number; replans: number;
}
export interface PlanReport {
  waypoints: Pose[]; goal_indices: number[]; controller: string; controller_description: string;
  legs: Leg[]; attempts: Attempt[]; simulated_time_s: number; distance_m: number; min_clearance_m: number;
  prm_path_length_m: number; waypoint_path_length_m: number; replans: number; trajectory: Pose[];
  roadmap: { samples: number; nodes: number; seed: number; inflation_m: number; cached: boolean; kind: string };
  laser?: { angles_rad: number[]; max_range_m: number };
  robot?: string; floor?: string; policy?: string | null; note?: string | null; service_ms?: number;
}
export interface JobView {
  id: string; kind: string; state: string; payload: Record<string, unknown>; priority: number; attempts: number;
  max_attempts: number; cancel_requested: boolean; created: string; updated: string; run_after: string;
  started?: string | null; finished?: string | null; progress?: Record<string, unknown> | null;
  result?: Record<string, unknown> | null; error?: string | null; checkpoint?: unknown; worker?: string | null; events: string;
}
export interface PolicySummary {
  id: string; robot?: string | null; floor?: string | null; place?: string | null; job_id?: string | null;
  created?: string | null; eval: Record<string, unknown>;
}
export interface Me { name: string; role: 'engineer' | 'robot' | string }
export interface TimedPose { t_s: number; x: number; y: number; yaw: number }
export interface Itinerary {
  plan_id: string; robot: string; floor: string; start_unix_ms: number; trajectory: TimedPose[];
  radius_m: number; tolerance_s: number; expires_unix_ms: number; delay_s: number;
}
export interface FloorTraffic { floor: string; version: number; plans: Itinerary[] }
