// Jobs: list and filter, submit a training or evaluation job (engineers), a job's detail with
// live progress and learning curves from its server-sent events, cancel, curves CSV/PNG.

import { h, add, clear, field, fmt, pct, download } from '../dom';
import { ApiError, getBlob, getJson, postJson, showError, clearError, type JobView } from '../api';
import * as data from '../data';
import { stream, type SseEvent } from '../sse';
import { lineChart } from '../chart';
import type { PageContext, Cleanup } from '../main';

const FINAL = new Set(['succeeded', 'failed', 'cancelled']);

export async function mount(root: HTMLElement, ctx: PageContext): Promise<Cleanup> {
  if (ctx.args[0]) return detail(root, ctx, ctx.args[0]);
  return list(root, ctx);
}

// ---------------------------------------------------------------------------------------------
// List and submission

async function list(root: HTMLElement, ctx: PageContext): Promise<Cleanup> {
  root.append(h('h1', { id: 'page-title' }, 'Jobs'));
  const stateSel = h('select', { name: 'state' }, ['', 'queued', 'running', 'succeeded', 'failed', 'cancelled'].map((s) => h('option', { value: s, selected: s === (ctx.query.get('state') ?? '') }, s || 'any')));
  const kindSel = h('select', { name: 'kind' }, ['', 'train', 'evaluate', 'validate', 'roadmap'].map((s) => h('option', { value: s, selected: s === (ctx.query.get('kind') ?? '') }, s || 'any')));
  const limitIn = h('input', { type: 'number', name: 'limit', min: '1', max: '1000', value: ctx.query.get('limit') ?? '50' });
  const listErr = h('div', { hidden: true });
  const table = h('div', { id: 'job-list' });
  const filters = h('form', { class: 'inline', 'aria-label': 'Filter jobs' },
    field('State', stateSel), field('Kind', kindSel), field('Limit', limitIn),
    h('button', { type: 'submit' }, 'Apply'),
  );
  filters.addEventListener('submit', (e) => {
    e.preventDefault();
    const q = new URLSearchParams();
    if (stateSel.value) q.set('state', stateSel.value);
    if (kindSel.value) q.set('kind', kindSel.value);
    if (limitIn.value) q.set('limit', limitIn.value);
    history.replaceState(null, '', `#/jobs?${q}`);
    void load();
  });
  const layout = h('div', { class: 'split jobs-split' }, h('div', null, h('h2', null, 'All jobs'), filters, listErr, table));
  root.append(layout);
  if (ctx.engineer) layout.append(submitForm(ctx));

  let timer = 0;
  let shown = '';
  async function load(): Promise<void> {
    clearError(listErr);
    const q = new URLSearchParams();
    if (stateSel.value) q.set('state', stateSel.value);
    if (kindSel.value) q.set('kind', kindSel.value);
    if (limitIn.value) q.set('limit', limitIn.value);
    try {
      const jobs = await getJson<JobView[]>(`/v1/jobs?${q}`);
      // Re-render only on change: a refresh must not take the keyboard focus away.
      const key = JSON.stringify(jobs.map((j) => [j.id, j.state, j.progress?.fraction_done]));
      if (key === shown) return;
      shown = key;
      clear(table);
      if (!jobs.length) {
        table.append(h('p', { class: 'muted' }, 'No job matches.'));
        return;
      }
      table.append(h('table', null,
        h('thead', null, h('tr', null, ['job', 'kind', 'state', 'progress', 'created', 'payload'].map((t) => h('th', null, t)))),
        h('tbody', null, jobs.map((j) => h('tr', null,
          h('td', null, h('a', { href: `#/jobs/${j.id}` }, j.id.slice(0, 8) + '…')),
          h('td', null, j.kind),
          h('td', null, stateBadge(j.state)),
          h('td', null, j.progress && typeof j.progress.fraction_done === 'number' ? pct(j.progress.fraction_done) : '—'),
          h('td', null, j.created.replace('T', ' ').replace(/\.\d+Z$/, 'Z')),
          h('td', { class: 'mono small' }, summarise(j.payload)),
        ))),
      ));
    } catch (e) {
      showError(listErr, e);
    }
  }
  await load();
  timer = window.setInterval(() => void load(), 10_000);
  return () => clearInterval(timer);
}

