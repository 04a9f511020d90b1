// The map canvas: one world <-> screen transform for everything drawn on a floor, pan (drag,
// arrow keys, buttons) and zoom (wheel, +/- keys, buttons), and two layers: a static one
// (map, places, roadmap, trajectories) rendered to an offscreen canvas only when the view or
// the data changes, and a dynamic one (robot, beams, cursor) drawn over it every frame.

import { h } from './dom';
import type { MapView } from './api';

export interface Tool {
  down(x: number, y: number, e: PointerEvent): void;
  move?(x: number, y: number, e: PointerEvent): void;
  up?(x: number, y: number, e: PointerEvent): void;
}

type Layer = (ctx: CanvasRenderingContext2D, m: MapCanvas) => void;

export class MapCanvas {
  readonly el: HTMLDivElement;
  readonly canvas: HTMLCanvasElement;
  readonly toolbar: HTMLDivElement;
  private ctx: CanvasRenderingContext2D;
  private layer: HTMLCanvasElement;
  private layerCtx: CanvasRenderingContext2D;
  private dirty = true;
  private frame = 0;
  /** Screen (CSS px) = (x * scale + tx, -y * scale + ty). */
  scale = 20;
  tx = 0;
  ty = 0;
  cssW = 800;
  cssH = 500;
  private dpr = 1;
  image: ImageBitmap | HTMLImageElement | null = null;
  map: MapView | null = null;
  drawStatic: Layer = () => {};
  drawDynamic: Layer = () => {};
  tool: Tool | null = null;
  onHover: ((x: number, y: number, sx: number, sy: number) => void) | null = null;
  onLeave: (() => void) | null = null;
  /** A primary-button press released where it started (no pan), when no tool is set. */
  onClick: ((x: number, y: number, e: PointerEvent) => void) | null = null;
  onViewChange: (() => void) | null = null;
  private drag: { sx: number; sy: number; tx: number; ty: number; tool: boolean; id: number } | null = null;
  private fitted = false;
  private bounds: [number, number, number, number] | null = null;
  private resizeObs: ResizeObserver;
  draws = 0;

  constructor(label: string) {
    this.canvas = h('canvas', {
      class: 'map-canvas',
      tabindex: 0,
      role: 'img',
      'aria-label': `${label}. Arrow keys pan, + and - zoom, 0 fits the map.`,
    });
    const btn = (text: string, title: string, f: () => void) =>
      h('button', { type: 'button', class: 'icon', title, 'aria-label': title, onclick: f }, text);
    this.toolbar = h(
      'div',
      { class: 'map-tools', role: 'toolbar', 'aria-label': 'Map view' },
      btn('+', 'Zoom in', () => this.zoom(1.25)),
      btn('−', 'Zoom out', () => this.zoom(0.8)),
      btn('⤢', 'Fit the map', () => this.fit()),
      btn('←', 'Pan left', () => this.pan(80, 0)),
      btn('→', 'Pan right', () => this.pan(-80, 0)),
      btn('↑', 'Pan up', () => this.pan(0, 80)),
      btn('↓', 'Pan down', () => this.pan(0, -80)),
    );
    this.el = h('div', { class: 'map-wrap' }, this.toolbar, this.canvas);
    this.ctx = this.canvas.getContext('2d')!;
    this.layer = document.createElement('canvas');
    this.layerCtx = this.layer.getContext('2d')!;
    this.canvas.addEventListener('wheel', (e) => this.onWheel(e), { passive: false });
    this.canvas.addEventListener('pointerdown', (e) => this.onDown(e));
    this.canvas.addEventListener('pointermove', (e) => this.onMove(e));
    this.canvas.addEventListener('pointerup', (e) => this.onUp(e));
    this.canvas.addEventListener('pointercancel', () => (this.drag = null));
    this.canvas.addEventListener('pointerleave', () => this.onLeave?.());
    this.canvas.addEventListener('keydown', (e) => this.onKey(e));
    this.resizeObs = new ResizeObserver(() => this.resize());
    this.resizeObs.observe(this.canvas);
  }

