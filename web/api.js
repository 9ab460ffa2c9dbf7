// The public API under /v1 on this origin, with the user's API key where the server wants one
// (kept in this tab's sessionStorage and sent as a Bearer token, as the API documents).
import { el } from './util.js';

const KEY_STORE = 'millsim.apiKey';
export const app = document.getElementById('app');
let onKeySet = () => {};
export function whenKeySet(f) { onKeySet = f; }

export const apiKey = () => sessionStorage.getItem(KEY_STORE) || '';
export function authHeaders() {
  const k = apiKey();
  return k ? { Authorization: 'Bearer ' + k } : {};
}
export class NeedKey extends Error {}

// A refusal keeps its problem document (file, line, column) on the error, for the views.
export async function api(path, opts) {
  const res = await fetch(path, { ...(opts || {}), headers: { ...authHeaders(), ...((opts && opts.headers) || {}) } });
  if (res.status === 401) throw new NeedKey('401');
  if (!res.ok) {
    let p = null;
    try { p = await res.json(); } catch (_) { /* not JSON */ }
    const err = new Error((p && (p.detail || p.title)) || res.status + ' ' + res.statusText);
    err.problem = p;
    throw err;
  }
  return res;
}
export const getJson = async (path) => (await api(path)).json();
export const postJson = async (path, body, type) =>
  (await api(path, { method: 'POST', headers: { 'content-type': type || 'application/json' }, body: typeof body === 'string' || body instanceof ArrayBuffer ? body : JSON.stringify(body) })).json();

export function renderKeyState() {
  const box = document.getElementById('keystate');
  box.replaceChildren();
  if (apiKey()) {
    box.append('API key set ', el('button', { onclick: () => { sessionStorage.removeItem(KEY_STORE); location.reload(); } }, 'Forget'));
  }
}

function askForKey(again) {
  app.replaceChildren(
    el('h1', {}, 'API key'),
    el('p', {}, again ? 'The server refused that key. ' : '', 'This server requires an API key. It is kept in this tab only (sessionStorage) and sent as ',
      el('code', {}, 'Authorization: Bearer KEY'), '.'),
    el('form', {
      id: 'keyform', onsubmit: (e) => {
        e.preventDefault();
        const v = e.target.elements.key.value.trim();
        if (v) { sessionStorage.setItem(KEY_STORE, v); renderKeyState(); onKeySet(); }
      },
    }, el('input', { name: 'key', type: 'password', autocomplete: 'off', placeholder: 'ms_…', size: 60 }), ' ', el('button', { type: 'submit' }, 'Use key')),
  );
}

export function handleError(err, where) {
  if (err instanceof NeedKey) { const had = !!apiKey(); if (had) sessionStorage.removeItem(KEY_STORE); renderKeyState(); askForKey(had); return; }
  (where || app).append(el('p', { class: 'error' }, 'Error: ' + err.message));
}

// Server-sent events read with fetch (EventSource cannot send the API key header).
export async function follow(id, onEvent, signal) {
  const res = await fetch('/v1/jobs/' + encodeURIComponent(id) + '/events', { headers: authHeaders(), signal });
  if (!res.ok || !res.body) return;
  const reader = res.body.pipeThrough(new TextDecoderStream()).getReader();
  let buf = '';
  for (;;) {
    const { value, done } = await reader.read();
    if (done) return;
    buf += value.replace(/\r\n/g, '\n');
    let i;
    while ((i = buf.indexOf('\n\n')) >= 0) {
      const chunk = buf.slice(0, i);
      buf = buf.slice(i + 2);
      let ev = 'message';
      const data = [];
      for (const line of chunk.split('\n')) {
        if (line.startsWith('event:')) ev = line.slice(6).trim();
        else if (line.startsWith('data:')) data.push(line.slice(5).replace(/^ /, ''));
      }
      if (data.length) {
        let parsed;
        try { parsed = JSON.parse(data.join('\n')); } catch (_) { continue; }
        onEvent(ev, parsed);
      }
    }
  }
}

// Program names by resource id (a job's inputs name the program resource).
const programNames = new Map();
export async function programName(job) {
  if (job.summary && job.summary.file) return job.summary.file;
  const pid = job.inputs && job.inputs.program;
  if (typeof pid !== 'string') return '';
  if (!programNames.has(pid)) {
    programNames.set(pid, getJson('/v1/programs/' + encodeURIComponent(pid)).then((r) => r.name || '').catch(() => ''));
  }
  return programNames.get(pid);
}

// The job's stored program, as lines (for hovers and the program views).
export async function programSource(job) {
  const pid = job.inputs && job.inputs.program;
  if (typeof pid !== 'string') return null;
  return (await (await api('/v1/programs/' + encodeURIComponent(pid) + '/content')).text()).split(/\r?\n/);
}

// A download link; with an API key it is fetched with the key and saved from a blob.
export function downloadLink(label, href, file, errorBox) {
  return el('a', { href, download: file || '', 'data-download': label,
    onclick: async (e) => {
      if (!apiKey()) return; // a plain link: the browser downloads it
      e.preventDefault();
      try { const b = await (await api(href)).blob(); const u = URL.createObjectURL(b); const a = el('a', { href: u, download: file || '' }); a.click(); setTimeout(() => URL.revokeObjectURL(u), 10000); } catch (err) { handleError(err, errorBox); }
    } }, label);
}

// Cancels a queued or running job: a queued job is cancelled at once, a running one when its
// worker next looks (the job's events then say `cancelled`).
export async function cancelJob(id) {
  return (await api('/v1/jobs/' + encodeURIComponent(id) + '/cancel', { method: 'POST' })).json();
}