function summarise(p: Record<string, unknown>): string {
  return Object.entries(p).filter(([, v]) => typeof v !== 'object').map(([k, v]) => `${k}=${v}`).join(' ').slice(0, 80);
}

function stateBadge(state: string): HTMLElement {
  const cls = state === 'succeeded' ? 'good' : state === 'failed' ? 'bad' : state === 'running' ? 'busy' : '';
  return h('span', { class: `badge ${cls}`, 'data-state': state }, state);
}

function submitForm(ctx: PageContext): HTMLElement {
  const kindTrain = h('input', { type: 'radio', name: 'kind', value: 'train', checked: true });
  const kindEval = h('input', { type: 'radio', name: 'kind', value: 'evaluate' });
  const robot = h('select', { name: 'robot' });
  const place = h('select', { name: 'place' });
  const minutes = h('input', { type: 'number', name: 'minutes', step: 'any', min: '0', value: '1' });
  const seed = h('input', { type: 'number', name: 'seed', min: '0', step: '1' });
  const config = h('textarea', { name: 'config', rows: 3, placeholder: '{"preset": …} (optional JSON object)', spellcheck: 'false' });
  const policy = h('input', { type: 'text', name: 'policy', list: 'policy-ids', autocomplete: 'off' });
  const policyList = h('datalist', { id: 'policy-ids' });
  const evalPlace = h('select', { name: 'eval_place' });
  const episodes = h('input', { type: 'number', name: 'episodes', min: '1', step: '1', value: '20' });
  const priority = h('input', { type: 'number', name: 'priority', step: '1' });
  const maxAttempts = h('input', { type: 'number', name: 'max_attempts', min: '1', max: '100', step: '1' });
  const formErr = h('div', { hidden: true, id: 'job-form-error' });
  const trainSet = h('fieldset', null, h('legend', null, 'Training'),
    field('Robot', robot), field('Place (floor)', place), field('Minutes', minutes, 'wall-clock budget'),
    field('Seed (optional)', seed), field('Config (optional JSON)', config, 'any keys of learning::TrainConfig'),
  );
  const evalSet = h('fieldset', { hidden: true }, h('legend', null, 'Evaluation'),
    field('Policy id', policy), policyList, field('Place (floor)', evalPlace), field('Episodes', episodes),
  );
  const form = h('form', { class: 'card', id: 'job-form', 'aria-labelledby': 'job-form-title', novalidate: true },
    h('h2', { id: 'job-form-title' }, 'Submit a job'),
    h('fieldset', { class: 'inline' }, h('legend', null, 'Kind'), h('label', null, kindTrain, ' train'), h('label', null, kindEval, ' evaluate')),
    trainSet, evalSet,
    h('details', null, h('summary', null, 'Queue options'), field('Priority', priority), field('Max attempts', maxAttempts)),
    h('button', { type: 'submit', class: 'primary' }, 'Submit'),
    formErr,
  );
  const fields: Record<string, HTMLElement> = { robot, place, minutes, seed, config, policy, episodes, priority, max_attempts: maxAttempts };
  const kindChanged = () => {
    trainSet.hidden = !kindTrain.checked;
    evalSet.hidden = kindTrain.checked;
    clearFieldErrors();
  };
  kindTrain.addEventListener('change', kindChanged);
  kindEval.addEventListener('change', kindChanged);

  void Promise.all([data.robots(), data.places()]).then(([rs, ps]) => {
    for (const r of rs) robot.append(h('option', { value: r.id ?? r.iri }, `${r.name} (${r.id ?? r.iri})`));
    const floors = data.indexPlaces(ps).floors;
    for (const f of floors) {
      place.append(h('option', { value: f.id ?? f.iri }, `${f.name} (${f.id ?? f.iri})`));
      evalPlace.append(h('option', { value: f.id ?? f.iri }, `${f.name} (${f.id ?? f.iri})`));
    }
  }, (e) => showError(formErr, e));
  void data.policies().then((ps) => {
    for (const p of ps) policyList.append(h('option', { value: p.id }, `${p.place ?? ''} ${pct(p.eval?.success_rate)}`));
    if (ps[0]) policy.value = ps[0].id;
  }, () => undefined);

  function clearFieldErrors(): void {
    clearError(formErr);
    for (const el of Object.values(fields)) {
      el.removeAttribute('aria-invalid');
      const e = document.getElementById(`${el.id}-err`);
      if (e) e.textContent = '';
    }
  }
  function fieldError(name: string, message: string): boolean {
    const el = fields[name === 'place' && kindEval.checked ? 'eval_place' : name] ?? (name === 'place' && kindEval.checked ? evalPlace : undefined);
    const target = el ?? (name === 'place' ? (kindTrain.checked ? place : evalPlace) : undefined);
    if (!target) return false;
    target.setAttribute('aria-invalid', 'true');
    const e = document.getElementById(`${target.id}-err`);
    if (e) e.textContent = message;
    return true;
  }
  fields.eval_place = evalPlace;

  form.addEventListener('submit', async (e) => {
    e.preventDefault();
    clearFieldErrors();
    const kind = kindTrain.checked ? 'train' : 'evaluate';
    const payload: Record<string, unknown> = {};
    const num = (el: HTMLInputElement) => (el.value.trim() === '' ? undefined : Number(el.value));
    if (kind === 'train') {
      payload.robot = robot.value;
      payload.place = place.value;
      payload.minutes = num(minutes);
      if (num(seed) !== undefined) payload.seed = num(seed);
      if (config.value.trim()) {
        try {
          payload.config = JSON.parse(config.value);
        } catch (x) {
          fieldError('config', `not JSON: ${(x as Error).message}`);
          config.focus();
          return;
        }
      }
    } else {
      payload.policy = policy.value.trim();
      payload.place = evalPlace.value;
      if (num(episodes) !== undefined) payload.episodes = num(episodes);
    }
    const body: Record<string, unknown> = { kind, payload };
    if (num(priority) !== undefined) body.priority = num(priority);
    if (num(maxAttempts) !== undefined) body.max_attempts = num(maxAttempts);
    try {
      const job = await postJson<JobView>('/v1/jobs', body);
      data.forget('policies');
      ctx.navigate(`#/jobs/${job.id}`);
    } catch (x) {
      let placed = false;
      if (x instanceof ApiError) {
        for (const f of x.fields()) {
          const key = f.split('.')[0];
          if (fieldError(key, x.message)) {
            if (!placed) (fields[key] ?? evalPlace).focus();
            placed = true;
          }
        }
      }
      showError(formErr, x);
    }
  });
  return form;
}

