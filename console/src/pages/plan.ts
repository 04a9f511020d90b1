// Plan: pick a robot, set a start (drag for heading) and goals on the map or in the form, run
// POST /v1/plan with a trace, and see every attempt; a timeline replays the rehearsal.

import { h, add, clear, field, fmt } from '../dom';
import { ApiError, postJson, showError, clearError, type Attempt, type PlaceView, type PlanReport, type Pose, type RobotView } from '../api';
import * as data from '../data';
import { MapCanvas, drawRobot, marker, polyline, label } from '../mapview';
import { drawAreas, drawObjects } from '../layers';
import type { PageContext, Cleanup } from '../main';

declare global {
  interface Window {
    __replayStats?: { frames: number; ms: number; drawMs: number; maxDrawMs: number; poses: number; lengthM: number };
  }
}

const OK = '#16a34a';
const FAIL = '#ea580c';
const WAYPOINT = '#2563eb';
const REACH_M = 0.35;

interface Track {
  poses: Pose[];
  t: number[];
  ranges: number[][] | null;
  active: number[]; // index into `targets` per pose
  targets: { x: number; y: number }[];
  lengthM: number;
}

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
  let floor = index.floors.find((f) => f.id === ctx.args[0] || f.iri === ctx.args[0]) ?? index.floors[0];
  let alive = true;

  // ---- state ----
  let start: { x: number; y: number; yaw: number } | null = null;
  const goals: { x: number; y: number }[] = [];
  let report: PlanReport | null = null;
  let highlighted: number | null = null; // attempt index
  let blocked: { x: number; y: number; nearest?: { x: number; y: number } } | null = null;
  let track: Track | null = null;
  let frame = 0;
  let playing = false;
  let hoverTip: { x: number; y: number; text: string } | null = null;

  // ---- controls ----
  const floorSel = h('select', { name: 'floor' }, index.floors.map((f) => h('option', { value: f.id ?? f.iri, selected: f === floor }, f.name)));
  const robotSel = h('select', { name: 'robot' }, robots.map((r) => h('option', { value: r.id ?? r.iri }, `${r.name} (${r.id ?? r.iri})`)));
  const policyIn = h('input', { type: 'text', name: 'policy', placeholder: "the robot's newest", autocomplete: 'off' });
  const attemptsIn = h('input', { type: 'number', name: 'max_attempts', min: '1', max: '50', value: '5' });
  const seedIn = h('input', { type: 'number', name: 'seed', min: '0', value: '0' });
  const roadmapSel = h('select', { name: 'roadmap' }, ['auto', 'geometric', 'policy'].map((v) => h('option', { value: v }, v)));
  const modeName = 'plan-mode';
  const modeStart = h('input', { type: 'radio', name: modeName, value: 'start', checked: true });
  const modeGoal = h('input', { type: 'radio', name: modeName, value: 'goal' });
  const modePan = h('input', { type: 'radio', name: modeName, value: 'pan' });
  const sx = h('input', { type: 'number', step: 'any', name: 'start_x', inputmode: 'decimal' });
  const sy = h('input', { type: 'number', step: 'any', name: 'start_y', inputmode: 'decimal' });
  const syaw = h('input', { type: 'number', step: 'any', name: 'start_yaw', value: '0', inputmode: 'decimal' });
  const gx = h('input', { type: 'number', step: 'any', name: 'goal_x', inputmode: 'decimal' });
  const gy = h('input', { type: 'number', step: 'any', name: 'goal_y', inputmode: 'decimal' });
  const goalList = h('ol', { class: 'goal-list', 'aria-label': 'Goals' });
  const runBtn = h('button', { type: 'button', class: 'primary', id: 'run-plan' }, 'Run plan');
  const clearBtn = h('button', { type: 'button' }, 'Clear start and goals');
  const runErr = h('div', { hidden: true, id: 'plan-error' });
  const status = h('p', { class: 'status', 'aria-live': 'polite' });
  const coords = h('output', { class: 'coords' }, ' ');
  const results = h('div', { class: 'plan-results', id: 'plan-results' });

  // replay
  const slider = h('input', { type: 'range', min: '0', max: '0', value: '0', step: '1', name: 'timeline', disabled: true });
  const playBtn = h('button', { type: 'button', id: 'play', disabled: true }, 'Play');
  const speedSel = h('select', { name: 'speed' }, [1, 2, 5, 10, 20, 50].map((s) => h('option', { value: String(s), selected: s === 5 }, `${s}×`)));
  const replaySel = h('select', { name: 'replay' }, h('option', { value: 'validated' }, 'validated run (every leg)'));
  const timeOut = h('output', { class: 'replay-time' }, '—');

  const m = new MapCanvas('Plan map: click to set the start (drag for its heading), then click to add goals');
  m.el.id = 'plan-map';

  root.append(
    h('div', { class: 'controls' },
      field('Floor', floorSel), field('Robot', robotSel), field('Policy id (optional)', policyIn),
      field('Max attempts', attemptsIn), field('Seed', seedIn), field('Roadmap', roadmapSel),
    ),
    h('fieldset', { class: 'inline' }, h('legend', null, 'A click on the map'),
      h('label', null, modeStart, ' sets the start (drag for heading)'),
      h('label', null, modeGoal, ' adds a goal'),
      h('label', null, modePan, ' pans (Shift+drag always pans)'),
    ),
    h('div', { class: 'split plan-split' },
      h('div', null, m.el, h('div', { class: 'below-map' }, coords, status),
        h('div', { class: 'replay', role: 'group', 'aria-label': 'Replay of the rehearsal' },
          field('Replay', replaySel), playBtn, field('Speed', speedSel), field('Timeline', slider), timeOut,
        ),
        legendEl(),
      ),
      h('div', { class: 'side' },
        h('form', { class: 'inline', 'aria-label': 'Start pose', onsubmit: (e: Event) => {
          e.preventDefault();
          const x = parseFloat(sx.value), y = parseFloat(sy.value);
          if (Number.isFinite(x) && Number.isFinite(y)) setStart({ x, y, yaw: parseFloat(syaw.value) || 0 });
        } }, field('Start x (m)', sx), field('Start y (m)', sy), field('Start yaw (rad)', syaw), h('button', { type: 'submit' }, 'Set start')),
        h('form', { class: 'inline', 'aria-label': 'Add a goal', onsubmit: (e: Event) => {
          e.preventDefault();
          const x = parseFloat(gx.value), y = parseFloat(gy.value);
          if (Number.isFinite(x) && Number.isFinite(y)) addGoal({ x, y });
        } }, field('Goal x (m)', gx), field('Goal y (m)', gy), h('button', { type: 'submit' }, 'Add goal')),
        h('h2', null, 'Goals'), goalList,
        h('div', { class: 'buttons' }, runBtn, clearBtn),
        runErr,
        results,
      ),
    ),
  );

  // ---- floor ----
  let areas: PlaceView[] = [];
  let objects: Awaited<ReturnType<typeof data.objects>> = [];
  async function loadFloor(): Promise<void> {
    areas = index.areasOn(floor);
    objects = [];
    await data.showFloorOn(m, floor, () => alive, (o) => { objects = o; m.invalidate(); }, (e) => showError(topErr, e, 'map: '));
  }
  floorSel.addEventListener('change', () => {
    floor = index.floors.find((f) => (f.id ?? f.iri) === floorSel.value) ?? floor;
    start = null;
    goals.length = 0;
    setReport(null);
    renderGoals();
    void loadFloor();
  });
  const robot = () => robots.find((r) => (r.id ?? r.iri) === robotSel.value) ?? robots[0];

  // ---- start and goals ----
  function setStart(p: { x: number; y: number; yaw: number }): void {
    start = p;
    sx.value = p.x.toFixed(2);
    sy.value = p.y.toFixed(2);
    syaw.value = p.yaw.toFixed(2);
    m.el.dataset.start = `${p.x.toFixed(3)},${p.y.toFixed(3)},${p.yaw.toFixed(3)}`;
    m.request();
  }
  function addGoal(p: { x: number; y: number }): void {
    goals.push(p);
    renderGoals();
    m.request();
  }
  function renderGoals(): void {
    clear(goalList);
    goals.forEach((g, i) =>
      goalList.append(h('li', null, `(${g.x.toFixed(2)}, ${g.y.toFixed(2)}) `,
        h('button', { type: 'button', class: 'small', 'aria-label': `Remove goal ${i + 1}`, onclick: () => {
          goals.splice(i, 1);
          renderGoals();
          m.request();
        } }, 'Remove'))),
    );
    if (!goals.length) goalList.append(h('li', { class: 'muted' }, 'none yet'));
    m.el.dataset.goals = String(goals.length);
  }
  renderGoals();
  clearBtn.addEventListener('click', () => {
    start = null;
    goals.length = 0;
    blocked = null;
    modeStart.checked = true;
    updateTool();
    renderGoals();
    m.request();
  });

  let dragging = false;
  const tool = {
    down(x: number, y: number) {
      if (modeStart.checked) {
        dragging = true;
        setStart({ x, y, yaw: 0 });
      } else if (modeGoal.checked) addGoal({ x, y });
    },
    move(x: number, y: number) {
      if (dragging && start && Math.hypot(x - start.x, y - start.y) > 0.05) {
        setStart({ ...start, yaw: Math.atan2(y - start.y, x - start.x) });
      }
    },
    up() {
      if (dragging) {
        dragging = false;
        modeGoal.checked = true;
        updateTool();
      }
    },
  };
  function updateTool(): void {
    m.tool = modePan.checked ? null : tool;
    m.canvas.style.cursor = modePan.checked ? 'grab' : 'crosshair';
  }
  for (const r of [modeStart, modeGoal, modePan]) r.addEventListener('change', updateTool);
  updateTool();

  m.onHover = (x, y, hx, hy) => {
    coords.value = `x ${x.toFixed(2)} m, y ${y.toFixed(2)} m`;
    // A failed attempt's end marker under the pointer: its reason.
    let tip: typeof hoverTip = null;
    if (report) {
      for (const a of report.attempts) {
        if (a.outcome === 'reached') continue;
        const [ex, ey] = m.toScreen(a.end_pose.x, a.end_pose.y);
        if (Math.hypot(ex - hx, ey - hy) < 9) tip = { x: a.end_pose.x, y: a.end_pose.y, text: `attempt ${a.attempt} (leg ${a.leg}, ${a.controller}): ${a.outcome}: ${a.reason}` };
      }
    }
    if (tip?.text !== hoverTip?.text) {
      hoverTip = tip;
      m.canvas.title = tip?.text ?? '';
      m.request();
    }
  };

  // ---- drawing ----
  m.drawStatic = (c) => {
    drawAreas(c, m, areas);
    drawObjects(c, m, objects, false);
    if (!report) return;
    // every attempt: failed first, validating over them
    const order = report.attempts.map((_, i) => i).sort((i, j) => Number(report!.attempts[i].outcome === 'reached') - Number(report!.attempts[j].outcome === 'reached'));
    for (const i of order) {
      const a = report.attempts[i];
      const traj = a.trajectory;
      if (!traj || traj.length < 2) continue;
      const ok = a.outcome === 'reached';
      c.strokeStyle = ok ? OK : FAIL;
      c.lineWidth = highlighted === i ? 4 : ok ? 2.5 : 1.5;
      c.setLineDash(ok ? [] : [6, 4]);
      polyline(c, m, traj);
      c.stroke();
    }
    c.setLineDash([]);
    if (!report.attempts.some((a) => a.trajectory?.length) && report.trajectory.length > 1) {
      c.strokeStyle = OK;
      c.lineWidth = 2.5;
      polyline(c, m, report.trajectory);
      c.stroke();
    }
    if (highlighted !== null && report.attempts[highlighted]?.path) {
      c.strokeStyle = '#7c3aed';
      c.lineWidth = 1.5;
      c.setLineDash([2, 3]);
      polyline(c, m, report.attempts[highlighted].path!);
      c.stroke();
      c.setLineDash([]);
    }
    for (const a of report.attempts) {
      if (a.outcome !== 'reached') marker(c, m, a.end_pose.x, a.end_pose.y, 'cross', '#b91c1c', 6);
    }
    // waypoints
    c.strokeStyle = WAYPOINT;
    c.lineWidth = 1;
    if (start) {
      polyline(c, m, [start, ...report.waypoints]);
      c.stroke();
    }
    report.waypoints.forEach((w) => marker(c, m, w.x, w.y, 'dot', WAYPOINT, 3.5));
  };
  m.drawDynamic = (c) => {
    if (blocked) {
      marker(c, m, blocked.x, blocked.y, 'cross', '#dc2626', 9);
      if (blocked.nearest) marker(c, m, blocked.nearest.x, blocked.nearest.y, 'ring', '#16a34a', 7);
    }
    goals.forEach((g, i) => {
      marker(c, m, g.x, g.y, 'ring', '#9333ea', 8);
      const [gsx, gsy] = m.toScreen(g.x, g.y);
      label(c, `G${i + 1}`, gsx, gsy - 16, '#6b21a8');
    });
    if (start) drawRobot(c, m, start, robot()?.footprint, 'rgba(147, 51, 234, 0.35)', '#6b21a8');
    if (track) {
      const i = Math.min(frame, track.poses.length - 1);
      const p = track.poses[i];
      const laser = report?.laser;
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
      drawRobot(c, m, p, robot()?.footprint);
    }
    if (hoverTip) {
      const [tx, ty] = m.toScreen(hoverTip.x, hoverTip.y);
      c.font = '12px system-ui, sans-serif';
      const w = c.measureText(hoverTip.text).width + 10;
      const bx = Math.min(tx + 10, m.cssW - w - 4);
      c.fillStyle = 'rgba(17,24,39,0.9)';
      c.fillRect(bx, ty - 26, w, 20);
      c.fillStyle = '#fff';
      c.textAlign = 'left';
      c.textBaseline = 'middle';
      c.fillText(hoverTip.text, bx + 5, ty - 16);
    }
  };

  // ---- run ----
  runBtn.addEventListener('click', () => void run());
  async function run(): Promise<void> {
    clearError(runErr);
    blocked = null;
    if (!start || !goals.length) {
      m.el.dataset.plan = 'error';
      return showError(runErr, new Error(!start ? 'set a start first: click the map or type it in the start form' : 'add at least one goal'));
    }
    const options: Record<string, unknown> = { trace: true };
    const n = parseInt(attemptsIn.value, 10);
    if (Number.isFinite(n)) options.max_attempts = n;
    const s = parseInt(seedIn.value, 10);
    if (Number.isFinite(s)) options.seed = s;
    if (roadmapSel.value !== 'auto') options.roadmap = roadmapSel.value;
    const body: Record<string, unknown> = {
      robot: robotSel.value, place: floor.id ?? floor.iri,
      start: { x: start.x, y: start.y, yaw: start.yaw }, goals: goals.map((g) => ({ x: g.x, y: g.y })), options,
    };
    if (policyIn.value.trim()) body.policy = policyIn.value.trim();
    runBtn.disabled = true;
    status.textContent = 'Rehearsing in the mental simulation…';
    m.el.dataset.plan = 'running';
    const t0 = performance.now();
    try {
      let r: PlanReport;
      try {
        r = await postJson<PlanReport>('/v1/plan', body);
      } catch (e) {
        // A service without the trace option yet: ask again without it.
        if (e instanceof ApiError && (e.status === 400 || e.status === 422) && /trace/.test(e.message)) {
          delete options.trace;
          r = await postJson<PlanReport>('/v1/plan', body);
        } else throw e;
      }
      if (!alive) return;
      normaliseReport(r);
      status.textContent = `Validated in ${((performance.now() - t0) / 1000).toFixed(1)} s.`;
      setReport(r);
    } catch (e) {
      status.textContent = '';
      m.el.dataset.plan = 'error';
      showError(runErr, e);
      const d = e instanceof ApiError ? (e.details as Record<string, unknown> | null) : null;
      if (d && d.point && typeof d.point === 'object') {
        const p = d.point as { x: number; y: number };
        const nf = d.nearest_free as { x: number; y: number } | null;
        blocked = { x: p.x, y: p.y, nearest: nf ?? undefined };
        if (nf) {
          runErr.append(h('button', { type: 'button', onclick: () => {
            if (d.which === 'start' && start) setStart({ ...start, x: nf.x, y: nf.y });
            else {
              const gi = goals.findIndex((g) => Math.hypot(g.x - p.x, g.y - p.y) < 1e-6);
              if (gi >= 0) goals[gi] = { x: nf.x, y: nf.y };
              renderGoals();
            }
            blocked = null;
            clearError(runErr);
            m.request();
          } }, `Move it to the nearest free point (${fmt(nf.x)}, ${fmt(nf.y)})`));
        }
      }
      setReport(null);
    } finally {
      runBtn.disabled = false;
      m.request();
    }
  }

  function setReport(r: PlanReport | null): void {
    stop();
    report = r;
    highlighted = null;
    track = null;
    clear(results);
    clear(replaySel);
    replaySel.append(h('option', { value: 'validated' }, 'validated run (every leg)'));
    if (!r) {
      slider.disabled = playBtn.disabled = true;
      m.invalidate();
      return;
    }
    r.attempts.forEach((a, i) => replaySel.append(h('option', { value: String(i) }, `attempt ${a.attempt}, leg ${a.leg} (${a.controller}, ${a.outcome})`)));
    renderResults(r);
    selectTrack('validated');
    m.invalidate();
    m.draw();
    const validated = r.attempts.filter((a) => a.outcome === 'reached').length;
    m.el.dataset.plan = 'drawn';
    m.el.dataset.attempts = String(r.attempts.length);
    m.el.dataset.validated = String(validated);
    m.el.dataset.trajectoryPoses = String(r.attempts.reduce((s, a) => s + (a.trajectory?.length ?? 0), 0) || r.trajectory.length);
  }

  function renderResults(r: PlanReport): void {
    const dl = (pairs: [string, unknown][]) => h('dl', { class: 'kv' }, pairs.flatMap(([k, v]) => [h('dt', null, k), h('dd', null, String(v))]));
    add(results,
      h('h2', null, 'Result'),
      r.note ? h('p', { class: 'notice' }, r.note) : null,
      dl([
        ['simulated time', `${fmt(r.simulated_time_s, 1)} s`],
        ['distance driven', `${fmt(r.distance_m, 1)} m`],
        ['min clearance', `${fmt(r.min_clearance_m, 3)} m`],
        ['replans', r.replans],
        ['controller', r.controller],
        ['policy', r.policy ?? '—'],
        ['roadmap', `${r.roadmap.kind}, ${r.roadmap.samples} samples, seed ${r.roadmap.seed}${r.roadmap.cached ? ' (cached)' : ''}`],
        ['waypoints', r.waypoints.length],
        ['service time', r.service_ms !== undefined ? `${fmt(r.service_ms, 0)} ms` : '—'],
      ]),
      h('h3', null, 'Legs'),
      h('table', { id: 'legs' },
        h('thead', null, h('tr', null, ['leg', 'to goal', 'validated by', 'roadmap', 'attempts', 'sim. time', 'distance', 'clearance'].map((t) => h('th', null, t)))),
        h('tbody', null, r.legs.map((l, i) => h('tr', null,
          h('td', null, i), h('td', null, `G${l.goal_index + 1}`), h('td', null, l.controller), h('td', null, l.roadmap),
          h('td', null, l.attempts), h('td', null, `${fmt(l.simulated_time_s, 1)} s`), h('td', null, `${fmt(l.distance_m, 1)} m`),
          h('td', null, `${fmt(l.min_clearance_m, 3)} m`),
        ))),
      ),
      h('h3', null, 'Attempts'),
      h('table', { id: 'attempts' },
        h('thead', null, h('tr', null, ['#', 'leg', 'controller', 'outcome', 'why', 'sim. time', 'distance', 'clearance', ''].map((t) => h('th', null, t)))),
        h('tbody', null, r.attempts.map((a, i) => h('tr', { class: a.outcome === 'reached' ? 'ok' : 'failed', 'data-outcome': a.outcome },
          h('td', null, a.attempt), h('td', null, a.leg), h('td', null, a.controller),
          h('td', null, h('span', { class: `badge ${a.outcome === 'reached' ? 'good' : 'bad'}` }, a.outcome)),
          h('td', { class: 'reason' }, a.reason),
          h('td', null, `${fmt(a.simulated_time_s, 1)} s`), h('td', null, `${fmt(a.distance_m, 1)} m`), h('td', null, `${fmt(a.min_clearance_m, 3)} m`),
          h('td', null, h('button', { type: 'button', class: 'small', 'aria-label': `Show attempt ${a.attempt} of leg ${a.leg}`, onclick: () => {
            highlighted = highlighted === i ? null : i;
            if (highlighted !== null) {
              replaySel.value = String(i);
              selectTrack(String(i));
            }
            m.invalidate();
          } }, 'Show')),
        ))),
      ),
    );
  }

  // ---- replay ----
  function selectTrack(which: string): void {
    stop();
    if (!report) return;
    track = which === 'validated' ? validatedTrack(report) : attemptTrack(report, report.attempts[+which]);
    frame = 0;
    const n = track?.poses.length ?? 0;
    slider.max = String(Math.max(0, n - 1));
    slider.value = '0';
    slider.disabled = playBtn.disabled = n < 2;
    updateTime();
    m.request();
  }
  replaySel.addEventListener('change', () => selectTrack(replaySel.value));
  slider.addEventListener('input', () => {
    frame = +slider.value;
    updateTime();
    m.request();
  });
  function updateTime(): void {
    if (!track || !track.poses.length) {
      timeOut.value = '—';
      slider.setAttribute('aria-valuetext', 'no replay');
      return;
    }
    const t = track.t[frame] ?? 0;
    const text = `${t.toFixed(1)} s of ${track.t[track.t.length - 1].toFixed(1)} s`;
    timeOut.value = text;
    slider.setAttribute('aria-valuetext', text);
  }

  let raf = 0;
  playBtn.addEventListener('click', () => (playing ? stop() : play()));
  function play(): void {
    if (!track || track.poses.length < 2) return;
    if (frame >= track.poses.length - 1) frame = 0;
    playing = true;
    playBtn.textContent = 'Pause';
    playBtn.setAttribute('aria-pressed', 'true');
    const tr = track;
    const stats = { frames: 0, ms: 0, drawMs: 0, maxDrawMs: 0, poses: tr.poses.length, lengthM: tr.lengthM };
    window.__replayStats = stats;
    const startWall = performance.now();
    let simT = tr.t[frame];
    let last = startWall;
    const step = (now: number) => {
      if (!playing || track !== tr) return;
      const speed = parseFloat(speedSel.value) || 1;
      simT += ((now - last) / 1000) * speed;
      last = now;
      while (frame < tr.t.length - 1 && tr.t[frame + 1] <= simT) frame++;
      const d0 = performance.now();
      m.draw();
      const d = performance.now() - d0;
      stats.frames += 1;
      stats.ms = performance.now() - startWall;
      stats.drawMs += d;
      stats.maxDrawMs = Math.max(stats.maxDrawMs, d);
      slider.value = String(frame);
      if ((stats.frames & 7) === 0) updateTime();
      if (frame >= tr.poses.length - 1) {
        stop();
        return;
      }
      raf = requestAnimationFrame(step);
    };
    raf = requestAnimationFrame(step);
  }
  function stop(): void {
    if (!playing) return;
    playing = false;
    cancelAnimationFrame(raf);
    playBtn.textContent = 'Play';
    playBtn.setAttribute('aria-pressed', 'false');
    updateTime();
  }

  await loadFloor();
  return () => {
    alive = false;
    stop();
    m.destroy();
  };
}

