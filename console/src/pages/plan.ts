// Plan: pick a robot, set a start (drag for heading) and goals on the map or in the form, run
// POST /v1/plan with a trace, and see every attempt; a timeline replays the rehearsal.

import { h, add, clear, field, fmt } from '../dom';
import {
  ApiError, postJson, showError, clearError,
  type AttemptReport, type PlaceView, type PlanApiRequest, type PlanApiResponse, type PlanOptions, type Point, type Pose, type RobotView,
} from '../api';
import * as data from '../data';
import type { MapObject } from '../data';
import { FieldErrors } from '../form';
import { MapCanvas, drawRobot, marker, polyline, label, type Tool } from '../mapview';
import { drawAreas, drawObjects } from '../layers';
import type { PageContext, Cleanup } from '../main';

declare global {
  interface Window {
    __replayStats?: ReplayStats;
  }
}

interface ReplayStats { frames: number; ms: number; drawMs: number; maxDrawMs: number; poses: number; lengthM: number }

const OK = '#16a34a';
const FAIL = '#ea580c';
const WAYPOINT = '#2563eb';
const REACH_M = 0.35;

/** What the replay drives: poses on one clock, the laser at each, the target each heads to. */
interface Track {
  poses: Pose[];
  t: number[];
  ranges: number[][] | null;
  active: number[]; // index into `targets` per pose
  targets: Point[];
  lengthM: number;
}

interface StartPose { x: number; y: number; yaw: number }
/** A failed attempt's reason, shown where it ended while the pointer is there. */
interface Tip { x: number; y: number; text: string }
/** A start or goal the service refused (in an obstacle, off the map), and the free point nearest. */
interface Blocked { x: number; y: number; nearest?: Point }

export async function mount(root: HTMLElement, ctx: PageContext): Promise<Cleanup> {
  root.append(h('h1', { id: 'page-title' }, 'Plan'));
  const topErr = h('div', { hidden: true });
  root.append(topErr);
  let all: PlaceView[], robots: RobotView[];
  try {
    [all, robots] = await Promise.all([data.places(), data.robots()]);
  } catch (e) {
    showError(topErr, e);
    return;
  }
  const index = data.indexPlaces(all);
  if (!index.floors.length) {
    root.append(h('p', null, 'No floor yet.'));
    return;
  }
  const floor = index.floors.find((f) => f.id === ctx.args[0] || f.iri === ctx.args[0]) ?? index.floors[0];
  const page = new PlanPage(root, topErr, index, robots, floor);
  await page.loadFloor();
  return () => page.destroy();
}

/** The page's controls: the request's fields, the map's click modes, the replay. */
function controls(index: data.FloorIndex, floor: PlaceView, robots: RobotView[]) {
  const modeName = 'plan-mode';
  return {
    floorSel: h('select', { name: 'floor' }, index.floors.map((f) => h('option', { value: f.id ?? f.iri, selected: f === floor }, f.name))),
    robotSel: h('select', { name: 'robot' }, robots.map((r) => h('option', { value: r.id ?? r.iri }, `${r.name} (${r.id ?? r.iri})`))),
    policyIn: h('input', { type: 'text', name: 'policy', placeholder: "the robot's newest", autocomplete: 'off' }),
    attemptsIn: h('input', { type: 'number', name: 'max_attempts', min: '1', max: '50', value: '5' }),
    seedIn: h('input', { type: 'number', name: 'seed', min: '0', value: '0' }),
    roadmapSel: h('select', { name: 'roadmap' }, ['auto', 'geometric', 'policy'].map((v) => h('option', { value: v }, v))),
    modeStart: h('input', { type: 'radio', name: modeName, value: 'start', checked: true }),
    modeGoal: h('input', { type: 'radio', name: modeName, value: 'goal' }),
    modePan: h('input', { type: 'radio', name: modeName, value: 'pan' }),
    sx: h('input', { type: 'number', step: 'any', name: 'start_x', inputmode: 'decimal' }),
    sy: h('input', { type: 'number', step: 'any', name: 'start_y', inputmode: 'decimal' }),
    syaw: h('input', { type: 'number', step: 'any', name: 'start_yaw', value: '0', inputmode: 'decimal' }),
    gx: h('input', { type: 'number', step: 'any', name: 'goal_x', inputmode: 'decimal' }),
    gy: h('input', { type: 'number', step: 'any', name: 'goal_y', inputmode: 'decimal' }),
    goalList: h('ol', { class: 'goal-list', 'aria-label': 'Goals' }),
    runBtn: h('button', { type: 'button', class: 'primary', id: 'run-plan' }, 'Run plan'),
    clearBtn: h('button', { type: 'button' }, 'Clear start and goals'),
    runErr: h('div', { hidden: true, id: 'plan-error' }),
    status: h('p', { class: 'status', 'aria-live': 'polite' }),
    coords: h('output', { class: 'coords' }, ' '),
    results: h('div', { class: 'plan-results', id: 'plan-results' }),
    slider: h('input', { type: 'range', min: '0', max: '0', value: '0', step: '1', name: 'timeline', disabled: true }),
    playBtn: h('button', { type: 'button', id: 'play', disabled: true }, 'Play'),
    speedSel: h('select', { name: 'speed' }, [1, 2, 5, 10, 20, 50].map((s) => h('option', { value: String(s), selected: s === 5 }, `${s}×`))),
    replaySel: h('select', { name: 'replay' }, h('option', { value: 'validated' }, 'validated run (every leg)')),
    timeOut: h('output', { class: 'replay-time' }, '—'),
  };
}

