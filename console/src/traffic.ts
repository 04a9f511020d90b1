// The fleet's traffic in time, apart from any page: where an itinerary puts its robot at a
// moment (as the service's `Itinerary::pose_at`), the waits it holds, and a colour per robot.

import type { Itinerary, TimedPose } from './api';

/** A place where an itinerary stands still for a while (not counting its parking at the end). */
export interface Wait { x: number; y: number; fromMs: number; toMs: number }

/** Still: moved less than this (m) and turned less than this (rad). */
const STILL_M = 0.05;
const STILL_RAD = 0.1;
/** The shortest stand that counts as a wait, seconds. */
const MIN_WAIT_S = 1;

export function startMs(it: Itinerary): number {
  return it.start_unix_ms + ((it.trajectory[0]?.t_s ?? 0) + it.delay_s) * 1000;
}

export function endMs(it: Itinerary): number {
  return it.start_unix_ms + ((it.trajectory[it.trajectory.length - 1]?.t_s ?? 0) + it.delay_s) * 1000;
}

/** Where the schedule puts the robot at `ms`: interpolated, parked after the end until the
 * expiry, `null` before its first pose or after its expiry. */
export function poseAt(it: Itinerary, ms: number): TimedPose | null {
  const tr = it.trajectory;
  if (!tr.length || ms > it.expires_unix_ms) return null;
  const t = (ms - it.start_unix_ms) / 1000 - it.delay_s;
  if (!(t >= tr[0].t_s)) return null;
  let lo = 0;
  let hi = tr.length;
  while (lo < hi) {
    const mid = (lo + hi) >> 1;
    if (tr[mid].t_s <= t) lo = mid + 1;
    else hi = mid;
  }
  if (lo >= tr.length) return tr[tr.length - 1];
  const a = tr[Math.max(0, lo - 1)];
  const b = tr[lo];
  const span = b.t_s - a.t_s;
  const u = span > 0 ? Math.min(1, Math.max(0, (t - a.t_s) / span)) : 1;
  let dyaw = b.yaw - a.yaw;
  dyaw = Math.atan2(Math.sin(dyaw), Math.cos(dyaw));
  return { t_s: t, x: a.x + u * (b.x - a.x), y: a.y + u * (b.y - a.y), yaw: a.yaw + u * dyaw };
}

/** The stands of at least a second before the last pose: waits the schedule gave the robot. */
export function waits(it: Itinerary): Wait[] {
  const tr = it.trajectory;
  const out: Wait[] = [];
  const at = (s: number) => it.start_unix_ms + (s + it.delay_s) * 1000;
  let i = 0;
  while (i < tr.length - 1) {
    let j = i;
    while (
      j + 1 < tr.length &&
      Math.hypot(tr[j + 1].x - tr[i].x, tr[j + 1].y - tr[i].y) < STILL_M &&
      Math.abs(Math.atan2(Math.sin(tr[j + 1].yaw - tr[i].yaw), Math.cos(tr[j + 1].yaw - tr[i].yaw))) < STILL_RAD
    ) j++;
    if (j < tr.length - 1 && tr[j].t_s - tr[i].t_s >= MIN_WAIT_S) {
      out.push({ x: tr[i].x, y: tr[i].y, fromMs: at(tr[i].t_s), toMs: at(tr[j].t_s) });
    }
    i = Math.max(j, i + 1);
  }
  return out;
}

/** A stable, distinct colour per robot. */
export function robotColour(robot: string): string {
  let hash = 2166136261;
  for (let i = 0; i < robot.length; i++) hash = Math.imul(hash ^ robot.charCodeAt(i), 16777619);
  return `hsl(${(hash >>> 0) % 360}, 70%, 40%)`;
}