/** The contract's per-attempt `trajectory`, `t`, `ranges`, `path` ([x, y] pairs), also from
 *  the variant that nests them as `trace: {poses, times_s, ranges, path: [{x, y}]}`. */
export function normaliseReport(r: PlanReport): void {
  for (const a of r.attempts) {
    const tr = (a as unknown as { trace?: { poses?: Pose[]; times_s?: number[]; ranges?: number[][]; path?: unknown[] } }).trace;
    if (tr) {
      a.trajectory ??= tr.poses;
      a.t ??= tr.times_s;
      a.ranges ??= tr.ranges;
      a.path ??= tr.path as number[][];
    }
    if (a.path) a.path = a.path.map((p) => (Array.isArray(p) ? p : [(p as Pose).x, (p as Pose).y]));
  }
}

/** The validating attempts of every leg, one after the other on one clock. */
function validatedTrack(r: PlanReport): Track | null {
  const byLeg = new Map<number, Attempt>();
  for (const a of r.attempts) if (a.outcome === 'reached' && a.trajectory?.length) byLeg.set(a.leg, a);
  const legs = [...byLeg.keys()].sort((a, b) => a - b);
  const poses: Pose[] = [], t: number[] = [], ranges: number[][] = [];
  let haveRanges = true;
  let offset = 0;
  for (const leg of legs) {
    const a = byLeg.get(leg)!;
    const tr = a.trajectory!;
    const ts = a.t && a.t.length === tr.length ? a.t : tr.map((_, i) => (i * a.simulated_time_s) / Math.max(1, tr.length - 1));
    for (let i = 0; i < tr.length; i++) {
      poses.push(tr[i]);
      t.push(offset + ts[i]);
      if (a.ranges && a.ranges[i]) ranges.push(a.ranges[i]);
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

function attemptTrack(r: PlanReport, a: Attempt | undefined): Track | null {
  if (!a?.trajectory?.length) return null;
  const tr = a.trajectory;
  const ts = a.t && a.t.length === tr.length ? a.t : tr.map((_, i) => (i * a.simulated_time_s) / Math.max(1, tr.length - 1));
  const targets = a.path?.length ? a.path.map(([x, y]) => ({ x, y })) : r.waypoints;
  return withTargets(tr, ts, a.ranges && a.ranges.length === tr.length ? a.ranges : null, targets);
}

/** Which target is active at each pose: the first one not yet come within REACH_M of. */
function withTargets(poses: Pose[], t: number[], ranges: number[][] | null, targets: { x: number; y: number }[]): Track {
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