type Controls = ReturnType<typeof controls>;

class PlanPage {
  private readonly c: Controls;
  private readonly m: MapCanvas;
  private readonly fieldErrors: FieldErrors;
  private alive = true;
  private floor: PlaceView;
  private areas: PlaceView[] = [];
  private objects: MapObject[] = [];
  private start: StartPose | null = null;
  private readonly goals: Point[] = [];
  private report: PlanApiResponse | null = null;
  private highlighted: number | null = null; // attempt index
  private blocked: Blocked | null = null;
  private hoverTip: Tip | null = null;
  private dragging = false;
  private track: Track | null = null;
  private frame = 0;
  private playing = false;
  private raf = 0;

  constructor(root: HTMLElement, private readonly topErr: HTMLElement, private readonly index: data.FloorIndex,
    private readonly robots: RobotView[], floor: PlaceView) {
    this.floor = floor;
    this.c = controls(index, floor, robots);
    this.m = new MapCanvas('Plan map: click to set the start (drag for its heading), then click to add goals');
    this.m.el.id = 'plan-map';
    const c = this.c;
    // The request's fields (as `error.field` names them) and the controls that set them.
    this.fieldErrors = new FieldErrors(() => ({
      robot: c.robotSel, place: c.floorSel, policy: c.policyIn,
      start: c.sx, 'start.x': c.sx, 'start.y': c.sy, 'start.yaw': c.syaw,
      goal: c.gx, 'goal.y': c.gy, goals: c.gx,
      'options.max_attempts': c.attemptsIn, 'options.seed': c.seedIn, 'options.roadmap': c.roadmapSel,
    }));
    this.render(root);
    this.wireForm();
    this.wireMap();
    this.wireReplay();
    this.renderGoals();
    this.updateTool();
  }

  private render(root: HTMLElement): void {
    const { c, m } = this;
    root.append(
      h('div', { class: 'controls' },
        field('Floor', c.floorSel), field('Robot', c.robotSel), field('Policy id (optional)', c.policyIn),
        field('Max attempts', c.attemptsIn), field('Seed', c.seedIn), field('Roadmap', c.roadmapSel),
      ),
      h('fieldset', { class: 'inline' }, h('legend', null, 'A click on the map'),
        h('label', null, c.modeStart, ' sets the start (drag for heading)'),
        h('label', null, c.modeGoal, ' adds a goal'),
        h('label', null, c.modePan, ' pans (Shift+drag always pans)'),
      ),
      h('div', { class: 'split plan-split' },
        h('div', null, m.el, h('div', { class: 'below-map' }, c.coords, c.status),
          h('div', { class: 'replay', role: 'group', 'aria-label': 'Replay of the rehearsal' },
            field('Replay', c.replaySel), c.playBtn, field('Speed', c.speedSel), field('Timeline', c.slider), c.timeOut,
          ),
          legendEl(),
        ),
        h('div', { class: 'side' },
          h('form', { class: 'inline', 'aria-label': 'Start pose', onsubmit: (e: Event) => {
            e.preventDefault();
            const x = parseFloat(c.sx.value), y = parseFloat(c.sy.value);
            if (Number.isFinite(x) && Number.isFinite(y)) this.setStart({ x, y, yaw: parseFloat(c.syaw.value) || 0 });
          } }, field('Start x (m)', c.sx), field('Start y (m)', c.sy), field('Start yaw (rad)', c.syaw), h('button', { type: 'submit' }, 'Set start')),
          h('form', { class: 'inline', 'aria-label': 'Add a goal', onsubmit: (e: Event) => {
            e.preventDefault();
            const x = parseFloat(c.gx.value), y = parseFloat(c.gy.value);
            if (Number.isFinite(x) && Number.isFinite(y)) this.addGoal({ x, y });
          } }, field('Goal x (m)', c.gx), field('Goal y (m)', c.gy), h('button', { type: 'submit' }, 'Add goal')),
          h('h2', null, 'Goals'), c.goalList,
          h('div', { class: 'buttons' }, c.runBtn, c.clearBtn),
          c.runErr,
          c.results,
        ),
      ),
    );
  }

