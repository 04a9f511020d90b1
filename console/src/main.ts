import './style.css';
import { h, clear, field } from './dom';
import { ApiError, getJson, setOnUnauthorized, setToken, showError, token, type Me } from './api';
import * as data from './data';
import * as floors from './pages/floors';

export interface PageContext {
  me: Me;
  engineer: boolean;
  args: string[];
  query: URLSearchParams;
  navigate: (hash: string) => void;
}
export type Cleanup = (() => void) | void;
interface Page {
  mount(root: HTMLElement, ctx: PageContext): Cleanup | Promise<Cleanup>;
}

const PAGES: { path: string; title: string; load: () => Promise<Page> }[] = [
  { path: 'floors', title: 'Floors', load: async () => floors },
  { path: 'plan', title: 'Plan', load: () => import('./pages/plan') },
  { path: 'traffic', title: 'Traffic', load: () => import('./pages/traffic') },
  { path: 'jobs', title: 'Jobs', load: () => import('./pages/jobs') },
  { path: 'policies', title: 'Policies', load: () => import('./pages/policies') },
  { path: 'knowledge', title: 'Knowledge', load: () => import('./pages/knowledge') },
  { path: 'api', title: 'API', load: () => import('./pages/apiref') },
];

const main = document.getElementById('main')!;
const nav = document.getElementById('nav')!;
const who = document.getElementById('who')!;
let me: Me | null = null;
let meWarning = '';
let cleanup: Cleanup = undefined;
let generation = 0;

function parseHash(): { page: string; args: string[]; query: URLSearchParams } {
  const raw = location.hash.replace(/^#\/?/, '');
  const [path, q = ''] = raw.split('?');
  const parts = path.split('/').filter(Boolean).map(decodeURIComponent);
  return { page: parts[0] || 'floors', args: parts.slice(1), query: new URLSearchParams(q) };
}

function navigate(hash: string): void {
  if (location.hash === hash) void route();
  else location.hash = hash;
}

function renderChrome(current: string): void {
  clear(nav);
  if (!me) {
    clear(who);
    return;
  }
  nav.append(
    h('ul', null, PAGES.map((p) =>
      h('li', null, h('a', { href: `#/${p.path}`, 'aria-current': p.path === current ? 'page' : undefined }, p.title)),
    )),
  );
  clear(who);
  who.append(
    h('span', { class: 'who-name', title: me.name }, me.name),
    ' ',
    h('span', { class: `badge role-${me.role}`, 'data-role': me.role }, me.role),
    ' ',
    h('button', { type: 'button', id: 'sign-out', onclick: signOut }, 'Sign out'),
  );
}

function signOut(): void {
  setToken(null);
  me = null;
  data.forget();
  navigate('#/floors');
  void route();
}

async function loadMe(): Promise<Me> {
  try {
    return await getJson<Me>('/v1/me');
  } catch (e) {
    if (e instanceof ApiError && (e.status === 404 || e.status === 405)) {
      // Before /v1/me exists: the token works for reading places, the role is unknown.
      await getJson('/v1/robots');
      meWarning = 'GET /v1/me is not available on this service: the role is unknown, every control is shown.';
      return { name: 'token', role: 'engineer' };
    }
    throw e;
  }
}

function signInForm(message?: string): void {
  renderChrome('');
  clear(main);
  const input = h('input', { type: 'password', name: 'token', autocomplete: 'off', required: true, spellcheck: 'false' });
  const err = h('div', { class: 'error', hidden: true });
  const form = h('form', { class: 'card signin', id: 'sign-in', 'aria-labelledby': 'signin-title' },
    h('h1', { id: 'signin-title' }, 'Sign in'),
    h('p', null, 'Paste a bearer token. It is kept in this browser tab only (session storage) and sent with every API call.'),
    field('Bearer token', input),
    h('button', { type: 'submit', class: 'primary' }, 'Sign in'),
    err,
  );
  if (message) showError(err, new Error(message));
  form.addEventListener('submit', async (e) => {
    e.preventDefault();
    setToken(input.value.trim());
    try {
      me = await loadMe();
      void route();
    } catch (x) {
      setToken(null);
      me = null;
      showError(err, x);
    }
  });
  main.append(form);
  input.focus();
}

async function route(): Promise<void> {
  const gen = ++generation;
  if (typeof cleanup === 'function') cleanup();
  cleanup = undefined;
  if (!token()) {
    signInForm();
    return;
  }
  if (!me) {
    // The floor pages' first read goes out with the token check, not after it.
    const first = parseHash().page;
    if (first === 'floors' || first === 'plan') data.places().catch(() => undefined);
    try {
      me = await loadMe();
    } catch (e) {
      setToken(null);
      signInForm(e instanceof Error ? e.message : String(e));
      return;
    }
  }
  const { page, args, query } = parseHash();
  const def = PAGES.find((p) => p.path === page) ?? PAGES[0];
  renderChrome(def.path);
  document.title = `${def.title} · Mentalsim console`;
  clear(main);
  if (meWarning) main.append(h('p', { class: 'notice' }, meWarning));
  const root = h('section', { class: `page page-${def.path}`, 'aria-labelledby': 'page-title' });
  main.append(root);
  try {
    const mod = await def.load();
    if (gen !== generation) return;
    const ctx: PageContext = { me: me!, engineer: me!.role === 'engineer', args, query, navigate };
    const c = await mod.mount(root, ctx);
    if (gen !== generation) {
      if (typeof c === 'function') c();
      return;
    }
    cleanup = c;
  } catch (e) {
    const box = h('div');
    root.append(box);
    showError(box, e);
  }
}

setOnUnauthorized(() => {
  if (me) {
    setToken(null);
    me = null;
    data.forget();
    signInForm('The token was refused (401): sign in again.');
  }
});
window.addEventListener('hashchange', () => void route());
void route();
