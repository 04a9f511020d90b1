// What the floor and plan pages draw on a map: places, objects, roadmap.

import type { PlaceView, RoadmapView } from './api';
import type { MapObject } from './data';
import { type MapCanvas, polyline, successColour, label } from './mapview';

const AREA_COLOURS: Record<string, string> = {
  room: '#7c3aed',
  corridor: '#0f766e',
  hall: '#b45309',
};

export function drawAreas(ctx: CanvasRenderingContext2D, m: MapCanvas, areas: PlaceView[], names = true): void {
  ctx.lineWidth = 1.5;
  for (const a of areas) {
    const c = AREA_COLOURS[a.kind] ?? '#475569';
    polyline(ctx, m, a.boundary, true);
    ctx.strokeStyle = c;
    ctx.fillStyle = c + '14';
    ctx.setLineDash([]);
    ctx.fill();
    ctx.stroke();
  }
  if (!names) return;
  for (const a of areas) {
    const [cx, cy] = centroid(a.boundary);
    const [sx, sy] = m.toScreen(cx, cy);
    label(ctx, a.name, sx, sy, AREA_COLOURS[a.kind] ?? '#334155');
  }
}

export function centroid(b: number[][]): [number, number] {
  // Area-weighted centroid of a simple polygon (vertex mean when degenerate).
  let a = 0, cx = 0, cy = 0;
  for (let i = 0; i < b.length; i++) {
    const [x0, y0] = b[i];
    const [x1, y1] = b[(i + 1) % b.length];
    const cross = x0 * y1 - x1 * y0;
    a += cross;
    cx += (x0 + x1) * cross;
    cy += (y0 + y1) * cross;
  }
  if (Math.abs(a) < 1e-9) {
    const n = b.length || 1;
    return [b.reduce((s, p) => s + p[0], 0) / n, b.reduce((s, p) => s + p[1], 0) / n];
  }
  return [cx / (3 * a), cy / (3 * a)];
}

export function objectColour(o: MapObject): string {
  return o.colour ?? 'rgba(100, 116, 139, 0.75)';
}

export function drawObjects(ctx: CanvasRenderingContext2D, m: MapCanvas, objects: MapObject[], names = true): void {
  for (const o of objects) {
    const [sx, sy] = m.toScreen(o.pose.x, o.pose.y);
    ctx.save();
    ctx.translate(sx, sy);
    ctx.rotate(-o.pose.yaw);
    ctx.beginPath();
    const s = o.shape;
    if (s.kind === 'box') {
      const L = m.px(s.length), W = m.px(s.width);
      ctx.rect(-L / 2, -W / 2, L, W);
    } else {
      ctx.arc(0, 0, Math.max(1, m.px(s.diameter / 2)), 0, Math.PI * 2);
    }
    ctx.fillStyle = objectColour(o);
    ctx.fill();
    ctx.lineWidth = o.placeholder ? 2 : 1;
    ctx.strokeStyle = o.placeholder ? '#dc2626' : '#1f2937';
    ctx.setLineDash(o.placeholder ? [5, 3] : o.open ? [2, 2] : []);
    ctx.stroke();
    ctx.setLineDash([]);
    ctx.restore();
    if (names && m.scale > 8) label(ctx, o.placeholder ? `${o.name} (placeholder)` : o.name, sx, sy - 12, o.placeholder ? '#b91c1c' : '#1f2937');
  }
}

export function drawRoadmap(ctx: CanvasRenderingContext2D, m: MapCanvas, r: RoadmapView, alpha = 0.9): void {
  const policyAware = r.kind === 'policy';
  ctx.lineWidth = policyAware ? 2 : 1;
  ctx.globalAlpha = alpha;
  for (const e of r.edges) {
    const a = r.nodes[e.a], b = r.nodes[e.b];
    if (!a || !b) continue;
    const [ax, ay] = m.toScreen(a[0], a[1]);
    const [bx, by] = m.toScreen(b[0], b[1]);
    ctx.beginPath();
    ctx.moveTo(ax, ay);
    ctx.lineTo(bx, by);
    ctx.strokeStyle = policyAware ? successColour(e.success ?? null) : '#5b7fa6';
    ctx.setLineDash(policyAware && e.kept === false ? [4, 4] : []);
    ctx.stroke();
  }
  ctx.setLineDash([]);
  ctx.fillStyle = '#1e3a5f';
  for (const n of r.nodes) {
    const [sx, sy] = m.toScreen(n[0], n[1]);
    ctx.fillRect(sx - 1.5, sy - 1.5, 3, 3);
  }
  ctx.globalAlpha = 1;
}