  // ---- floor, start and goals ----

  async loadFloor(): Promise<void> {
    this.areas = this.index.areasOn(this.floor);
    this.objects = [];
    await data.showFloorOn(this.m, this.floor, () => this.alive, (o) => {
      this.objects = o;
      this.m.invalidate();
    }, (e) => showError(this.topErr, e, 'map: '));
  }

  private robot(): RobotView | undefined {
    return this.robots.find((r) => (r.id ?? r.iri) === this.c.robotSel.value) ?? this.robots[0];
  }

  private wireForm(): void {
    const { c } = this;
    c.floorSel.addEventListener('change', () => {
      this.floor = this.index.floors.find((f) => (f.id ?? f.iri) === c.floorSel.value) ?? this.floor;
      this.start = null;
      this.goals.length = 0;
      this.setReport(null);
      this.renderGoals();
      void this.loadFloor();
    });
    c.clearBtn.addEventListener('click', () => {
      this.start = null;
      this.goals.length = 0;
      this.blocked = null;
      c.modeStart.checked = true;
      this.updateTool();
      this.renderGoals();
      this.m.request();
    });
    for (const r of [c.modeStart, c.modeGoal, c.modePan]) r.addEventListener('change', () => this.updateTool());
    c.runBtn.addEventListener('click', () => void this.run());
  }

  private setStart(p: StartPose): void {
    const { c, m } = this;
    this.start = p;
    c.sx.value = p.x.toFixed(2);
    c.sy.value = p.y.toFixed(2);
    c.syaw.value = p.yaw.toFixed(2);
    m.el.dataset.start = `${p.x.toFixed(3)},${p.y.toFixed(3)},${p.yaw.toFixed(3)}`;
    m.request();
  }

  private addGoal(p: Point): void {
    this.goals.push(p);
    this.renderGoals();
    this.m.request();
  }

  private renderGoals(): void {
    const { goals, m } = this;
    const list = this.c.goalList;
    clear(list);
    goals.forEach((g, i) =>
      list.append(h('li', null, `(${g.x.toFixed(2)}, ${g.y.toFixed(2)}) `,
        h('button', { type: 'button', class: 'small', 'aria-label': `Remove goal ${i + 1}`, onclick: () => {
          goals.splice(i, 1);
          this.renderGoals();
          m.request();
        } }, 'Remove'))),
    );
    if (!goals.length) list.append(h('li', { class: 'muted' }, 'none yet'));
    m.el.dataset.goals = String(goals.length);
  }

  // ---- the map: clicks, hover, drawing ----

  /** A press sets the start (a drag its heading, then the mode turns to goals) or adds a goal. */
  private readonly tool: Tool = {
    down: (x, y) => {
      if (this.c.modeStart.checked) {
        this.dragging = true;
        this.setStart({ x, y, yaw: 0 });
      } else if (this.c.modeGoal.checked) this.addGoal({ x, y });
    },
    move: (x, y) => {
      const s = this.start;
      if (this.dragging && s && Math.hypot(x - s.x, y - s.y) > 0.05) {
        this.setStart({ ...s, yaw: Math.atan2(y - s.y, x - s.x) });
      }
    },
    up: () => {
      if (this.dragging) {
        this.dragging = false;
        this.c.modeGoal.checked = true;
        this.updateTool();
      }
    },
  };

