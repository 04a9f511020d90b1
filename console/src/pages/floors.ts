// Floors: every building and floor; a floor's map with its rooms, objects, roadmap and the
// robot's footprint to scale.

import { h, add, clear, field, fmt } from '../dom';
import { showError, clearError, type PlaceView, type RobotView, type RoadmapView, type PolicySummary } from '../api';
import * as data from '../data';
import type { MapObject } from '../data';
import { MapCanvas, drawRobot } from '../mapview';
import { drawAreas, drawObjects, drawRoadmap, centroid } from '../layers';
import type { PageContext, Cleanup } from '../main';

declare global {
  interface Window {
    __floorStats?: { floor: string; drawnMs: number; imageMs: number; cells: number };
  }
}

export async function mount(root: HTMLElement, ctx: PageContext): Promise<Cleanup> {
  root.append(h('h1', { id: 'page-title' }, 'Floors'));
  const err = h('div', { hidden: true });
  root.append(err);
  let all: PlaceView[];
  try {
    all = await data.places();
  } catch (e) {
    showError(err, e);
    return;
  }
  const index = data.indexPlaces(all);
  const wanted = ctx.args[0];
  const floor =
    index.floors.find((f) => f.id === wanted || f.iri === wanted) ??
    (wanted ? undefined : index.floors[0]);

  const list = h('nav', { class: 'floor-list', 'aria-label': 'Buildings and floors' });
  const inBuilding = new Set<string>();
  for (const b of index.buildings) {
    const fl = index.floors.filter((f) => f.parent === b.iri);
    fl.forEach((f) => inBuilding.add(f.iri));
    list.append(h('h2', null, b.name), floorLinks(fl, floor));
  }
  const others = index.floors.filter((f) => !inBuilding.has(f.iri));
  if (others.length) list.append(h('h2', null, index.buildings.length ? 'Other floors' : 'Floors'), floorLinks(others, floor));
  const view = h('div', { class: 'floor-view' });
  root.append(h('div', { class: 'split' }, list, view));
  if (!floor) {
    view.append(h('p', null, wanted ? `No floor “${wanted}”.` : 'No floor yet: import a map (POST /v1/maps).'));
    return;
  }
  return showFloor(view, floor, index);
}

function floorLinks(floors: PlaceView[], current: PlaceView | undefined): HTMLUListElement {
  return h('ul', null, floors.map((f) =>
    h('li', null,
      h('a', { href: `#/floors/${encodeURIComponent(f.id ?? f.iri)}`, 'aria-current': f === current ? 'page' : undefined }, f.name),
      f.map ? h('span', { class: 'muted' }, ` ${f.map.width}×${f.map.height}`) : null,
    ),
  ));
}

async function showFloor(view: HTMLElement, floor: PlaceView, index: data.FloorIndex): Promise<Cleanup> {
  const f = new FloorView(floor, index);
  f.render(view);
  f.wire();
  const image = f.loadImage();
  f.loadObjects();
  f.loadRobots();
  await image;
  return () => f.destroy();
}

/** One floor's map, its layers and controls. */
class FloorView {
  private readonly t0 = performance.now();
  private readonly areas: PlaceView[];
  private alive = true;
  private objects: MapObject[] = [];
  private roadmap: RoadmapView | null = null;
  private robots: RobotView[] = [];
  private robot: RobotView | null = null;
  private robotPose: { x: number; y: number; yaw: number } | null = null;

  private readonly show = {
    areas: h('input', { type: 'checkbox', checked: true }),
    objects: h('input', { type: 'checkbox', checked: true }),
    roadmap: h('input', { type: 'checkbox' }),
    robot: h('input', { type: 'checkbox', checked: true }),
  };
  private readonly robotSel = h('select', { name: 'robot' });
  private readonly policySel = h('select', { name: 'policy' }, h('option', { value: '' }, 'none: geometric roadmap'));
  private readonly status = h('p', { class: 'status', 'aria-live': 'polite' });
  private readonly roadmapErr = h('div', { hidden: true });
  private readonly objectsErr = h('div', { hidden: true });
  private readonly mapErr = h('div', { hidden: true });
  private readonly coords = h('output', { class: 'coords', 'aria-live': 'off' }, ' ');
  private readonly px = h('input', { type: 'number', step: 'any', name: 'fx', inputmode: 'decimal' });
  private readonly py = h('input', { type: 'number', step: 'any', name: 'fy', inputmode: 'decimal' });
  private readonly pyaw = h('input', { type: 'number', step: 'any', name: 'fyaw', value: '0', inputmode: 'decimal' });
  private readonly details = h('div', { class: 'details' });
  private readonly legend = legendEl();
  private readonly m: MapCanvas;