// ---------------------------------------------------------------------------------------------
// One job

interface Curves {
  success: [number, number][];
  reward: [number, number][];
  evals: [number, number][];
  seenSteps: Set<number>;
  seenEvals: Set<number>;
}

async function detail(root: HTMLElement, ctx: PageContext, id: string): Promise<Cleanup> {
  root.append(h('p', null, h('a', { href: '#/jobs' }, '← all jobs')), h('h1', { id: 'page-title' }, `Job ${id}`));
  const err = h('div', { hidden: true });
  root.append(err);
  let job: JobView;
  try {
    job = await getJson<JobView>(`/v1/jobs/${encodeURIComponent(id)}`);
  } catch (e) {
    showError(err, e);
    return;
  }
  const head = h('div', { class: 'job-head' });
  const bar = h('progress', { max: '1', value: '0', id: 'job-progress', 'aria-label': 'Progress' });
  const progressTable = h('div', { class: 'progress-table' });
  const charts = h('div', { class: 'charts', id: 'job-curves', 'data-points': '0', 'data-events': '0' });
  const resultBox = h('div');
  const cancelErr = h('div', { hidden: true });
  const streamStatus = h('p', { class: 'status', 'aria-live': 'polite' });
  const cancelBtn = h('button', { type: 'button', id: 'cancel-job', class: 'danger' }, 'Cancel job');
  const curvesFiles = h('div', { class: 'curve-files' });
  add(root, head, h('div', { class: 'progress-row' }, bar, streamStatus),
    ctx.engineer ? h('div', { class: 'buttons' }, cancelBtn, cancelErr) : null,
    progressTable, charts, curvesFiles, resultBox);

  const curves: Curves = { success: [], reward: [], evals: [], seenSteps: new Set(), seenEvals: new Set() };
  let events = 0;

  function renderHead(): void {
    clear(head);
    const dl = (pairs: [string, unknown][]) => h('dl', { class: 'kv' }, pairs.flatMap(([k, v]) => [h('dt', null, k), h('dd', null, v instanceof Node ? v : String(v ?? '—'))]));
    head.append(dl([
      ['kind', job.kind],
      ['state', stateBadge(job.state)],
      ['attempts', `${job.attempts} of ${job.max_attempts}`],
      ['created', job.created],
      ['started', job.started ?? '—'],
      ['finished', job.finished ?? '—'],
      ['worker', job.worker ?? '—'],
      ['cancel requested', job.cancel_requested ? 'yes' : 'no'],
    ]), h('details', null, h('summary', null, 'Payload'), h('pre', null, JSON.stringify(job.payload, null, 2))));
    cancelBtn.disabled = FINAL.has(job.state) || job.cancel_requested;
    clear(resultBox);
    if (job.error) resultBox.append(h('h2', null, 'Error'), h('pre', { class: 'error-text' }, job.error));
    if (job.result) {
      const r = job.result;
      resultBox.append(h('h2', null, 'Result'));
      if (typeof r.policy_id === 'string') resultBox.append(h('p', null, 'Policy: ', h('a', { href: `#/policies/${r.policy_id}` }, r.policy_id)));
      resultBox.append(h('pre', { id: 'job-result' }, JSON.stringify(r, null, 2)));
    }
    root.dataset.state = job.state;
  }
  renderHead();

  cancelBtn.addEventListener('click', async () => {
    clearError(cancelErr);
    try {
      await postJson(`/v1/jobs/${job.id}/cancel`, {});
      streamStatus.textContent = 'Cancel requested.';
      await refresh();
    } catch (e) {
      showError(cancelErr, e);
    }
  });

  function applyProgress(p: Record<string, unknown>): void {
    const f = typeof p.fraction_done === 'number' ? p.fraction_done : null;
    if (f !== null) bar.value = Math.min(1, f);
    clear(progressTable);
    const rows = Object.entries(p).filter(([, v]) => v === null || typeof v !== 'object');
    progressTable.append(h('dl', { class: 'kv progress-kv' }, rows.flatMap(([k, v]) => [h('dt', null, k.replace(/_/g, ' ')), h('dd', null, typeof v === 'number' ? (k.includes('rate') || k === 'fraction_done' ? pct(v) : fmt(v)) : String(v ?? '—'))])));
    const steps = typeof p.env_steps === 'number' ? p.env_steps : null;
    if (steps !== null && !curves.seenSteps.has(steps)) {
      curves.seenSteps.add(steps);
      if (typeof p.success_rate_100 === 'number') curves.success.push([steps, p.success_rate_100]);
      if (typeof p.mean_reward_100 === 'number') curves.reward.push([steps, p.mean_reward_100]);
    }
    const ev = p.last_eval as Record<string, unknown> | null | undefined;
    if (ev && typeof ev.env_steps === 'number' && typeof ev.success_rate === 'number' && !curves.seenEvals.has(ev.env_steps)) {
      curves.seenEvals.add(ev.env_steps);
      curves.evals.push([ev.env_steps, ev.success_rate]);
    }
    scheduleCharts();
  }

  let chartFrame = 0;
  function scheduleCharts(): void {
    if (chartFrame) return;
    chartFrame = requestAnimationFrame(() => {
      chartFrame = 0;
      renderCharts();
    });
  }
  function renderCharts(): void {
    if (job.kind !== 'train' && !curves.success.length) return;
    clear(charts);
    charts.append(
      lineChart('Success rate (last 100 episodes) and evaluations', [
        { name: 'success rate', colour: '#16a34a', points: curves.success },
        { name: 'evaluation success', colour: '#7c3aed', points: curves.evals, dots: true },
      ], { xLabel: 'environment steps', yLabel: 'success rate', yRange: [0, 1] }),
      lineChart('Mean reward (last 100 episodes)', [
        { name: 'mean reward', colour: '#2563eb', points: curves.reward },
      ], { xLabel: 'environment steps', yLabel: 'reward' }),
    );
    charts.dataset.points = String(curves.success.length);
    charts.dataset.rewardPoints = String(curves.reward.length);
    charts.dataset.evalPoints = String(curves.evals.length);
  }
  if (job.progress) applyProgress(job.progress);
  renderCharts();

  async function refresh(): Promise<void> {
    try {
      job = await getJson<JobView>(`/v1/jobs/${encodeURIComponent(job.id)}`);
      renderHead();
      if (FINAL.has(job.state)) void showCurveFiles();
    } catch (e) {
      showError(err, e);
    }
  }

  let curveUrl = '';
  async function showCurveFiles(): Promise<void> {
    if (job.kind !== 'train' || curvesFiles.dataset.loaded) return;
    curvesFiles.dataset.loaded = '1';
    clear(curvesFiles);
    const csvBtn = h('button', { type: 'button', onclick: async () => {
      try {
        download(await getBlob(`/v1/jobs/${job.id}/curves.csv`), `curves-${job.id}.csv`);
      } catch (e) {
        showError(fileErr, e, 'curves.csv: ');
      }
    } }, 'Download curves.csv');
    const fileErr = h('div', { hidden: true });
    curvesFiles.append(h('h2', null, 'Curves'), csvBtn, fileErr);
    try {
      const blob = await getBlob(`/v1/jobs/${job.id}/curves.png`);
      curveUrl = URL.createObjectURL(blob);
      curvesFiles.append(h('img', { src: curveUrl, alt: `Learning curves of job ${job.id} (curves.png)`, class: 'curves-png' }));
    } catch (e) {
      if (e instanceof ApiError && e.status === 404) curvesFiles.append(h('p', { class: 'muted' }, 'No curve point was recorded (curves.png: 404).'));
      else showError(fileErr, e, 'curves.png: ');
    }
  }
  if (FINAL.has(job.state)) void showCurveFiles();

  const s = stream(`/v1/jobs/${encodeURIComponent(job.id)}/events`, {
    onOpen: () => (streamStatus.textContent = FINAL.has(job.state) ? 'Replaying the event log.' : 'Live: following the event stream.'),
    onEvent: (e: SseEvent) => {
      events += 1;
      charts.dataset.events = String(events);
      let payload: { kind?: string; data?: Record<string, unknown> } = {};
      try {
        payload = JSON.parse(e.data);
      } catch {
        return;
      }
      const d = payload.data ?? {};
      if (e.event === 'progress') applyProgress(d);
      else if (e.event === 'state' && typeof d.state === 'string') {
        job.state = d.state;
        renderHead();
        if (FINAL.has(d.state)) {
          streamStatus.textContent = `Finished: ${d.state}.`;
          void refresh();
        }
      } else if (e.event === 'cancel_requested') {
        job.cancel_requested = true;
        renderHead();
      }
    },
    done: () => FINAL.has(job.state),
    onError: (e) => {
      streamStatus.textContent = `Event stream: ${e instanceof Error ? e.message : String(e)}; reconnecting…`;
    },
  });
  const poll = window.setInterval(() => {
    if (!FINAL.has(job.state)) void refresh();
  }, 15_000);
  return () => {
    s.stop();
    clearInterval(poll);
    if (curveUrl) URL.revokeObjectURL(curveUrl);
  };
}