  private updateTool(): void {
    const pan = this.c.modePan.checked;
    this.m.tool = pan ? null : this.tool;
    this.m.canvas.style.cursor = pan ? 'grab' : 'crosshair';
  }

  private wireMap(): void {
    const { m } = this;
    m.onHover = (x, y, hx, hy) => this.hover(x, y, hx, hy);
    m.drawStatic = (c) => this.drawStatic(c);
    m.drawDynamic = (c) => this.drawDynamic(c);
  }

  private hover(x: number, y: number, hx: number, hy: number): void {
    const { m } = this;
    this.c.coords.value = `x ${x.toFixed(2)} m, y ${y.toFixed(2)} m`;
    // A failed attempt's end marker under the pointer: its reason.
    let tip: Tip | null = null;
    for (const a of this.report?.attempts ?? []) {
      if (a.outcome === 'reached') continue;
      const [ex, ey] = m.toScreen(a.end_pose.x, a.end_pose.y);
      if (Math.hypot(ex - hx, ey - hy) < 9) tip = { x: a.end_pose.x, y: a.end_pose.y, text: `attempt ${a.attempt} (leg ${a.leg}, ${a.controller}): ${a.outcome}: ${a.reason}` };
    }
    if (tip?.text !== this.hoverTip?.text) {
      this.hoverTip = tip;
      m.canvas.title = tip?.text ?? '';
      m.request();
    }
  }

  private drawStatic(c: CanvasRenderingContext2D): void {
    const { m, report } = this;
    drawAreas(c, m, this.areas);
    drawObjects(c, m, this.objects, false);
    if (!report) return;
    this.drawAttempts(c, report);
    // waypoints
    c.strokeStyle = WAYPOINT;
    c.lineWidth = 1;
    if (this.start) {
      polyline(c, m, [this.start, ...report.waypoints]);
      c.stroke();
    }
    report.waypoints.forEach((w) => marker(c, m, w.x, w.y, 'dot', WAYPOINT, 3.5));
  }

  /** Every attempt's drive (failed ones first, the validating ones over them), the highlighted
   *  attempt's roadmap path, and where each failed attempt ended. */
  private drawAttempts(c: CanvasRenderingContext2D, report: PlanApiResponse): void {
    const { m, highlighted } = this;
    const attempts = report.attempts;
    const reached = (i: number) => Number(attempts[i].outcome === 'reached');
    const order = attempts.map((_, i) => i).sort((i, j) => reached(i) - reached(j));
    for (const i of order) {
      const a = attempts[i];
      const traj = a.trace?.poses;
      if (!traj || traj.length < 2) continue;
      const ok = a.outcome === 'reached';
      c.strokeStyle = ok ? OK : FAIL;
      c.lineWidth = highlighted === i ? 4 : ok ? 2.5 : 1.5;
      c.setLineDash(ok ? [] : [6, 4]);
      polyline(c, m, traj);
      c.stroke();
    }
    c.setLineDash([]);
    if (!attempts.some((a) => a.trace?.poses.length) && report.trajectory.length > 1) {
      c.strokeStyle = OK;
      c.lineWidth = 2.5;
      polyline(c, m, report.trajectory);
      c.stroke();
    }
    const path = highlighted !== null ? attempts[highlighted]?.trace?.path : undefined;
    if (path?.length) {
      c.strokeStyle = '#7c3aed';
      c.lineWidth = 1.5;
      c.setLineDash([2, 3]);
      polyline(c, m, path);
      c.stroke();
      c.setLineDash([]);
    }
    for (const a of attempts) {
      if (a.outcome !== 'reached') marker(c, m, a.end_pose.x, a.end_pose.y, 'cross', '#b91c1c', 6);
    }
  }

  private drawDynamic(c: CanvasRenderingContext2D): void {
    const { m, blocked, start } = this;
    if (blocked) {
      marker(c, m, blocked.x, blocked.y, 'cross', '#dc2626', 9);
      if (blocked.nearest) marker(c, m, blocked.nearest.x, blocked.nearest.y, 'ring', '#16a34a', 7);
    }
    this.goals.forEach((g, i) => {
      marker(c, m, g.x, g.y, 'ring', '#9333ea', 8);
      const [gsx, gsy] = m.toScreen(g.x, g.y);
      label(c, `G${i + 1}`, gsx, gsy - 16, '#6b21a8');
    });
    if (start) drawRobot(c, m, start, this.robot()?.footprint, 'rgba(147, 51, 234, 0.35)', '#6b21a8');
    if (this.track) this.drawReplayFrame(c, this.track);
    if (this.hoverTip) this.drawTip(c, this.hoverTip);
  }

