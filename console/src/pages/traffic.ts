// Traffic: a floor's committed plans live (GET /v1/places/{floor}/traffic/events), every robot
// where its schedule puts it now, its route and its waits; a timeline to look ahead or play the
// schedule, and the replay of a joint rehearsal (`mentalsim bench fleet --replay DIR`).

import { h, add, clear, field, fmt, localName } from '../dom';
import { request, showError, clearError, type FloorTraffic, type Itinerary, type PlaceView } from '../api';
import * as data from '../data';
import type { MapObject } from '../data';
import { stream, type SseEvent } from '../sse';
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
  const floor = index.floors.find((f) => f.id === ctx.args[0] || f.iri === ctx.args[0]) ?? index.floors[0];
  const page = new TrafficPage(root, topErr, index, floor, ctx.engineer);
  await page.start();
  return () => page.destroy();
}

class TrafficPage {
  // ---- state ----
  private readonly plans = new Map<string, Shown>();
  private version = 0;
  private live = true;
  private replay: JointReplay | null = null;
  private nowMs = Date.now();
  private playing = false;
  private sub: { stop: () => void } | null = null;
  private areas: PlaceView[] = [];
  private objects: MapObject[] = [];
  private alive = true;
  private raf = 0;
  private last = 0;

  // ---- controls ----
  private readonly floorSel: HTMLSelectElement;
  private readonly liveBox = h('input', { type: 'checkbox', name: 'live', checked: true });
  private readonly slider = h('input', { type: 'range', name: 'time', min: '0', max: '1000', value: '0', step: '1', 'aria-label': 'Time on the schedule' });
  private readonly timeOut = h('output', { class: 'replay-time', id: 'traffic-time' }, '—');
  private readonly playBtn = h('button', { type: 'button', id: 'traffic-play' }, 'Play');
  private readonly speedSel = h('select', { name: 'speed' }, [1, 2, 5, 10, 20].map((s) => h('option', { value: String(s), selected: s === 5 }, `${s}×`)));
  private readonly fileIn = h('input', { type: 'file', name: 'replay', accept: 'application/json,.json' });
  private readonly status = h('p', { class: 'status', id: 'traffic-status', 'aria-live': 'polite' });
  private readonly streamErr = h('div', { hidden: true, id: 'traffic-error' });
  private readonly table = h('div', { class: 'traffic-plans', id: 'traffic-plans' });
  private readonly m = new MapCanvas('Traffic: every committed plan on the floor, each robot where its schedule puts it');

  constructor(private readonly root: HTMLElement, private readonly topErr: HTMLElement, private readonly index: data.FloorIndex,
    private floor: PlaceView | undefined, private readonly engineer: boolean) {
    this.floorSel = h('select', { name: 'floor' }, index.floors.map((f) => h('option', { value: f.id ?? f.iri, selected: f === floor }, f.name)));
    this.m.el.id = 'traffic-map';
    root.append(
      h('div', { class: 'controls' },
        field('Floor', this.floorSel),
        h('label', null, this.liveBox, ' Live (now)'),
        field('Joint rehearsal file (bench fleet --replay)', this.fileIn),
      ),
      this.streamErr,
      this.m.el,
      h('div', { class: 'below-map' }, this.status),
      h('div', { class: 'replay', role: 'group', 'aria-label': 'Timeline of the schedule' },
        this.playBtn, field('Speed', this.speedSel), field('Time', this.slider), this.timeOut),
      legendEl(),
      this.table,
    );
    this.wire();
    this.m.drawStatic = (c) => this.drawStatic(c);
    this.m.drawDynamic = (c) => this.drawDynamic(c);
    this.raf = requestAnimationFrame(this.tick);
  }

  async start(): Promise<void> {
    if (!this.floor) add(this.table, h('p', null, 'No floor yet: import a map (POST /v1/maps).'));
    else await this.loadFloor();
  }