  constructor(private readonly floor: PlaceView, index: data.FloorIndex) {
    this.areas = index.areasOn(floor);
    this.m = new MapCanvas(`Map of ${floor.name}`);
    this.m.canvas.dataset.floor = floor.id ?? floor.iri;
    if (floor.map) this.m.setMap(null, floor.map);
    else {
      const b = this.areas.flatMap((a) => a.boundary);
      if (b.length) this.m.setBounds([Math.min(...b.map((p) => p[0])), Math.min(...b.map((p) => p[1])), Math.max(...b.map((p) => p[0])), Math.max(...b.map((p) => p[1]))]);
    }
    this.placeDefaultPose();
  }

  render(view: HTMLElement): void {
    const { floor, show } = this;
    add(view,
      h('h2', null, floor.name, ' ', h('span', { class: 'muted' }, floor.id ?? floor.iri)),
      floor.map
        ? h('p', { class: 'muted' }, `${floor.map.width} × ${floor.map.height} cells at ${floor.map.resolution} m, origin (${floor.map.origin.slice(0, 2).map((v) => fmt(v)).join(', ')}), free area ${fmt(floor.map.free_area_m2, 1)} m²`)
        : null,
      h('div', { class: 'controls' },
        h('fieldset', null, h('legend', null, 'Show'),
          h('label', null, show.areas, ' Rooms and corridors'),
          h('label', null, show.objects, ' Objects'),
          h('label', null, show.roadmap, ' Roadmap'),
          h('label', null, show.robot, ' Robot footprint'),
        ),
        field('Robot', this.robotSel),
        field('Policy (policy-aware roadmap)', this.policySel),
      ),
      this.roadmapErr,
      this.objectsErr,
      this.mapErr,
      this.m.el,
      h('div', { class: 'below-map' }, this.coords, this.status),
      h('form', { class: 'inline', 'aria-label': 'Place the robot footprint', onsubmit: (e: Event) => {
        e.preventDefault();
        this.placeFromForm();
      } },
        field('Footprint x (m)', this.px), field('y (m)', this.py), field('yaw (rad)', this.pyaw),
        h('button', { type: 'submit' }, 'Place footprint'),
      ),
      this.legend,
    );
    view.append(this.details);
  }

  /** The map's layers and pointer, the layer toggles, the robot and policy pickers. */
  wire(): void {
    const { m, show } = this;
    m.drawStatic = (c) => {
      if (show.areas.checked) drawAreas(c, m, this.areas);
      if (show.roadmap.checked && this.roadmap) drawRoadmap(c, m, this.roadmap);
      if (show.objects.checked) drawObjects(c, m, this.objects);
    };
    m.drawDynamic = (c) => {
      if (show.robot.checked && this.robotPose) drawRobot(c, m, this.robotPose, this.robot?.footprint);
    };
    m.onHover = (x, y) => this.hover(x, y);
    m.onClick = (x, y) => {
      this.robotPose = { x, y, yaw: this.robotPose?.yaw ?? 0 };
      this.px.value = x.toFixed(2);
      this.py.value = y.toFixed(2);
      m.request();
    };
    for (const cb of Object.values(show)) cb.addEventListener('change', () => m.invalidate());
    show.roadmap.addEventListener('change', () => void this.loadRoadmap());
    this.robotSel.addEventListener('change', () => {
      this.robot = this.robots.find((r) => (r.id ?? r.iri) === this.robotSel.value) ?? null;
      void data.policies().then((ps) => this.fillPolicies(ps), () => undefined);
      m.request();
      void this.loadRoadmap();
    });
    this.policySel.addEventListener('change', () => {
      if (this.policySel.value) show.roadmap.checked = true;
      void this.loadRoadmap();
    });
  }

