// A small SVG line chart (no library): series of (x, y) points on shared axes.

import { svg, h } from './dom';

export interface Series { name: string; colour: string; points: [number, number][]; dots?: boolean; axis?: 'left' | 'right' }

export function lineChart(title: string, series: Series[], opts: { xLabel: string; yLabel: string; y2Label?: string; yRange?: [number, number] }): HTMLElement {
  const W = 560, H = 240, L = 52, R = opts.y2Label ? 56 : 16, T = 14, B = 36;
  const all = series.flatMap((s) => s.points);
  const left = series.filter((s) => s.axis !== 'right').flatMap((s) => s.points);
  const right = series.filter((s) => s.axis === 'right').flatMap((s) => s.points);
  const xs = all.map((p) => p[0]);
  const x0 = xs.length ? Math.min(...xs) : 0;
  const x1 = xs.length ? Math.max(...xs) : 1;
  const range = (pts: [number, number][], fixed?: [number, number]): [number, number] => {
    if (fixed) return fixed;
    const ys = pts.map((p) => p[1]).filter(Number.isFinite);
    if (!ys.length) return [0, 1];
    let a = Math.min(...ys), b = Math.max(...ys);
    if (a === b) { a -= 1; b += 1; }
    const pad = (b - a) * 0.05;
    return [a - pad, b + pad];
  };
  const [ly0, ly1] = range(left, opts.yRange);
  const [ry0, ry1] = range(right);
  const sx = (x: number) => L + ((x - x0) / Math.max(1e-9, x1 - x0)) * (W - L - R);
  const syL = (y: number) => T + (1 - (y - ly0) / (ly1 - ly0)) * (H - T - B);
  const syR = (y: number) => T + (1 - (y - ry0) / (ry1 - ry0)) * (H - T - B);
  const root = svg('svg', { viewBox: `0 0 ${W} ${H}`, width: '100%', role: 'img', 'aria-label': `${title}: ${series.map((s) => `${s.name} ${s.points.length} points`).join(', ')}`, class: 'chart' });
  root.append(svg('rect', { x: L, y: T, width: W - L - R, height: H - T - B, fill: '#fff', stroke: '#cbd5e1' }));
  const ticks = (a: number, b: number, n = 4) => Array.from({ length: n + 1 }, (_, i) => a + ((b - a) * i) / n);
  for (const v of ticks(ly0, ly1)) {
    root.append(svg('line', { x1: L, x2: W - R, y1: syL(v), y2: syL(v), stroke: '#eef2f7' }));
    root.append(svg('text', { x: L - 4, y: syL(v) + 4, 'text-anchor': 'end', class: 'tick' }, short(v)));
  }
  if (right.length) for (const v of ticks(ry0, ry1)) root.append(svg('text', { x: W - R + 4, y: syR(v) + 4, class: 'tick' }, short(v)));
  for (const v of ticks(x0, x1)) root.append(svg('text', { x: sx(v), y: H - B + 14, 'text-anchor': 'middle', class: 'tick' }, short(v)));
  root.append(svg('text', { x: (L + W - R) / 2, y: H - 4, 'text-anchor': 'middle', class: 'axis' }, opts.xLabel));
  root.append(svg('text', { x: 12, y: (T + H - B) / 2, transform: `rotate(-90 12 ${(T + H - B) / 2})`, 'text-anchor': 'middle', class: 'axis' }, opts.yLabel));
  if (opts.y2Label) root.append(svg('text', { x: W - 6, y: (T + H - B) / 2, transform: `rotate(90 ${W - 6} ${(T + H - B) / 2})`, 'text-anchor': 'middle', class: 'axis' }, opts.y2Label));
  for (const s of series) {
    const sy = s.axis === 'right' ? syR : syL;
    const pts = s.points.filter((p) => Number.isFinite(p[1]));
    if (pts.length > 1 && !s.dots) {
      root.append(svg('polyline', { points: pts.map((p) => `${sx(p[0]).toFixed(1)},${sy(p[1]).toFixed(1)}`).join(' '), fill: 'none', stroke: s.colour, 'stroke-width': 2 }));
    }
    if (s.dots || pts.length === 1) for (const p of pts) root.append(svg('circle', { cx: sx(p[0]), cy: sy(p[1]), r: 3.5, fill: s.colour }));
  }
  const legend = h('div', { class: 'legend' }, series.map((s) => h('span', null, h('span', { class: 'sw', style: `background:${s.colour}`, 'aria-hidden': 'true' }), `${s.name} (${s.points.length})`)));
  return h('figure', { class: 'chart-fig', 'data-points': String(all.length) }, h('figcaption', null, title), root, legend);
}

function short(v: number): string {
  const a = Math.abs(v);
  if (a >= 1e6) return `${(v / 1e6).toFixed(1)}M`;
  if (a >= 1e3) return `${(v / 1e3).toFixed(1)}k`;
  if (a >= 10) return v.toFixed(0);
  return v.toFixed(2);
}
