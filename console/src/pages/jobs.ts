// Jobs: list and filter, submit a training or evaluation job (engineers), a job's detail with
// live progress and learning curves from its server-sent events, cancel, curves CSV/PNG.

import { h, add, clear, field, fmt, pct, download } from '../dom';
import { ApiError, getBlob, getJson, postJson, showError, clearError, type JobView, type NewJobRequest } from '../api';
import * as data from '../data';
import { FieldErrors } from '../form';
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
  const query = () => {
    const q = new URLSearchParams();
    if (stateSel.value) q.set('state', stateSel.value);
    if (kindSel.value) q.set('kind', kindSel.value);
    if (limitIn.value) q.set('limit', limitIn.value);
    return q;
  };
  let shown = '';
  const load = async (): Promise<void> => {
    clearError(listErr);
    try {
      const jobs = await getJson<JobView[]>(`/v1/jobs?${query()}`);
      // Re-render only on change: a refresh must not take the keyboard focus away.
      const key = JSON.stringify(jobs.map((j) => [j.id, j.state, j.progress?.fraction_done]));
      if (key === shown) return;
      shown = key;
      clear(table);
      table.append(jobs.length ? jobsTable(jobs) : h('p', { class: 'muted' }, 'No job matches.'));
    } catch (e) {
      showError(listErr, e);
    }
  };
  filters.addEventListener('submit', (e) => {
    e.preventDefault();
    history.replaceState(null, '', `#/jobs?${query()}`);
    void load();
  });
  const layout = h('div', { class: 'split jobs-split' }, h('div', null, h('h2', null, 'All jobs'), filters, listErr, table));
  root.append(layout);
  if (ctx.engineer) layout.append(new JobForm(ctx).form);
  await load();
  const timer = window.setInterval(() => void load(), 10_000);
  return () => clearInterval(timer);
}

function jobsTable(jobs: JobView[]): HTMLElement {
  return h('table', null,
    h('thead', null, h('tr', null, ['job', 'kind', 'state', 'progress', 'created', 'payload'].map((t) => h('th', null, t)))),
    h('tbody', null, jobs.map((j) => h('tr', null,
      h('td', null, h('a', { href: `#/jobs/${j.id}` }, j.id.slice(0, 8) + '…')),
      h('td', null, j.kind),
      h('td', null, stateBadge(j.state)),
      h('td', null, j.progress && typeof j.progress.fraction_done === 'number' ? pct(j.progress.fraction_done) : '—'),
      h('td', null, j.created.replace('T', ' ').replace(/\.\d+Z$/, 'Z')),
      h('td', { class: 'mono small' }, summarise(j.payload)),
    ))),
  );
}

function summarise(p: Record<string, unknown>): string {
  return Object.entries(p).filter(([, v]) => typeof v !== 'object').map(([k, v]) => `${k}=${v}`).join(' ').slice(0, 80);
}

function stateBadge(state: string): HTMLElement {
  const cls = state === 'succeeded' ? 'good' : state === 'failed' ? 'bad' : state === 'running' ? 'busy' : '';
  return h('span', { class: `badge ${cls}`, 'data-state': state }, state);
}

/** A field left empty is left out of the request. */
function num(el: HTMLInputElement): number | undefined {
  return el.value.trim() === '' ? undefined : Number(el.value);
}

/** The form that submits a training or an evaluation job; the service's 422 goes next to the
 *  field it names (`error.field`: `payload.minutes`, `max_attempts`, ...). */
class JobForm {
  private readonly kindTrain = h('input', { type: 'radio', name: 'kind', value: 'train', checked: true });
  private readonly kindEval = h('input', { type: 'radio', name: 'kind', value: 'evaluate' });
  private readonly robot = h('select', { name: 'robot' });
  private readonly place = h('select', { name: 'place' });
  private readonly minutes = h('input', { type: 'number', name: 'minutes', step: 'any', min: '0', value: '1' });
  private readonly seed = h('input', { type: 'number', name: 'seed', min: '0', step: '1' });
  private readonly config = h('textarea', { name: 'config', rows: 3, placeholder: '{"preset": …} (optional JSON object)', spellcheck: 'false' });
  private readonly policy = h('input', { type: 'text', name: 'policy', list: 'policy-ids', autocomplete: 'off' });
  private readonly policyList = h('datalist', { id: 'policy-ids' });
  private readonly evalPlace = h('select', { name: 'eval_place' });
  private readonly episodes = h('input', { type: 'number', name: 'episodes', min: '1', step: '1', value: '20' });
  private readonly priority = h('input', { type: 'number', name: 'priority', step: '1' });
  private readonly maxAttempts = h('input', { type: 'number', name: 'max_attempts', min: '1', max: '100', step: '1' });
  private readonly formErr = h('div', { hidden: true, id: 'job-form-error' });
  private readonly trainSet: HTMLFieldSetElement;
  private readonly evalSet: HTMLFieldSetElement;
  private readonly fieldErrors: FieldErrors;
  readonly form: HTMLFormElement;

