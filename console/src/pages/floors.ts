// Floors: every building and floor; a floor's map with its rooms, objects, roadmap and the
// robot's footprint to scale.

import { h, add, clear, field, fmt } from '../dom';
import { showError, clearError, type PlaceView, type RobotView, type ObjectView, type Roadmap, type PolicySummary } from '../api';
import * as data from '../data';
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
  const t0 = performance.now();
  const areas = index.areasOn(floor);
  const state: {
    image: ImageBitmap | null; objects: ObjectView[]; roadmap: Roadmap | null; robots: RobotView[];
    robot: RobotView | null; robotPose: { x: number; y: number; yaw: number } | null; hover: [number, number] | null;
  } = { image: null, objects: [], roadmap: null, robots: [], robot: null, robotPose: null, hover: null };

  const show = {
    areas: h('input', { type: 'checkbox', checked: true }),
    objects: h('input', { type: 'checkbox', checked: true }),
    roadmap: h('input', { type: 'checkbox' }),
    robot: h('input', { type: 'checkbox', checked: true }),
  };
  const robotSel = h('select', { name: 'robot' });
  const policySel = h('select', { name: 'policy' }, h('option', { value: '' }, 'none: geometric roadmap'));
  const status = h('p', { class: 'status', 'aria-live': 'polite' });
  const roadmapErr = h('div', { hidden: true });
  const objectsErr = h('div', { hidden: true });
  const mapErr = h('div', { hidden: true });
  const coords = h('output', { class: 'coords', 'aria-live': 'off' }, ' ');
  const px = h('input', { type: 'number', step: 'any', name: 'fx', inputmode: 'decimal' });
  const py = h('input', { type: 'number', step: 'any', name: 'fy', inputmode: 'decimal' });
  const pyaw = h('input', { type: 'number', step: 'any', name: 'fyaw', value: '0', inputmode: 'decimal' });

  const m = new MapCanvas(`Map of ${floor.name}`);
  m.canvas.dataset.floor = floor.id ?? floor.iri;
  if (floor.map) m.setMap(null, floor.map);
  else {
    const b = areas.flatMap((a) => a.boundary);
    if (b.length) m.setBounds([Math.min(...b.map((p) => p[0])), Math.min(...b.map((p) => p[1])), Math.max(...b.map((p) => p[0])), Math.max(...b.map((p) => p[1]))]);
  }
  const legend = legendEl();
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
      field('Robot', robotSel),
      field('Policy (policy-aware roadmap)', policySel),
    ),
    roadmapErr,
    objectsErr,
    mapErr,
    m.el,
    h('div', { class: 'below-map' }, coords, status),
    h('form', { class: 'inline', 'aria-label': 'Place the robot footprint', onsubmit: (e: Event) => {
      e.preventDefault();
      const x = parseFloat(px.value), y = parseFloat(py.value);
      if (Number.isFinite(x) && Number.isFinite(y)) {
        state.robotPose = { x, y, yaw: parseFloat(pyaw.value) || 0 };
        m.request();
      }
    } },
      field('Footprint x (m)', px), field('y (m)', py), field('yaw (rad)', pyaw),
      h('button', { type: 'submit' }, 'Place footprint'),
    ),
    legend,
  );
  const details = h('div', { class: 'details' });
  view.append(details);

  m.drawStatic = (c) => {
    if (show.areas.checked) drawAreas(c, m, areas);
    if (show.roadmap.checked && state.roadmap) drawRoadmap(c, m, state.roadmap);
    if (show.objects.checked) drawObjects(c, m, state.objects);
  };
  m.drawDynamic = (c) => {
    if (show.robot.checked && state.robotPose) drawRobot(c, m, state.robotPose, state.robot?.footprint);
  };
  m.onHover = (x, y) => {
    coords.value = `x ${x.toFixed(2)} m, y ${y.toFixed(2)} m`;
    // The object under the pointer, by its footprint's bounding circle.
    const o = state.objects.find((ob) => {
      const s = ob.shape;
      const r = s.kind === 'box' ? Math.hypot(s.length, s.width) / 2 : s.diameter / 2;
      return Math.hypot(ob.pose.x - x, ob.pose.y - y) <= r;
    });
    const title = o ? `${o.name} (${o.class}${o.placeholder ? ', placeholder' : ''})` : '';
    if (m.canvas.title !== title) m.canvas.title = title;
  };
  m.onClick = (x, y) => {
    state.robotPose = { x, y, yaw: state.robotPose?.yaw ?? 0 };
    px.value = x.toFixed(2);
    py.value = y.toFixed(2);
    m.request();
  };
  for (const cb of Object.values(show)) cb.addEventListener('change', () => m.invalidate());
  show.roadmap.addEventListener('change', () => void loadRoadmap());

  // Default footprint position: the largest area's centroid, else the map's centre.
  const biggest = areas.slice().sort((a, b) => area(b.boundary) - area(a.boundary))[0];
  if (biggest) {
    const [cx, cy] = centroid(biggest.boundary);
    state.robotPose = { x: cx, y: cy, yaw: 0 };
  } else if (floor.map) {
    const { origin: [ox, oy], width, height, resolution } = floor.map;
    state.robotPose = { x: ox + (width * resolution) / 2, y: oy + (height * resolution) / 2, yaw: 0 };
  }
  if (state.robotPose) {
    px.value = state.robotPose.x.toFixed(2);
    py.value = state.robotPose.y.toFixed(2);
  }

  let alive = true;
  const imageP = floor.map
    ? data.mapImage(floor).then((img) => {
        if (!alive) return;
        state.image = img;
        m.setMap(img, floor.map!);
        m.draw();
        const now = performance.now();
        performance.mark('floor-map-drawn');
        m.canvas.dataset.ready = '1';
        window.__floorStats = { floor: floor.id ?? floor.iri, drawnMs: now, imageMs: now - t0, cells: floor.map!.width * floor.map!.height };
        status.textContent = `Map drawn in ${(now - t0).toFixed(0)} ms.`;
      }, (e) => showError(mapErr, e, 'map: '))
    : Promise.resolve();

  data.objects(floor).then((objs) => {
    if (!alive) return;
    state.objects = objs;
    m.invalidate();
    renderDetails(details, areas, objs);
  }, (e) => {
    showError(objectsErr, e, 'objects: ');
    renderDetails(details, areas, []);
  });

  data.robots().then((rs) => {
    if (!alive) return;
    state.robots = rs;
    for (const r of rs) robotSel.append(h('option', { value: r.id ?? r.iri }, `${r.name} (${r.id ?? r.iri})`));
    state.robot = rs[0] ?? null;
    m.request();
    return data.policies().then((ps) => fillPolicies(ps), () => undefined);
  }, (e) => showError(roadmapErr, e, 'robots: '));

  function fillPolicies(ps: PolicySummary[]): void {
    clear(policySel);
    policySel.append(h('option', { value: '' }, 'none: geometric roadmap'));
    for (const p of ps) {
      if (state.robot && p.robot && p.robot !== state.robot.iri) continue;
      const onFloor = !p.floor || p.floor === floor.iri;
      policySel.append(h('option', { value: p.id }, `${p.id.slice(0, 13)}… ${onFloor ? '' : '(other floor)'}`));
    }
  }
  robotSel.addEventListener('change', () => {
    state.robot = state.robots.find((r) => (r.id ?? r.iri) === robotSel.value) ?? null;
    void data.policies().then(fillPolicies, () => undefined);
    m.request();
    void loadRoadmap();
  });
  policySel.addEventListener('change', () => {
    if (policySel.value) show.roadmap.checked = true;
    void loadRoadmap();
  });

  async function loadRoadmap(): Promise<void> {
    clearError(roadmapErr);
    if (!show.roadmap.checked) return m.invalidate();
    if (!state.robot) return;
    status.textContent = 'Loading the roadmap…';
    try {
      const r = await data.roadmap(floor, state.robot.id ?? state.robot.iri, policySel.value || null);
      if (!alive) return;
      state.roadmap = r;
      legend.dataset.roadmap = r.kind;
      const kept = r.edges.filter((e) => e.kept !== false).length;
      status.textContent = `Roadmap: ${r.kind}, ${r.nodes.length} nodes, ${r.edges.length} edges` +
        (r.kind === 'policy' ? `, ${kept} kept by the policy` : '') + (r.note ? `. ${r.note}` : '.');
      m.invalidate();
    } catch (e) {
      state.roadmap = null;
      status.textContent = '';
      showError(roadmapErr, e, 'roadmap: ');
      m.invalidate();
    }
  }

  await imageP;
  return () => {
    alive = false;
    m.destroy();
  };
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

function renderDetails(el: HTMLElement, areas: PlaceView[], objects: ObjectView[]): void {
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