  private wire(): void {
    const { slider, liveBox, fileIn } = this;
    slider.addEventListener('input', () => {
      const [lo, hi] = this.span();
      this.setLive(false);
      this.nowMs = lo + (+slider.value / 1000) * (hi - lo);
      this.syncSlider();
      this.m.request();
    });
    liveBox.addEventListener('change', () => {
      if (liveBox.checked && this.replay) {
        this.replay = null;
        fileIn.value = '';
        void this.subscribe();
      }
      this.setLive(liveBox.checked);
    });
    this.playBtn.addEventListener('click', () => this.togglePlay());
    fileIn.addEventListener('change', () => void this.loadReplayFile());
    this.floorSel.addEventListener('change', () => {
      this.floor = this.index.floors.find((f) => (f.id ?? f.iri) === this.floorSel.value) ?? this.floor;
      this.replay = null;
      fileIn.value = '';
      this.setLive(true);
      void this.loadFloor();
    });
  }

  // ---- time ----

  /** The span the timeline covers: every plan's start to its end, and now when live. */
  private span(): [number, number] {
    let lo = Infinity;
    let hi = -Infinity;
    for (const s of this.plans.values()) {
      lo = Math.min(lo, startMs(s.it));
      hi = Math.max(hi, endMs(s.it));
    }
    if (this.live || !Number.isFinite(lo)) {
      lo = Math.min(lo, Date.now());
      hi = Math.max(hi, Date.now());
    }
    return [lo, Math.max(hi, lo + 1000)];
  }

  private syncSlider(): void {
    const [lo, hi] = this.span();
    const { nowMs } = this;
    this.slider.value = String(Math.round(((nowMs - lo) / (hi - lo)) * 1000));
    const rel = (nowMs - lo) / 1000;
    const text = this.replay
      ? `${rel.toFixed(1)} s of ${((hi - lo) / 1000).toFixed(1)} s`
      : `${new Date(nowMs).toLocaleTimeString()}${this.live ? ' (now)' : ''}`;
    this.timeOut.value = text;
    this.slider.setAttribute('aria-valuetext', text);
  }

  private setLive(on: boolean): void {
    this.live = on && !this.replay;
    this.liveBox.checked = this.live;
    if (this.live) this.stopPlay();
  }

  /** Every animation frame: the clock (now when live, the schedule's time when playing). */
  private readonly tick = (t: number): void => {
    if (!this.alive) return;
    if (this.live) this.nowMs = Date.now();
    else if (this.playing) {
      this.nowMs += (t - this.last) * (parseFloat(this.speedSel.value) || 1);
      if (this.nowMs >= this.span()[1]) this.stopPlay();
    }
    this.last = t;
    this.syncSlider();
    this.m.draw();
    this.raf = requestAnimationFrame(this.tick);
  };

  private togglePlay(): void {
    if (this.playing) return this.stopPlay();
    this.setLive(false);
    const [lo, hi] = this.span();
    if (this.nowMs >= hi) this.nowMs = lo;
    this.playing = true;
    this.playBtn.textContent = 'Pause';
    this.playBtn.setAttribute('aria-pressed', 'true');
  }

  private stopPlay(): void {
    this.playing = false;
    this.playBtn.textContent = 'Play';
    this.playBtn.setAttribute('aria-pressed', 'false');
  }

  // ---- drawing ----