  constructor(private readonly ctx: PageContext) {
    this.trainSet = h('fieldset', null, h('legend', null, 'Training'),
      field('Robot', this.robot), field('Place (floor)', this.place), field('Minutes', this.minutes, 'wall-clock budget'),
      field('Seed (optional)', this.seed), field('Config (optional JSON)', this.config, 'any keys of learning::TrainConfig'),
    );
    this.evalSet = h('fieldset', { hidden: true }, h('legend', null, 'Evaluation'),
      field('Policy id', this.policy), this.policyList, field('Place (floor)', this.evalPlace), field('Episodes', this.episodes),
    );
    this.form = h('form', { class: 'card', id: 'job-form', 'aria-labelledby': 'job-form-title', novalidate: true },
      h('h2', { id: 'job-form-title' }, 'Submit a job'),
      h('fieldset', { class: 'inline' }, h('legend', null, 'Kind'), h('label', null, this.kindTrain, ' train'), h('label', null, this.kindEval, ' evaluate')),
      this.trainSet, this.evalSet,
      h('details', null, h('summary', null, 'Queue options'), field('Priority', this.priority), field('Max attempts', this.maxAttempts)),
      h('button', { type: 'submit', class: 'primary' }, 'Submit'),
      this.formErr,
    );
    this.fieldErrors = new FieldErrors(() => this.controls());
    const kindChanged = () => {
      this.trainSet.hidden = !this.kindTrain.checked;
      this.evalSet.hidden = this.kindTrain.checked;
      this.clearErrors();
    };
    this.kindTrain.addEventListener('change', kindChanged);
    this.kindEval.addEventListener('change', kindChanged);
    this.form.addEventListener('submit', (e) => {
      e.preventDefault();
      void this.submit();
    });
    this.fillChoices();
  }

  /** The request's fields, as `error.field` names them, and the controls of the kind shown. */
  private controls(): Record<string, HTMLElement> {
    const queue = { priority: this.priority, max_attempts: this.maxAttempts };
    return this.kindTrain.checked
      ? { ...queue, 'payload.robot': this.robot, 'payload.place': this.place, 'payload.minutes': this.minutes, 'payload.seed': this.seed, 'payload.config': this.config }
      : { ...queue, 'payload.policy': this.policy, 'payload.place': this.evalPlace, 'payload.episodes': this.episodes };
  }

  private fillChoices(): void {
    void Promise.all([data.robots(), data.places()]).then(([rs, ps]) => {
      for (const r of rs) this.robot.append(h('option', { value: r.id ?? r.iri }, `${r.name} (${r.id ?? r.iri})`));
      for (const f of data.indexPlaces(ps).floors) {
        this.place.append(h('option', { value: f.id ?? f.iri }, `${f.name} (${f.id ?? f.iri})`));
        this.evalPlace.append(h('option', { value: f.id ?? f.iri }, `${f.name} (${f.id ?? f.iri})`));
      }
    }, (e) => showError(this.formErr, e));
    void data.policies().then((ps) => {
      for (const p of ps) this.policyList.append(h('option', { value: p.id }, `${p.place ?? ''} ${pct(p.eval?.success_rate)}`));
      if (ps[0]) this.policy.value = ps[0].id;
    }, () => undefined);
  }

  private clearErrors(): void {
    clearError(this.formErr);
    this.fieldErrors.clear();
  }