  /** The replay's robot at the current frame, its laser beams and the waypoint it heads to. */
  private drawReplayFrame(c: CanvasRenderingContext2D, track: Track): void {
    const { m } = this;
    const i = Math.min(this.frame, track.poses.length - 1);
    const p = track.poses[i];
    const laser = this.report?.laser;
    const r = track.ranges?.[i];
    if (laser && r) {
      const [px0, py0] = m.toScreen(p.x, p.y);
      c.lineWidth = 1;
      for (let k = 0; k < laser.angles_rad.length && k < r.length; k++) {
        const ang = (p.yaw ?? 0) + laser.angles_rad[k];
        const d = Math.min(r[k], laser.max_range_m);
        const [bx, by] = m.toScreen(p.x + d * Math.cos(ang), p.y + d * Math.sin(ang));
        c.strokeStyle = r[k] >= laser.max_range_m - 1e-6 ? 'rgba(220, 38, 38, 0.2)' : 'rgba(220, 38, 38, 0.7)';
        c.beginPath();
        c.moveTo(px0, py0);
        c.lineTo(bx, by);
        c.stroke();
      }
    }
    const w = track.targets[track.active[i]];
    if (w) {
      marker(c, m, w.x, w.y, 'ring', '#f59e0b', 10);
      marker(c, m, w.x, w.y, 'dot', '#f59e0b', 4);
    }
    drawRobot(c, m, p, this.robot()?.footprint);
  }

  private drawTip(c: CanvasRenderingContext2D, tip: Tip): void {
    const [tx, ty] = this.m.toScreen(tip.x, tip.y);
    c.font = '12px system-ui, sans-serif';
    const w = c.measureText(tip.text).width + 10;
    const bx = Math.min(tx + 10, this.m.cssW - w - 4);
    c.fillStyle = 'rgba(17,24,39,0.9)';
    c.fillRect(bx, ty - 26, w, 20);
    c.fillStyle = '#fff';
    c.textAlign = 'left';
    c.textBaseline = 'middle';
    c.fillText(tip.text, bx + 5, ty - 16);
  }

  // ---- run ----

  /** The plan request the form describes, with a trace to replay. */
  private request(start: StartPose): PlanApiRequest {
    const { c } = this;
    const options: PlanOptions = { trace: true };
    const n = parseInt(c.attemptsIn.value, 10);
    if (Number.isFinite(n)) options.max_attempts = n;
    const s = parseInt(c.seedIn.value, 10);
    if (Number.isFinite(s)) options.seed = s;
    const roadmap = c.roadmapSel.value;
    if (roadmap === 'geometric' || roadmap === 'policy') options.roadmap = roadmap;
    const policy = c.policyIn.value.trim();
    return {
      robot: c.robotSel.value, place: this.floor.id ?? this.floor.iri,
      start: { x: start.x, y: start.y, yaw: start.yaw }, goals: this.goals.map((g) => ({ x: g.x, y: g.y })), options,
      ...(policy ? { policy } : {}),
    };
  }

  private async run(): Promise<void> {
    const { c, m } = this;
    clearError(c.runErr);
    this.fieldErrors.clear();
    this.blocked = null;
    if (!this.start || !this.goals.length) {
      m.el.dataset.plan = 'error';
      return showError(c.runErr, new Error(!this.start ? 'set a start first: click the map or type it in the start form' : 'add at least one goal'));
    }
    const body = this.request(this.start);
    c.runBtn.disabled = true;
    c.status.textContent = 'Rehearsing in the mental simulation…';
    m.el.dataset.plan = 'running';
    const t0 = performance.now();
    try {
      const r = await postJson<PlanApiResponse>('/v1/plan', body);
      if (!this.alive) return;
      c.status.textContent = `Validated in ${((performance.now() - t0) / 1000).toFixed(1)} s.`;
      this.setReport(r);
    } catch (e) {
      this.showRunError(e);
      this.setReport(null);
    } finally {
      c.runBtn.disabled = false;
      m.request();
    }
  }