  private hover(x: number, y: number): void {
    this.coords.value = `x ${x.toFixed(2)} m, y ${y.toFixed(2)} m`;
    // The object under the pointer, by its footprint's bounding circle.
    const o = this.objects.find((ob) => {
      const s = ob.shape;
      const r = s.kind === 'box' ? Math.hypot(s.length, s.width) / 2 : s.diameter / 2;
      return Math.hypot(ob.pose.x - x, ob.pose.y - y) <= r;
    });
    const title = o ? `${o.name} (${o.class}${o.placeholder ? ', placeholder' : ''})` : '';
    if (this.m.canvas.title !== title) this.m.canvas.title = title;
  }

  private placeFromForm(): void {
    const x = parseFloat(this.px.value), y = parseFloat(this.py.value);
    if (Number.isFinite(x) && Number.isFinite(y)) {
      this.robotPose = { x, y, yaw: parseFloat(this.pyaw.value) || 0 };
      this.m.request();
    }
  }

  /** The footprint's first place: the largest area's centroid, else the map's centre. */
  private placeDefaultPose(): void {
    const biggest = this.areas.slice().sort((a, b) => area(b.boundary) - area(a.boundary))[0];
    if (biggest) {
      const [cx, cy] = centroid(biggest.boundary);
      this.robotPose = { x: cx, y: cy, yaw: 0 };
    } else if (this.floor.map) {
      const { origin: [ox, oy], width, height, resolution } = this.floor.map;
      this.robotPose = { x: ox + (width * resolution) / 2, y: oy + (height * resolution) / 2, yaw: 0 };
    }
    if (this.robotPose) {
      this.px.value = this.robotPose.x.toFixed(2);
      this.py.value = this.robotPose.y.toFixed(2);
    }
  }

  /** The map image; once drawn, the canvas is ready and `window.__floorStats` says when. */
  async loadImage(): Promise<void> {
    const { floor, m } = this;
    const map = floor.map;
    if (!map) return;
    try {
      const img = await data.mapImage(floor);
      if (!this.alive) return;
      m.setMap(img, map);
      m.draw();
      const now = performance.now();
      performance.mark('floor-map-drawn');
      m.canvas.dataset.ready = '1';
      window.__floorStats = { floor: floor.id ?? floor.iri, drawnMs: now, imageMs: now - this.t0, cells: map.width * map.height };
      this.status.textContent = `Map drawn in ${(now - this.t0).toFixed(0)} ms.`;
    } catch (e) {
      showError(this.mapErr, e, 'map: ');
    }
  }

  loadObjects(): void {
    data.objects(this.floor).then((objs) => {
      if (!this.alive) return;
      this.objects = objs;
      this.m.invalidate();
      renderDetails(this.details, this.areas, objs);
    }, (e) => {
      showError(this.objectsErr, e, 'objects: ');
      renderDetails(this.details, this.areas, []);
    });
  }

  loadRobots(): void {
    data.robots().then((rs) => {
      if (!this.alive) return;
      this.robots = rs;
      for (const r of rs) this.robotSel.append(h('option', { value: r.id ?? r.iri }, `${r.name} (${r.id ?? r.iri})`));
      this.robot = rs[0] ?? null;
      this.m.request();
      return data.policies().then((ps) => this.fillPolicies(ps), () => undefined);
    }, (e) => showError(this.roadmapErr, e, 'robots: '));
  }

  private fillPolicies(ps: PolicySummary[]): void {
    const { policySel, robot, floor } = this;
    clear(policySel);
    policySel.append(h('option', { value: '' }, 'none: geometric roadmap'));
    for (const p of ps) {
      if (robot && p.robot && p.robot !== robot.iri) continue;
      const onFloor = !p.floor || p.floor === floor.iri;
      policySel.append(h('option', { value: p.id }, `${p.id.slice(0, 13)}… ${onFloor ? '' : '(other floor)'}`));
    }
  }