  /** The job the form describes, or null when a field cannot be sent as it is (marked). */
  private request(): NewJobRequest | null {
    const queue = { priority: num(this.priority), max_attempts: num(this.maxAttempts) };
    if (!this.kindTrain.checked) {
      return { kind: 'evaluate', ...queue, payload: { policy: this.policy.value.trim(), place: this.evalPlace.value, episodes: num(this.episodes) } };
    }
    const minutes = num(this.minutes);
    if (minutes === undefined) return this.refuse('payload.minutes', 'payload.minutes: a number of minutes is required');
    let config: Record<string, unknown> | undefined;
    if (this.config.value.trim()) {
      try {
        config = JSON.parse(this.config.value);
      } catch (x) {
        return this.refuse('payload.config', `not JSON: ${(x as Error).message}`);
      }
    }
    return { kind: 'train', ...queue, payload: { robot: this.robot.value, place: this.place.value, minutes, seed: num(this.seed), config } };
  }

  private refuse(fieldPath: string, message: string): null {
    this.fieldErrors.show(fieldPath, message)?.focus();
    return null;
  }

  private async submit(): Promise<void> {
    this.clearErrors();
    const body = this.request();
    if (!body) return;
    try {
      const job = await postJson<JobView>('/v1/jobs', body);
      data.forget('policies');
      this.ctx.navigate(`#/jobs/${job.id}`);
    } catch (x) {
      this.fieldErrors.showError(x, true);
      showError(this.formErr, x);
    }
  }
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
  const d = new JobDetail(root, err, job, ctx.engineer);
  d.follow();
  return () => d.destroy();
}

/** A job's state, progress and curves, kept up to date from its event stream (and a poll). */
class JobDetail {
  private readonly head = h('div', { class: 'job-head' });
  private readonly bar = h('progress', { max: '1', value: '0', id: 'job-progress', 'aria-label': 'Progress' });
  private readonly progressTable = h('div', { class: 'progress-table' });
  private readonly charts = h('div', { class: 'charts', id: 'job-curves', 'data-points': '0', 'data-events': '0' });
  private readonly resultBox = h('div');
  private readonly cancelErr = h('div', { hidden: true });
  private readonly streamStatus = h('p', { class: 'status', 'aria-live': 'polite' });
  private readonly cancelBtn = h('button', { type: 'button', id: 'cancel-job', class: 'danger' }, 'Cancel job');
  private readonly curvesFiles = h('div', { class: 'curve-files' });
  private readonly curves: Curves = { success: [], reward: [], evals: [], seenSteps: new Set(), seenEvals: new Set() };
  private events = 0;
  private chartFrame = 0;
  private curveUrl = '';
  private sub: { stop: () => void } | null = null;
  private poll = 0;

  constructor(private readonly root: HTMLElement, private readonly err: HTMLElement, private job: JobView, engineer: boolean) {
    add(root, this.head, h('div', { class: 'progress-row' }, this.bar, this.streamStatus),
      engineer ? h('div', { class: 'buttons' }, this.cancelBtn, this.cancelErr) : null,
      this.progressTable, this.charts, this.curvesFiles, this.resultBox);
    this.cancelBtn.addEventListener('click', () => void this.cancel());
    this.renderHead();
    if (job.progress) this.applyProgress(job.progress);
    this.renderCharts();
    if (FINAL.has(job.state)) void this.showCurveFiles();
  }

  private renderHead(): void {
    const { job, head, resultBox } = this;
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
    this.cancelBtn.disabled = FINAL.has(job.state) || job.cancel_requested;
    clear(resultBox);
    if (job.error) resultBox.append(h('h2', null, 'Error'), h('pre', { class: 'error-text' }, job.error));
    const r = job.result;
    if (r) {
      resultBox.append(h('h2', null, 'Result'));
      if ('policy_id' in r) resultBox.append(h('p', null, 'Policy: ', h('a', { href: `#/policies/${r.policy_id}` }, r.policy_id)));
      resultBox.append(h('pre', { id: 'job-result' }, JSON.stringify(r, null, 2)));
    }
    this.root.dataset.state = job.state;
  }

  private async cancel(): Promise<void> {
    clearError(this.cancelErr);
    try {
      await postJson(`/v1/jobs/${this.job.id}/cancel`, {});
      this.streamStatus.textContent = 'Cancel requested.';
      await this.refresh();
    } catch (e) {
      showError(this.cancelErr, e);
    }
  }