  /** The error in place: next to the field it names (`error.field`), a refused start or goal
   *  marked on the map with a button to move it to the nearest free point. */
  private showRunError(e: unknown): void {
    const { c, m } = this;
    c.status.textContent = '';
    m.el.dataset.plan = 'error';
    showError(c.runErr, e);
    this.fieldErrors.showError(e);
    if (!(e instanceof ApiError)) return;
    const d = e.details;
    if (!d || !d.point || typeof d.point !== 'object') return;
    const p = d.point as Point;
    const nf = (d.nearest_free as Point | null | undefined) ?? null;
    this.blocked = { x: p.x, y: p.y, nearest: nf ?? undefined };
    if (!nf) return;
    const isStart = e.field === 'start';
    c.runErr.append(h('button', { type: 'button', onclick: () => {
      if (isStart && this.start) this.setStart({ ...this.start, x: nf.x, y: nf.y });
      else {
        const gi = this.goals.findIndex((g) => Math.hypot(g.x - p.x, g.y - p.y) < 1e-6);
        if (gi >= 0) this.goals[gi] = { x: nf.x, y: nf.y };
        this.renderGoals();
      }
      this.blocked = null;
      clearError(c.runErr);
      this.fieldErrors.clear();
      m.request();
    } }, `Move it to the nearest free point (${fmt(nf.x)}, ${fmt(nf.y)})`));
  }

  private setReport(r: PlanApiResponse | null): void {
    const { c, m } = this;
    this.stop();
    this.report = r;
    this.highlighted = null;
    this.track = null;
    clear(c.results);
    clear(c.replaySel);
    c.replaySel.append(h('option', { value: 'validated' }, 'validated run (every leg)'));
    if (!r) {
      c.slider.disabled = c.playBtn.disabled = true;
      m.invalidate();
      return;
    }
    r.attempts.forEach((a, i) => c.replaySel.append(h('option', { value: String(i) }, `attempt ${a.attempt}, leg ${a.leg} (${a.controller}, ${a.outcome})`)));
    add(c.results, h('h2', null, 'Result'), r.note ? h('p', { class: 'notice' }, r.note) : null, summary(r),
      h('h3', null, 'Legs'), legsTable(r), h('h3', null, 'Attempts'), this.attemptsTable(r));
    this.selectTrack('validated');
    m.invalidate();
    m.draw();
    m.el.dataset.plan = 'drawn';
    m.el.dataset.attempts = String(r.attempts.length);
    m.el.dataset.validated = String(r.attempts.filter((a) => a.outcome === 'reached').length);
    m.el.dataset.trajectoryPoses = String(r.attempts.reduce((s, a) => s + (a.trace?.poses.length ?? 0), 0) || r.trajectory.length);
  }

  private attemptsTable(r: PlanApiResponse): HTMLElement {
    return h('table', { id: 'attempts' },
      h('thead', null, h('tr', null, ['#', 'leg', 'controller', 'outcome', 'why', 'sim. time', 'distance', 'clearance', ''].map((t) => h('th', null, t)))),
      h('tbody', null, r.attempts.map((a, i) => h('tr', { class: a.outcome === 'reached' ? 'ok' : 'failed', 'data-outcome': a.outcome },
        h('td', null, a.attempt), h('td', null, a.leg), h('td', null, a.controller),
        h('td', null, h('span', { class: `badge ${a.outcome === 'reached' ? 'good' : 'bad'}` }, a.outcome)),
        h('td', { class: 'reason' }, a.reason),
        h('td', null, `${fmt(a.simulated_time_s, 1)} s`), h('td', null, `${fmt(a.distance_m, 1)} m`), h('td', null, `${fmt(a.min_clearance_m, 3)} m`),
        h('td', null, h('button', { type: 'button', class: 'small', 'aria-label': `Show attempt ${a.attempt} of leg ${a.leg}`, onclick: () => this.highlight(i) }, 'Show')),
      ))),
    );
  }

  /** Shows attempt `i` over the others (and replays it), or, again, no longer. */
  private highlight(i: number): void {
    this.highlighted = this.highlighted === i ? null : i;
    if (this.highlighted !== null) {
      this.c.replaySel.value = String(i);
      this.selectTrack(String(i));
    }
    this.m.invalidate();
  }

