// Traffic: a floor's committed plans live (GET /v1/places/{floor}/traffic/events), every robot
// where its schedule puts it now, its route and its waits; a timeline to look ahead or play the
// schedule, and the replay of a joint rehearsal (`mentalsim bench fleet --replay DIR`).

import { h, add, clear, field, fmt, localName } from '../dom';
import { request, showError, clearError, type FloorTraffic, type Itinerary, type PlaceView } from '../api';
import * as data from '../data';
import { stream } from '../sse';
import { MapCanvas, marker, polyline, label } from '../mapview';
import { drawAreas, drawObjects } from '../layers';
import { endMs, poseAt, robotColour, startMs, waits, type Wait } from '../traffic';
import type { PageContext, Cleanup } from '../main';

/** What a joint rehearsal file holds beside the plans: how each robot fared. */
interface JointOutcome { robot: string; outcome: string; reason: string; time_s: number }
interface JointReplay extends FloorTraffic { joint?: JointOutcome[]; map?: string; scenario?: string }

interface Shown { it: Itinerary; waits: Wait[]; colour: string }

export async function mount(root: HTMLElement, ctx: PageContext): Promise<Cleanup> {
  root.append(h('h1', { id: 'page-title' }, 'Traffic'));
  const topErr = h('div', { hidden: true });
  root.append(topErr);
  let all: PlaceView[];
  try {
    all = await data.places();
  } catch (e) {
    showError(topErr, e);
    return;
  }
  const index = data.indexPlaces(all);
  let floor: PlaceView | undefined =
    index.floors.find((f) => f.id === ctx.args[0] || f.iri === ctx.args[0]) ?? index.floors[0];
  let alive = true;

  // ---- state ----
  const plans = new Map<string, Shown>();
  let version = 0;
  let live = true;
  let replay: JointReplay | null = null;
  let nowMs = Date.now();
  let playing = false;
  let sub: { stop: () => void } | null = null;
  let areas: PlaceView[] = [];
  let objects: Awaited<ReturnType<typeof data.objects>> = [];

  // ---- controls ----
  const floorSel = h('select', { name: 'floor' }, index.floors.map((f) => h('option', { value: f.id ?? f.iri, selected: f === floor }, f.name)));
  const liveBox = h('input', { type: 'checkbox', name: 'live', checked: true });
  const slider = h('input', { type: 'range', name: 'time', min: '0', max: '1000', value: '0', step: '1', 'aria-label': 'Time on the schedule' });
  const timeOut = h('output', { class: 'replay-time', id: 'traffic-time' }, '—');
  const playBtn = h('button', { type: 'button', id: 'traffic-play' }, 'Play');
  const speedSel = h('select', { name: 'speed' }, [1, 2, 5, 10, 20].map((s) => h('option', { value: String(s), selected: s === 5 }, `${s}×`)));
  const fileIn = h('input', { type: 'file', name: 'replay', accept: 'application/json,.json' });
  const status = h('p', { class: 'status', id: 'traffic-status', 'aria-live': 'polite' });
  const streamErr = h('div', { hidden: true, id: 'traffic-error' });
  const table = h('div', { class: 'traffic-plans', id: 'traffic-plans' });
  const m = new MapCanvas('Traffic: every committed plan on the floor, each robot where its schedule puts it');
  m.el.id = 'traffic-map';

  root.append(
    h('div', { class: 'controls' },
      field('Floor', floorSel),
      h('label', null, liveBox, ' Live (now)'),
      field('Joint rehearsal file (bench fleet --replay)', fileIn),
    ),
    streamErr,
    m.el,
    h('div', { class: 'below-map' }, status),
    h('div', { class: 'replay', role: 'group', 'aria-label': 'Timeline of the schedule' },
      playBtn, field('Speed', speedSel), field('Time', slider), timeOut),
    legendEl(),
    table,
  );

  // ---- time ----
  /** The span the timeline covers: every plan's start to its end, and now when live. */
  function span(): [number, number] {
    let lo = Infinity;
    let hi = -Infinity;
    for (const s of plans.values()) {
      lo = Math.min(lo, startMs(s.it));
      hi = Math.max(hi, endMs(s.it));
    }
    if (live || !Number.isFinite(lo)) {
      lo = Math.min(lo, Date.now());
      hi = Math.max(hi, Date.now());
    }
    return [lo, Math.max(hi, lo + 1000)];
  }
  function syncSlider(): void {
    const [lo, hi] = span();
    slider.value = String(Math.round(((nowMs - lo) / (hi - lo)) * 1000));
    const rel = (nowMs - lo) / 1000;
    const text = replay
      ? `${rel.toFixed(1)} s of ${((hi - lo) / 1000).toFixed(1)} s`
      : `${new Date(nowMs).toLocaleTimeString()}${live ? ' (now)' : ''}`;
    timeOut.value = text;
    slider.setAttribute('aria-valuetext', text);
  }
  slider.addEventListener('input', () => {
    const [lo, hi] = span();
    setLive(false);
    nowMs = lo + (+slider.value / 1000) * (hi - lo);
    syncSlider();
    m.request();
  });
  function setLive(on: boolean): void {
    live = on && !replay;
    liveBox.checked = live;
    if (live) stopPlay();
  }
  liveBox.addEventListener('change', () => {
    if (liveBox.checked && replay) {
      replay = null;
      fileIn.value = '';
      void subscribe();
    }
    setLive(liveBox.checked);
  });

  let raf = 0;
  let last = 0;
  const tick = (t: number) => {
    if (!alive) return;
    if (live) nowMs = Date.now();
    else if (playing) {
      nowMs += (t - last) * (parseFloat(speedSel.value) || 1);
      if (nowMs >= span()[1]) stopPlay();
    }
    last = t;
    syncSlider();
    m.draw();
    raf = requestAnimationFrame(tick);
  };
  raf = requestAnimationFrame(tick);
  playBtn.addEventListener('click', () => {
    if (playing) return stopPlay();
    setLive(false);
    const [lo, hi] = span();
    if (nowMs >= hi) nowMs = lo;
    playing = true;
    playBtn.textContent = 'Pause';
    playBtn.setAttribute('aria-pressed', 'true');
  });
  function stopPlay(): void {
    playing = false;
    playBtn.textContent = 'Play';
    playBtn.setAttribute('aria-pressed', 'false');
  }

  // ---- drawing ----
  m.drawStatic = (c) => {
    drawAreas(c, m, areas);
    drawObjects(c, m, objects, false);
    for (const s of plans.values()) {
      c.strokeStyle = s.colour;
      c.globalAlpha = 0.55;
      c.lineWidth = 2;
      polyline(c, m, s.it.trajectory);
      c.stroke();
      c.globalAlpha = 1;
      const goal = s.it.trajectory[s.it.trajectory.length - 1];
      if (goal) marker(c, m, goal.x, goal.y, 'cross', s.colour);
      for (const w of s.waits) marker(c, m, w.x, w.y, 'ring', s.colour, 7);
    }
  };
  m.drawDynamic = (c) => {
    let drawn = 0;
    for (const s of plans.values()) {
      const p = poseAt(s.it, nowMs);
      if (!p) continue;
      drawn++;
      const [sx, sy] = m.toScreen(p.x, p.y);
      const waiting = s.waits.some((w) => w.fromMs <= nowMs && nowMs < w.toMs);
      c.fillStyle = s.colour;
      c.globalAlpha = waiting ? 0.35 : 0.7;
      c.beginPath();
      c.arc(sx, sy, Math.max(3, m.px(s.it.radius_m)), 0, Math.PI * 2);
      c.fill();
      c.globalAlpha = 1;
      c.strokeStyle = s.colour;
      c.lineWidth = 2;
      c.beginPath();
      c.moveTo(sx, sy);
      c.lineTo(sx + Math.cos(p.yaw) * Math.max(8, m.px(s.it.radius_m)), sy - Math.sin(p.yaw) * Math.max(8, m.px(s.it.radius_m)));
      c.stroke();
      label(c, localName(s.it.robot) + (waiting ? ' (waits)' : ''), sx, sy - Math.max(12, m.px(s.it.radius_m) + 8), s.colour);
    }
    m.canvas.dataset.robotsDrawn = String(drawn);
  };

  function renderTable(): void {
    clear(table);
    root.dataset.plans = String(plans.size);
    root.dataset.version = String(version);
    const rows = [...plans.values()].sort((a, b) => startMs(a.it) - startMs(b.it));
    const outcomes = new Map((replay?.joint ?? []).map((j) => [j.robot, j]));
    if (!rows.length) {
      table.append(h('p', { class: 'muted' }, replay ? 'The file holds no plans.' : 'No plan is committed on this floor now.'));
      return;
    }
    const t = (ms: number) => new Date(ms).toLocaleTimeString();
    table.append(h('table', null,
      h('thead', null, h('tr', null, ['robot', 'plan', 'sets off', 'arrives', 'delay', 'waits', replay ? 'joint run' : 'expires', ''].map((c) => h('th', null, c)))),
      h('tbody', null, rows.map((s) => {
        const waited = s.waits.reduce((sum, w) => sum + (w.toMs - w.fromMs) / 1000, 0);
        const o = outcomes.get(s.it.robot);
        return h('tr', { 'data-plan': s.it.plan_id },
          h('td', null, h('span', { class: 'sw', style: `background:${s.colour}`, 'aria-hidden': 'true' }), ' ', localName(s.it.robot)),
          h('td', null, h('code', null, s.it.plan_id)),
          h('td', null, t(startMs(s.it))),
          h('td', null, t(endMs(s.it))),
          h('td', null, `${fmt(s.it.delay_s, 1)} s`),
          h('td', { title: s.waits.map((w) => `${((w.toMs - w.fromMs) / 1000).toFixed(1)} s at (${fmt(w.x)}, ${fmt(w.y)})`).join('\n') },
            s.waits.length ? `${s.waits.length} (${waited.toFixed(1)} s)` : 'none'),
          h('td', { title: o?.reason ?? '' }, replay ? (o ? `${o.outcome} at ${fmt(o.time_s, 1)} s` : '—') : t(s.it.expires_unix_ms)),
          h('td', null, ctx.engineer && !replay
            ? h('button', { type: 'button', class: 'small', 'aria-label': `Cancel the plan of ${localName(s.it.robot)}`, onclick: () => void cancel(s.it.plan_id) }, 'Cancel')
            : null),
        );
      })),
    ));
  }

  async function cancel(id: string): Promise<void> {
    clearError(streamErr);
    try {
      await request(`/v1/plans/${encodeURIComponent(id)}`, { method: 'DELETE' });
    } catch (e) {
      showError(streamErr, e, 'cancel: ');
    }
  }

  function setPlans(list: Itinerary[]): void {
    plans.clear();
    for (const it of list) put(it);
  }
  function put(it: Itinerary): void {
    for (const [id, s] of plans) if (s.it.robot === it.robot && id !== it.plan_id) plans.delete(id);
    plans.set(it.plan_id, { it, waits: waits(it), colour: robotColour(it.robot) });
  }
  function changed(what: string): void {
    // An itinerary past its expiry leaves without an event.
    const now = Date.now();
    if (!replay) for (const [id, s] of plans) if (s.it.expires_unix_ms < now) plans.delete(id);
    status.textContent = `${replay ? 'Joint rehearsal' : 'Live'}: version ${version}, ${plans.size} plan${plans.size === 1 ? '' : 's'}. ${what}`;
    renderTable();
    m.invalidate();
  }

  // ---- the live stream ----
  async function subscribe(): Promise<void> {
    sub?.stop();
    sub = null;
    clearError(streamErr);
    if (!floor) return;
    setPlans([]);
    changed('Connecting…');
    sub = stream(`/v1/places/${encodeURIComponent(floor.iri)}/traffic/events`, {
      onEvent: (e) => {
        if (!alive || replay) return;
        let d: Record<string, unknown>;
        try {
          d = JSON.parse(e.data);
        } catch {
          return;
        }
        version = Number(e.id) || version;
        if (e.event === 'snapshot') {
          setPlans((d as unknown as FloorTraffic).plans);
          changed('Snapshot received.');
        } else if (e.event === 'committed' || e.event === 'progressed') {
          const it = d.itinerary as Itinerary;
          put(it);
          changed(`${e.event === 'committed' ? 'Committed' : 'Progress of'} ${localName(it.robot)} at ${new Date().toLocaleTimeString()}.`);
        } else if (e.event === 'removed') {
          plans.delete(String(d.plan_id));
          changed(`${localName(String(d.robot))}'s plan ${d.reason === 'replaced' ? 'replaced' : 'cancelled'} at ${new Date().toLocaleTimeString()}.`);
        }
      },
      onError: (e) => showError(streamErr, e, 'live traffic: '),
      onOpen: () => clearError(streamErr),
    });
  }

  // ---- a joint rehearsal from a file ----
  fileIn.addEventListener('change', async () => {
    const f = fileIn.files?.[0];
    if (!f) return;
    clearError(streamErr);
    try {
      const r = JSON.parse(await f.text()) as JointReplay;
      if (!r || !Array.isArray(r.plans) || r.plans.some((p) => !Array.isArray(p?.trajectory))) {
        throw new Error('not a joint rehearsal: expected {"floor", "plans": [itineraries], "joint": [...]}');
      }
      sub?.stop();
      sub = null;
      replay = r;
      setLive(false);
      const onFloor = index.floors.find((fl) => fl.iri === r.floor);
      if (onFloor && onFloor !== floor) {
        floor = onFloor;
        floorSel.value = onFloor.id ?? onFloor.iri;
        await loadFloor(false);
      } else if (!onFloor) {
        areas = [];
        objects = [];
        m.setMap(null, null);
        const xs = r.plans.flatMap((p) => p.trajectory.map((q) => q.x));
        const ys = r.plans.flatMap((p) => p.trajectory.map((q) => q.y));
        if (xs.length) m.setBounds([Math.min(...xs) - 1, Math.min(...ys) - 1, Math.max(...xs) + 1, Math.max(...ys) + 1]);
      }
      version = r.version ?? 0;
      setPlans(r.plans);
      nowMs = span()[0];
      const arrived = (r.joint ?? []).filter((j) => j.outcome === 'reached').length;
      changed(`${r.map ?? localName(r.floor)}${r.scenario ? ` (${r.scenario})` : ''}: ${arrived} of ${r.plans.length} arrived in the joint run` +
        (onFloor ? '.' : '; the floor is not on this service, drawn without its map.'));
    } catch (e) {
      showError(streamErr, e, 'joint rehearsal: ');
    }
  });

  // ---- floor ----
  async function loadFloor(listen = true): Promise<void> {
    if (!floor) return;
    areas = index.areasOn(floor);
    objects = [];
    if (listen) void subscribe();
    await data.showFloorOn(m, floor, () => alive, (o) => { objects = o; m.invalidate(); }, (e) => showError(topErr, e, 'map: '));
  }
  floorSel.addEventListener('change', () => {
    floor = index.floors.find((f) => (f.id ?? f.iri) === floorSel.value) ?? floor;
    replay = null;
    fileIn.value = '';
    setLive(true);
    void loadFloor();
  });

  if (!floor) {
    add(table, h('p', null, 'No floor yet: import a map (POST /v1/maps).'));
  } else {
    await loadFloor();
  }
  return () => {
    alive = false;
    cancelAnimationFrame(raf);
    sub?.stop();
    m.destroy();
  };
}

function legendEl(): HTMLElement {
  const sw = (cls: string) => h('span', { class: `sw ${cls}`, 'aria-hidden': 'true' });
  return h('div', { class: 'legend', 'aria-label': 'Legend' },
    h('span', null, sw('sw-robot'), 'robot where its schedule puts it (faint: waiting), in its colour'),
    h('span', null, sw('sw-edge'), 'its committed route'),
    h('span', null, '◯ a wait the schedule gave it'),
    h('span', null, '✕ its goal'),
  );
}