  /** A progress report: the bar, its figures, and the curves' new points. */
  private applyProgress(p: Record<string, unknown>): void {
    const { curves } = this;
    const f = typeof p.fraction_done === 'number' ? p.fraction_done : null;
    if (f !== null) this.bar.value = Math.min(1, f);
    clear(this.progressTable);
    const rows = Object.entries(p).filter(([, v]) => v === null || typeof v !== 'object');
    this.progressTable.append(h('dl', { class: 'kv progress-kv' }, rows.flatMap(([k, v]) => [h('dt', null, k.replace(/_/g, ' ')), h('dd', null, typeof v === 'number' ? (k.includes('rate') || k === 'fraction_done' ? pct(v) : fmt(v)) : String(v ?? '—'))])));
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
    this.scheduleCharts();
  }

  private scheduleCharts(): void {
    if (this.chartFrame) return;
    this.chartFrame = requestAnimationFrame(() => {
      this.chartFrame = 0;
      this.renderCharts();
    });
  }

  private renderCharts(): void {
    const { curves, charts } = this;
    if (this.job.kind !== 'train' && !curves.success.length) return;
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

  private async refresh(): Promise<void> {
    try {
      this.job = await getJson<JobView>(`/v1/jobs/${encodeURIComponent(this.job.id)}`);
      this.renderHead();
      if (FINAL.has(this.job.state)) void this.showCurveFiles();
    } catch (e) {
      showError(this.err, e);
    }
  }

  /** A finished training's curves.csv (a download) and curves.png. */
  private async showCurveFiles(): Promise<void> {
    const { job, curvesFiles } = this;
    if (job.kind !== 'train' || curvesFiles.dataset.loaded) return;
    curvesFiles.dataset.loaded = '1';
    clear(curvesFiles);
    const fileErr = h('div', { hidden: true });
    const csvBtn = h('button', { type: 'button', onclick: async () => {
      try {
        download(await getBlob(`/v1/jobs/${job.id}/curves.csv`), `curves-${job.id}.csv`);
      } catch (e) {
        showError(fileErr, e, 'curves.csv: ');
      }
    } }, 'Download curves.csv');
    curvesFiles.append(h('h2', null, 'Curves'), csvBtn, fileErr);
    try {
      const blob = await getBlob(`/v1/jobs/${job.id}/curves.png`);
      this.curveUrl = URL.createObjectURL(blob);
      curvesFiles.append(h('img', { src: this.curveUrl, alt: `Learning curves of job ${job.id} (curves.png)`, class: 'curves-png' }));
    } catch (e) {
      if (e instanceof ApiError && e.status === 404) curvesFiles.append(h('p', { class: 'muted' }, 'No curve point was recorded (curves.png: 404).'));
      else showError(fileErr, e, 'curves.png: ');
    }
  }

  /** Follows the job's event stream (the log replayed for a finished job), and polls it. */
  follow(): void {
    const { streamStatus } = this;
    this.sub = stream(`/v1/jobs/${encodeURIComponent(this.job.id)}/events`, {
      onOpen: () => (streamStatus.textContent = FINAL.has(this.job.state) ? 'Replaying the event log.' : 'Live: following the event stream.'),
      onEvent: (e) => this.onEvent(e),
      done: () => FINAL.has(this.job.state),
      onError: (e) => {
        streamStatus.textContent = `Event stream: ${e instanceof Error ? e.message : String(e)}; reconnecting…`;
      },
    });
    this.poll = window.setInterval(() => {
      if (!FINAL.has(this.job.state)) void this.refresh();
    }, 15_000);
  }

  private onEvent(e: SseEvent): void {
    const { job } = this;
    this.events += 1;
    this.charts.dataset.events = String(this.events);
    let payload: { kind?: string; data?: Record<string, unknown> } = {};
    try {
      payload = JSON.parse(e.data);
    } catch {
      return;
    }
    const d = payload.data ?? {};
    if (e.event === 'progress') this.applyProgress(d);
    else if (e.event === 'state' && typeof d.state === 'string') {
      job.state = d.state;
      this.renderHead();
      if (FINAL.has(d.state)) {
        this.streamStatus.textContent = `Finished: ${d.state}.`;
        void this.refresh();
      }
    } else if (e.event === 'cancel_requested') {
      job.cancel_requested = true;
      this.renderHead();
    }
  }

  destroy(): void {
    this.sub?.stop();
    clearInterval(this.poll);
    if (this.curveUrl) URL.revokeObjectURL(this.curveUrl);
  }
}