  // ---- replay ----

  private wireReplay(): void {
    const { c } = this;
    c.replaySel.addEventListener('change', () => this.selectTrack(c.replaySel.value));
    c.slider.addEventListener('input', () => {
      this.frame = +c.slider.value;
      this.updateTime();
      this.m.request();
    });
    c.playBtn.addEventListener('click', () => (this.playing ? this.stop() : this.play()));
  }

  private selectTrack(which: string): void {
    const { c, report } = this;
    this.stop();
    if (!report) return;
    this.track = which === 'validated' ? validatedTrack(report) : attemptTrack(report, report.attempts[+which]);
    this.frame = 0;
    const n = this.track?.poses.length ?? 0;
    c.slider.max = String(Math.max(0, n - 1));
    c.slider.value = '0';
    c.slider.disabled = c.playBtn.disabled = n < 2;
    this.updateTime();
    this.m.request();
  }

  private updateTime(): void {
    const { c, track } = this;
    if (!track || !track.poses.length) {
      c.timeOut.value = '—';
      c.slider.setAttribute('aria-valuetext', 'no replay');
      return;
    }
    const t = track.t[this.frame] ?? 0;
    const text = `${t.toFixed(1)} s of ${track.t[track.t.length - 1].toFixed(1)} s`;
    c.timeOut.value = text;
    c.slider.setAttribute('aria-valuetext', text);
  }

  /** Plays the track at the chosen speed, one draw per animation frame (`window.__replayStats`
   *  counts them). */
  private play(): void {
    const { c, m } = this;
    const tr = this.track;
    if (!tr || tr.poses.length < 2) return;
    if (this.frame >= tr.poses.length - 1) this.frame = 0;
    this.playing = true;
    c.playBtn.textContent = 'Pause';
    c.playBtn.setAttribute('aria-pressed', 'true');
    const stats: ReplayStats = { frames: 0, ms: 0, drawMs: 0, maxDrawMs: 0, poses: tr.poses.length, lengthM: tr.lengthM };
    window.__replayStats = stats;
    const startWall = performance.now();
    let simT = tr.t[this.frame];
    let last = startWall;
    const step = (now: number) => {
      if (!this.playing || this.track !== tr) return;
      simT += ((now - last) / 1000) * (parseFloat(c.speedSel.value) || 1);
      last = now;
      while (this.frame < tr.t.length - 1 && tr.t[this.frame + 1] <= simT) this.frame++;
      const d0 = performance.now();
      m.draw();
      const d = performance.now() - d0;
      stats.frames += 1;
      stats.ms = performance.now() - startWall;
      stats.drawMs += d;
      stats.maxDrawMs = Math.max(stats.maxDrawMs, d);
      c.slider.value = String(this.frame);
      if ((stats.frames & 7) === 0) this.updateTime();
      if (this.frame >= tr.poses.length - 1) {
        this.stop();
        return;
      }
      this.raf = requestAnimationFrame(step);
    };
    this.raf = requestAnimationFrame(step);
  }

  private stop(): void {
    if (!this.playing) return;
    this.playing = false;
    cancelAnimationFrame(this.raf);
    this.c.playBtn.textContent = 'Play';
    this.c.playBtn.setAttribute('aria-pressed', 'false');
    this.updateTime();
  }

  destroy(): void {
    this.alive = false;
    this.stop();
    this.m.destroy();
  }
}

function summary(r: PlanApiResponse): HTMLElement {
  const pairs: [string, unknown][] = [
    ['simulated time', `${fmt(r.simulated_time_s, 1)} s`],
    ['distance driven', `${fmt(r.distance_m, 1)} m`],
    ['min clearance', `${fmt(r.min_clearance_m, 3)} m`],
    ['replans', r.replans],
    ['controller', r.controller],
    ['policy', r.policy ?? '—'],
    ['roadmap', `${r.roadmap.kind}, ${r.roadmap.samples} samples, seed ${r.roadmap.seed}${r.roadmap.cached ? ' (cached)' : ''}`],
    ['waypoints', r.waypoints.length],
    ['service time', `${fmt(r.service_ms, 0)} ms`],
  ];
  return h('dl', { class: 'kv' }, pairs.flatMap(([k, v]) => [h('dt', null, k), h('dd', null, String(v))]));
}