  destroy(): void {
    this.resizeObs.disconnect();
    if (this.frame) cancelAnimationFrame(this.frame);
  }

  /** The floor's occupancy grid and its placement (ROS map_server: row 0 at the top, y up). */
  setMap(image: ImageBitmap | HTMLImageElement | null, map: MapView | null): void {
    this.image = image;
    this.map = map;
    if (map) {
      const [ox, oy] = map.origin;
      this.bounds = [ox, oy, ox + map.width * map.resolution, oy + map.height * map.resolution];
    }
    this.fitted = false;
    this.resize();
  }

  setBounds(b: [number, number, number, number]): void {
    this.bounds = b;
    this.fitted = false;
    this.resize();
  }

  toScreen(x: number, y: number): [number, number] {
    return [x * this.scale + this.tx, -y * this.scale + this.ty];
  }
  toWorld(sx: number, sy: number): [number, number] {
    return [(sx - this.tx) / this.scale, -(sy - this.ty) / this.scale];
  }
  /** World coordinates of a pointer event. */
  eventWorld(e: MouseEvent): [number, number] {
    const r = this.canvas.getBoundingClientRect();
    return this.toWorld(e.clientX - r.left, e.clientY - r.top);
  }

  resize(): void {
    const r = this.canvas.getBoundingClientRect();
    const w = Math.max(50, Math.round(r.width));
    const hgt = Math.max(50, Math.round(r.height));
    const dpr = window.devicePixelRatio || 1;
    if (w !== this.cssW || hgt !== this.cssH || dpr !== this.dpr || this.canvas.width !== Math.round(w * dpr)) {
      this.cssW = w;
      this.cssH = hgt;
      this.dpr = dpr;
      this.canvas.width = this.layer.width = Math.round(w * dpr);
      this.canvas.height = this.layer.height = Math.round(hgt * dpr);
    }
    if (!this.fitted && this.bounds && r.width > 0) this.fit();
    else this.invalidate();
  }

  fit(): void {
    if (!this.bounds) return;
    const [x0, y0, x1, y1] = this.bounds;
    const pad = 12;
    this.scale = Math.min((this.cssW - 2 * pad) / Math.max(1e-6, x1 - x0), (this.cssH - 2 * pad) / Math.max(1e-6, y1 - y0));
    this.tx = this.cssW / 2 - ((x0 + x1) / 2) * this.scale;
    this.ty = this.cssH / 2 + ((y0 + y1) / 2) * this.scale;
    this.fitted = true;
    this.viewChanged();
  }

  zoom(factor: number, sx = this.cssW / 2, sy = this.cssH / 2): void {
    const next = Math.min(2000, Math.max(0.05, this.scale * factor));
    const f = next / this.scale;
    this.tx = sx - (sx - this.tx) * f;
    this.ty = sy - (sy - this.ty) * f;
    this.scale = next;
    this.viewChanged();
  }

  pan(dx: number, dy: number): void {
    this.tx += dx;
    this.ty += dy;
    this.viewChanged();
  }

  private viewChanged(): void {
    const d = this.canvas.dataset;
    d.scale = String(this.scale);
    d.tx = String(this.tx);
    d.ty = String(this.ty);
    this.onViewChange?.();
    this.invalidate();
  }

  /** The static layer must be rendered again (view or data changed). */
  invalidate(): void {
    this.dirty = true;
    this.request();
  }

  /** Draw at the next animation frame (once). */
  request(): void {
    if (this.frame) return;
    this.frame = requestAnimationFrame(() => {
      this.frame = 0;
      this.draw();
    });
  }

  /** Draw now: the static layer if needed, then the dynamic one over it. */
  draw(): void {
    const dpr = this.dpr;
    if (this.dirty) {
      const c = this.layerCtx;
      c.setTransform(1, 0, 0, 1, 0, 0);
      c.fillStyle = '#d9dde3';
      c.fillRect(0, 0, this.layer.width, this.layer.height);
      c.setTransform(dpr, 0, 0, dpr, 0, 0);
      this.drawMapImage(c);
      this.drawStatic(c, this);
      this.dirty = false;
    }
    const ctx = this.ctx;
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.drawImage(this.layer, 0, 0);
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    this.drawDynamic(ctx, this);
    this.draws += 1;
    this.canvas.dataset.draws = String(this.draws);
  }