  private drawStatic(c: CanvasRenderingContext2D): void {
    const { m } = this;
    drawAreas(c, m, this.areas);
    drawObjects(c, m, this.objects, false);
    for (const s of this.plans.values()) {
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
  }

  /** Each robot where its schedule puts it at the timeline's time (faint while it waits). */
  private drawDynamic(c: CanvasRenderingContext2D): void {
    const { m, nowMs } = this;
    let drawn = 0;
    for (const s of this.plans.values()) {
      const p = poseAt(s.it, nowMs);
      if (!p) continue;
      drawn++;
      const [sx, sy] = m.toScreen(p.x, p.y);
      const waiting = s.waits.some((w) => w.fromMs <= nowMs && nowMs < w.toMs);
      const r = Math.max(8, m.px(s.it.radius_m));
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
      c.lineTo(sx + Math.cos(p.yaw) * r, sy - Math.sin(p.yaw) * r);
      c.stroke();
      label(c, localName(s.it.robot) + (waiting ? ' (waits)' : ''), sx, sy - Math.max(12, m.px(s.it.radius_m) + 8), s.colour);
    }
    m.canvas.dataset.robotsDrawn = String(drawn);
  }

  // ---- the plans ----

  private renderTable(): void {
    const { table, plans, replay } = this;
    clear(table);
    this.root.dataset.plans = String(plans.size);
    this.root.dataset.version = String(this.version);
    const rows = [...plans.values()].sort((a, b) => startMs(a.it) - startMs(b.it));
    if (!rows.length) {
      table.append(h('p', { class: 'muted' }, replay ? 'The file holds no plans.' : 'No plan is committed on this floor now.'));
      return;
    }
    const outcomes = new Map((replay?.joint ?? []).map((j) => [j.robot, j]));
    table.append(h('table', null,
      h('thead', null, h('tr', null, ['robot', 'plan', 'revision', 'sets off', 'arrives', 'delay', 'waits', replay ? 'joint run' : 'expires', ''].map((c) => h('th', null, c)))),
      h('tbody', null, rows.map((s) => this.planRow(s, outcomes.get(s.it.robot)))),
    ));
  }

  private planRow(s: Shown, o: JointOutcome | undefined): HTMLElement {
    const { it } = s;
    const t = (ms: number) => new Date(ms).toLocaleTimeString();
    const waited = s.waits.reduce((sum, w) => sum + (w.toMs - w.fromMs) / 1000, 0);
    return h('tr', { 'data-plan': it.plan_id },
      h('td', null, h('span', { class: 'sw', style: `background:${s.colour}`, 'aria-hidden': 'true' }), ' ', localName(it.robot)),
      h('td', null, h('code', null, it.plan_id)),
      h('td', null, String(it.revision ?? 1)),
      h('td', null, t(startMs(it))),
      h('td', null, t(endMs(it))),
      h('td', null, `${fmt(it.delay_s, 1)} s`),
      h('td', { title: s.waits.map((w) => `${((w.toMs - w.fromMs) / 1000).toFixed(1)} s at (${fmt(w.x)}, ${fmt(w.y)})`).join('\n') },
        s.waits.length ? `${s.waits.length} (${waited.toFixed(1)} s)` : 'none'),
      h('td', { title: o?.reason ?? '' }, this.replay ? (o ? `${o.outcome} at ${fmt(o.time_s, 1)} s` : '—') : t(it.expires_unix_ms)),
      h('td', null, this.engineer && !this.replay
        ? h('button', { type: 'button', class: 'small', 'aria-label': `Cancel the plan of ${localName(it.robot)}`, onclick: () => void this.cancel(it.plan_id) }, 'Cancel')
        : null),
    );
  }

  private async cancel(id: string): Promise<void> {
    clearError(this.streamErr);
    try {
      await request(`/v1/plans/${encodeURIComponent(id)}`, { method: 'DELETE' });
    } catch (e) {
      showError(this.streamErr, e, 'cancel: ');
    }
  }

  private setPlans(list: Itinerary[]): void {
    this.plans.clear();
    for (const it of list) this.put(it);
  }

  /** An itinerary in: it replaces its robot's other one (a robot has one at most). */
  private put(it: Itinerary): void {
    for (const [id, s] of this.plans) if (s.it.robot === it.robot && id !== it.plan_id) this.plans.delete(id);
    this.plans.set(it.plan_id, { it, waits: waits(it), colour: robotColour(it.robot) });
  }

  private changed(what: string): void {
    const { plans, replay } = this;
    // An itinerary past its expiry leaves without an event.
    const now = Date.now();
    if (!replay) for (const [id, s] of plans) if (s.it.expires_unix_ms < now) plans.delete(id);
    this.status.textContent = `${replay ? 'Joint rehearsal' : 'Live'}: version ${this.version}, ${plans.size} plan${plans.size === 1 ? '' : 's'}. ${what}`;
    this.renderTable();
    this.m.invalidate();
  }

  // ---- the live stream ----

  private async subscribe(): Promise<void> {
    this.sub?.stop();
    this.sub = null;
    clearError(this.streamErr);
    if (!this.floor) return;
    this.setPlans([]);
    this.changed('Connecting…');
    this.sub = stream(`/v1/places/${encodeURIComponent(this.floor.iri)}/traffic/events`, {
      onEvent: (e) => this.onEvent(e),
      onError: (e) => showError(this.streamErr, e, 'live traffic: '),
      onOpen: () => clearError(this.streamErr),
    });
  }

  /** `snapshot` (the floor's traffic), `committed`, `revised` and `progressed` (an itinerary), `removed`. */
  private onEvent(e: SseEvent): void {
    if (!this.alive || this.replay) return;
    let d: Record<string, unknown>;
    try {
      d = JSON.parse(e.data);
    } catch {
      return;
    }
    this.version = Number(e.id) || this.version;
    if (e.event === 'snapshot') {
      this.setPlans((d as unknown as FloorTraffic).plans);
      this.changed('Snapshot received.');
    } else if (e.event === 'committed' || e.event === 'revised' || e.event === 'progressed') {
      const it = d.itinerary as Itinerary;
      this.put(it);
      const what = { committed: 'Committed', revised: `Revision ${it.revision} of`, progressed: 'Progress of' }[e.event];
      this.changed(`${what} ${localName(it.robot)}'s plan at ${new Date().toLocaleTimeString()}.`);
    } else if (e.event === 'removed') {
      this.plans.delete(String(d.plan_id));
      this.changed(`${localName(String(d.robot))}'s plan ${d.reason === 'replaced' ? 'replaced' : 'cancelled'} at ${new Date().toLocaleTimeString()}.`);
    }
  }

  // ---- a joint rehearsal from a file ----

  private async loadReplayFile(): Promise<void> {
    const f = this.fileIn.files?.[0];
    if (!f) return;
    clearError(this.streamErr);
    try {
      const r = JSON.parse(await f.text()) as JointReplay;
      if (!r || !Array.isArray(r.plans) || r.plans.some((p) => !Array.isArray(p?.trajectory))) {
        throw new Error('not a joint rehearsal: expected {"floor", "plans": [itineraries], "joint": [...]}');
      }
      this.sub?.stop();
      this.sub = null;
      this.replay = r;
      this.setLive(false);
      const onFloor = await this.showReplayFloor(r);
      this.version = r.version ?? 0;
      this.setPlans(r.plans);
      this.nowMs = this.span()[0];
      const arrived = (r.joint ?? []).filter((j) => j.outcome === 'reached').length;
      this.changed(`${r.map ?? localName(r.floor)}${r.scenario ? ` (${r.scenario})` : ''}: ${arrived} of ${r.plans.length} arrived in the joint run` +
        (onFloor ? '.' : '; the floor is not on this service, drawn without its map.'));
    } catch (e) {
      showError(this.streamErr, e, 'joint rehearsal: ');
    }
  }

  /** The replay's floor, when this service has it; else its plans' extent without a map. */
  private async showReplayFloor(r: JointReplay): Promise<PlaceView | undefined> {
    const onFloor = this.index.floors.find((fl) => fl.iri === r.floor);
    if (onFloor && onFloor !== this.floor) {
      this.floor = onFloor;
      this.floorSel.value = onFloor.id ?? onFloor.iri;
      await this.loadFloor(false);
    } else if (!onFloor) {
      this.areas = [];
      this.objects = [];
      this.m.setMap(null, null);
      const xs = r.plans.flatMap((p) => p.trajectory.map((q) => q.x));
      const ys = r.plans.flatMap((p) => p.trajectory.map((q) => q.y));
      if (xs.length) this.m.setBounds([Math.min(...xs) - 1, Math.min(...ys) - 1, Math.max(...xs) + 1, Math.max(...ys) + 1]);
    }
    return onFloor;
  }

  // ---- floor ----

  private async loadFloor(listen = true): Promise<void> {
    const floor = this.floor;
    if (!floor) return;
    this.areas = this.index.areasOn(floor);
    this.objects = [];
    if (listen) void this.subscribe();
    await data.showFloorOn(this.m, floor, () => this.alive, (o) => {
      this.objects = o;
      this.m.invalidate();
    }, (e) => showError(this.topErr, e, 'map: '));
  }

  destroy(): void {
    this.alive = false;
    cancelAnimationFrame(this.raf);
    this.sub?.stop();
    this.m.destroy();
  }
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