function legsTable(r: PlanApiResponse): HTMLElement {
  return h('table', { id: 'legs' },
    h('thead', null, h('tr', null, ['leg', 'to goal', 'validated by', 'roadmap', 'attempts', 'sim. time', 'distance', 'clearance'].map((t) => h('th', null, t)))),
    h('tbody', null, r.legs.map((l, i) => h('tr', null,
      h('td', null, i), h('td', null, `G${l.goal_index + 1}`), h('td', null, l.controller), h('td', null, l.roadmap),
      h('td', null, l.attempts), h('td', null, `${fmt(l.simulated_time_s, 1)} s`), h('td', null, `${fmt(l.distance_m, 1)} m`),
      h('td', null, `${fmt(l.min_clearance_m, 3)} m`),
    ))),
  );
}

/** An attempt's recorded times, else its poses spread evenly over its simulated time. */
function timesOf(a: AttemptReport, poses: Pose[]): number[] {
  const ts = a.trace?.times_s;
  return ts && ts.length === poses.length ? ts : poses.map((_, i) => (i * a.simulated_time_s) / Math.max(1, poses.length - 1));
}

/** The validating attempts of every leg, one after the other on one clock. */
function validatedTrack(r: PlanApiResponse): Track | null {
  const byLeg = new Map<number, AttemptReport>();
  for (const a of r.attempts) if (a.outcome === 'reached' && a.trace?.poses.length) byLeg.set(a.leg, a);
  const legs = [...byLeg.keys()].sort((a, b) => a - b);
  const poses: Pose[] = [], t: number[] = [], ranges: number[][] = [];
  let haveRanges = true;
  let offset = 0;
  for (const leg of legs) {
    const a = byLeg.get(leg)!;
    const tr = a.trace!.poses;
    const ts = timesOf(a, tr);
    for (let i = 0; i < tr.length; i++) {
      poses.push(tr[i]);
      t.push(offset + ts[i]);
      const ri = a.trace!.ranges[i];
      if (ri) ranges.push(ri);
      else haveRanges = false;
    }
    offset += ts[ts.length - 1] ?? 0;
  }
  if (!poses.length) {
    if (r.trajectory.length < 2) return null;
    const n = r.trajectory.length;
    return withTargets(r.trajectory, r.trajectory.map((_, i) => (i * r.simulated_time_s) / (n - 1)), null, r.waypoints);
  }
  return withTargets(poses, t, haveRanges ? ranges : null, r.waypoints);
}

function attemptTrack(r: PlanApiResponse, a: AttemptReport | undefined): Track | null {
  const trace = a?.trace;
  if (!a || !trace?.poses.length) return null;
  const tr = trace.poses;
  const targets = trace.path.length ? trace.path : r.waypoints;
  return withTargets(tr, timesOf(a, tr), trace.ranges.length === tr.length ? trace.ranges : null, targets);
}

/** Which target is active at each pose: the first one not yet come within REACH_M of. */
function withTargets(poses: Pose[], t: number[], ranges: number[][] | null, targets: Point[]): Track {
  const active: number[] = new Array(poses.length);
  let w = 0;
  let lengthM = 0;
  for (let i = 0; i < poses.length; i++) {
    const p = poses[i];
    if (i) lengthM += Math.hypot(p.x - poses[i - 1].x, p.y - poses[i - 1].y);
    while (w < targets.length - 1 && Math.hypot(targets[w].x - p.x, targets[w].y - p.y) < REACH_M) w++;
    active[i] = w;
  }
  return { poses, t, ranges, active, targets, lengthM };
}

function legendEl(): HTMLElement {
  const sw = (cls: string) => h('span', { class: `sw ${cls}`, 'aria-hidden': 'true' });
  return h('div', { class: 'legend', 'aria-label': 'Legend' },
    h('span', null, sw('sw-ok'), 'validating run'),
    h('span', null, sw('sw-fail'), 'failed attempt'),
    h('span', null, sw('sw-end'), 'where it failed (hover for why)'),
    h('span', null, sw('sw-wp'), 'waypoint'),
    h('span', null, sw('sw-active'), 'active waypoint'),
    h('span', null, sw('sw-beam'), 'laser beam'),
    h('span', null, sw('sw-start'), 'start and goals'),
  );
}