  private drawMapImage(c: CanvasRenderingContext2D): void {
    if (!this.image || !this.map) return;
    const m = this.map;
    const [ox, oy] = m.origin;
    const [sx, sy] = this.toScreen(ox, oy + m.height * m.resolution);
    const w = m.width * m.resolution * this.scale;
    const hh = m.height * m.resolution * this.scale;
    c.imageSmoothingEnabled = this.scale * m.resolution < 2;
    c.drawImage(this.level(this.scale * m.resolution * this.dpr), sx, sy, w, hh);
    c.imageSmoothingEnabled = true;
  }

  private levels: (HTMLCanvasElement | undefined)[] = [];
  private levelsOf: unknown = null;

  /** The map image halved k times, so that a cell covers about a device pixel: a big map
   *  zoomed out is drawn from a small copy (each halving made once, from the previous one). */
  private level(cellPx: number): CanvasImageSource {
    const img = this.image!;
    if (this.levelsOf !== img) {
      this.levels = [];
      this.levelsOf = img;
    }
    let k = 0;
    while (cellPx * 2 ** (k + 1) <= 1 && k < 8) k++;
    if (k === 0) return img;
    let src: CanvasImageSource = img;
    let w = img.width, hh = img.height;
    for (let i = 1; i <= k; i++) {
      w = Math.max(1, Math.ceil(w / 2));
      hh = Math.max(1, Math.ceil(hh / 2));
      let lv = this.levels[i];
      if (!lv) {
        lv = document.createElement('canvas');
        lv.width = w;
        lv.height = hh;
        const c = lv.getContext('2d')!;
        c.imageSmoothingQuality = 'medium';
        c.drawImage(src, 0, 0, w, hh);
        this.levels[i] = lv;
      }
      src = lv;
    }
    return src;
  }

  /** Metres per CSS pixel → a line width in world units is not needed: we draw in screen space. */
  px(metres: number): number {
    return metres * this.scale;
  }

  private onWheel(e: WheelEvent): void {
    e.preventDefault();
    const r = this.canvas.getBoundingClientRect();
    const dy = e.deltaMode === 1 ? e.deltaY * 16 : e.deltaY;
    this.zoom(Math.pow(1.0015, -dy), e.clientX - r.left, e.clientY - r.top);
  }

  private onDown(e: PointerEvent): void {
    if (e.button !== 0 && e.button !== 1) return;
    const useTool = !!this.tool && e.button === 0 && !e.shiftKey;
    this.canvas.setPointerCapture(e.pointerId);
    this.drag = { sx: e.clientX, sy: e.clientY, tx: this.tx, ty: this.ty, tool: useTool, id: e.pointerId };
    if (useTool) {
      const [x, y] = this.eventWorld(e);
      this.tool!.down(x, y, e);
    }
  }

  private onMove(e: PointerEvent): void {
    const [x, y] = this.eventWorld(e);
    if (this.drag && this.drag.id === e.pointerId) {
      if (this.drag.tool) this.tool?.move?.(x, y, e);
      else {
        this.tx = this.drag.tx + (e.clientX - this.drag.sx);
        this.ty = this.drag.ty + (e.clientY - this.drag.sy);
        this.viewChanged();
      }
    }
    if (this.onHover) {
      const r = this.canvas.getBoundingClientRect();
      this.onHover(x, y, e.clientX - r.left, e.clientY - r.top);
    }
  }

  private onUp(e: PointerEvent): void {
    if (!this.drag || this.drag.id !== e.pointerId) return;
    const d = this.drag;
    this.drag = null;
    const [x, y] = this.eventWorld(e);
    if (d.tool) this.tool?.up?.(x, y, e);
    else if (this.onClick && Math.hypot(e.clientX - d.sx, e.clientY - d.sy) < 4) this.onClick(x, y, e);
  }