  private async loadRoadmap(): Promise<void> {
    const { m, status } = this;
    clearError(this.roadmapErr);
    if (!this.show.roadmap.checked) return m.invalidate();
    if (!this.robot) return;
    status.textContent = 'Loading the roadmap…';
    try {
      const r = await data.roadmap(this.floor, this.robot.id ?? this.robot.iri, this.policySel.value || null);
      if (!this.alive) return;
      this.roadmap = r;
      this.legend.dataset.roadmap = r.kind;
      const kept = r.edges.filter((e) => e.kept !== false).length;
      status.textContent = `Roadmap: ${r.kind}, ${r.nodes.length} nodes, ${r.edges.length} edges` +
        (r.kind === 'policy' ? `, ${kept} kept by the policy` : '') + (r.note ? `. ${r.note}` : '.');
      m.invalidate();
    } catch (e) {
      this.roadmap = null;
      status.textContent = '';
      showError(this.roadmapErr, e, 'roadmap: ');
      m.invalidate();
    }
  }

  destroy(): void {
    this.alive = false;
    this.m.destroy();
  }
}

function area(b: number[][]): number {
  let a = 0;
  for (let i = 0; i < b.length; i++) {
    const [x0, y0] = b[i];
    const [x1, y1] = b[(i + 1) % b.length];
    a += x0 * y1 - x1 * y0;
  }
  return Math.abs(a / 2);
}

function legendEl(): HTMLElement {
  const sw = (cls: string) => h('span', { class: `sw ${cls}`, 'aria-hidden': 'true' });
  return h('div', { class: 'legend', 'aria-label': 'Legend' },
    h('span', null, sw('sw-room'), 'room'),
    h('span', null, sw('sw-corridor'), 'corridor'),
    h('span', null, sw('sw-hall'), 'hall'),
    h('span', null, sw('sw-object'), 'object (its colour)'),
    h('span', null, sw('sw-placeholder'), 'placeholder'),
    h('span', null, sw('sw-edge'), 'roadmap edge'),
    h('span', null, h('span', { class: 'sw sw-grad', 'aria-hidden': 'true' }), 'edge success 0 → 1 (policy-aware)'),
    h('span', null, sw('sw-dropped'), 'edge the policy does not keep'),
    h('span', null, sw('sw-robot'), 'robot footprint'),
  );
}

function renderDetails(el: HTMLElement, areas: PlaceView[], objects: MapObject[]): void {
  clear(el);
  el.append(
    h('details', null, h('summary', null, `Rooms and corridors (${areas.length})`),
      h('table', null,
        h('thead', null, h('tr', null, h('th', null, 'name'), h('th', null, 'kind'), h('th', null, 'id'), h('th', null, 'connected to'))),
        h('tbody', null, areas.map((a) => h('tr', null,
          h('td', null, h('a', { href: `#/knowledge?iri=${encodeURIComponent(a.iri)}` }, a.name)),
          h('td', null, a.kind), h('td', null, a.id ?? ''), h('td', null, a.connected.map((c) => c.split('/').pop()).join(', ')),
        ))),
      ),
    ),
    h('details', null, h('summary', null, `Objects (${objects.length})`),
      h('table', null,
        h('thead', null, h('tr', null, h('th', null, 'name'), h('th', null, 'class'), h('th', null, 'pose'), h('th', null, 'shape'), h('th', null, 'placeholder'))),
        h('tbody', null, objects.map((o) => h('tr', null,
          h('td', null, h('a', { href: `#/knowledge?iri=${encodeURIComponent(o.iri)}` }, o.name)),
          h('td', null, o.class),
          h('td', null, `(${fmt(o.pose.x)}, ${fmt(o.pose.y)}) yaw ${fmt(o.pose.yaw)}`),
          h('td', null, o.shape.kind === 'box' ? `box ${fmt(o.shape.length)}×${fmt(o.shape.width)}×${fmt(o.shape.height)}` : `${o.shape.kind} ⌀${fmt(o.shape.diameter)}`),
          h('td', null, o.placeholder ? 'yes' : 'no'),
        ))),
      ),
    ),
  );
}