  private onKey(e: KeyboardEvent): void {
    const step = 60;
    const keys: Record<string, () => void> = {
      ArrowLeft: () => this.pan(step, 0),
      ArrowRight: () => this.pan(-step, 0),
      ArrowUp: () => this.pan(0, step),
      ArrowDown: () => this.pan(0, -step),
      '+': () => this.zoom(1.25),
      '=': () => this.zoom(1.25),
      '-': () => this.zoom(0.8),
      '0': () => this.fit(),
    };
    const f = keys[e.key];
    if (f) {
      e.preventDefault();
      f();
    }
  }
}

// ---- drawing helpers, all through the canvas's transform ----

/** Success probability → colour (red 0, amber 0.5, green 1). */
export function successColour(p: number | null): string {
  if (p === null || p === undefined || !Number.isFinite(p)) return '#5b7fa6';
  const hue = Math.max(0, Math.min(1, p)) * 120;
  return `hsl(${hue.toFixed(0)}, 80%, 40%)`;
}

export function polyline(ctx: CanvasRenderingContext2D, m: MapCanvas, pts: ArrayLike<{ x: number; y: number }> | number[][], close = false): void {
  ctx.beginPath();
  const n = pts.length;
  for (let i = 0; i < n; i++) {
    const p = (pts as ArrayLike<unknown>)[i] as { x: number; y: number } | number[];
    const [x, y] = Array.isArray(p) ? p : [p.x, p.y];
    const [sx, sy] = m.toScreen(x, y);
    if (i === 0) ctx.moveTo(sx, sy);
    else ctx.lineTo(sx, sy);
  }
  if (close) ctx.closePath();
}

/** The robot's footprint (length × width, centred on the pose) and its heading. */
export function drawRobot(
  ctx: CanvasRenderingContext2D, m: MapCanvas, pose: { x: number; y: number; yaw?: number },
  footprint: number[] | null | undefined, fill = 'rgba(37, 99, 235, 0.45)', stroke = '#1e3a8a',
): void {
  const [l, w] = footprint && footprint.length >= 2 ? footprint : [0.5, 0.4];
  const yaw = pose.yaw ?? 0;
  const [sx, sy] = m.toScreen(pose.x, pose.y);
  ctx.save();
  ctx.translate(sx, sy);
  ctx.rotate(-yaw);
  const L = m.px(l);
  const W = m.px(w);
  ctx.fillStyle = fill;
  ctx.strokeStyle = stroke;
  ctx.lineWidth = 1.5;
  ctx.beginPath();
  ctx.rect(-L / 2, -W / 2, L, W);
  ctx.fill();
  ctx.stroke();
  ctx.beginPath();
  ctx.moveTo(0, 0);
  ctx.lineTo(Math.max(L / 2, 8), 0);
  ctx.stroke();
  ctx.restore();
}

export function marker(ctx: CanvasRenderingContext2D, m: MapCanvas, x: number, y: number, kind: 'dot' | 'cross' | 'ring', colour: string, r = 5): void {
  const [sx, sy] = m.toScreen(x, y);
  ctx.strokeStyle = colour;
  ctx.fillStyle = colour;
  ctx.lineWidth = 2;
  ctx.beginPath();
  if (kind === 'dot') {
    ctx.arc(sx, sy, r, 0, Math.PI * 2);
    ctx.fill();
  } else if (kind === 'ring') {
    ctx.arc(sx, sy, r, 0, Math.PI * 2);
    ctx.stroke();
  } else {
    ctx.moveTo(sx - r, sy - r);
    ctx.lineTo(sx + r, sy + r);
    ctx.moveTo(sx + r, sy - r);
    ctx.lineTo(sx - r, sy + r);
    ctx.stroke();
  }
}

export function label(ctx: CanvasRenderingContext2D, text: string, sx: number, sy: number, colour = '#111827'): void {
  ctx.font = '12px system-ui, sans-serif';
  ctx.textAlign = 'center';
  ctx.textBaseline = 'middle';
  ctx.lineWidth = 3;
  ctx.strokeStyle = 'rgba(255,255,255,0.85)';
  ctx.strokeText(text, sx, sy);
  ctx.fillStyle = colour;
  ctx.fillText(text, sx, sy);
}
