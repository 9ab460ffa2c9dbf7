// The job list (/): newest first, filters by status and kind, cursor paging, and progress
// bars that follow running jobs live (their event streams; polling for the rest).
import { el, fmt, fmtDate, statusPill, progressBar, safeText } from './util.js';
import { app, getJson, follow, handleError, programName, cancelJob } from './api.js';

const KINDS = ['interpret', 'simulate', 'optimize', 'stability', 'energy', 'rotary-feed', 'identify', 'accessibility'];
const STATUSES = ['queued', 'running', 'succeeded', 'failed', 'cancelled'];
const PAGE = 25;
// A browser keeps about 6 connections per host: at most this many event streams at once,
// the rest of the list follows by polling.
const MAX_STREAMS = 3;

// ---------- the job list ----------
let listTimer = null;
const streams = new Map(); // job id -> AbortController
// Leaving the list: no more polling, no open streams.
export function stopList() {
  if (listTimer) { clearInterval(listTimer); listTimer = null; }
  for (const c of streams.values()) c.abort();
  streams.clear();
}

export async function renderList(route) {
  const q = new URLSearchParams(location.search);
  const status = q.get('status') || '';
  const kind = q.get('kind') || '';
  const cursor = q.get('cursor') || '';
  const prev = q.getAll('prev');
  const setQuery = (changes) => {
    const n = new URLSearchParams(location.search);
    for (const [k, v] of Object.entries(changes)) { n.delete(k); if (Array.isArray(v)) v.forEach((x) => n.append(k, x)); else if (v) n.set(k, v); }
    history.pushState(null, '', '/' + (n.toString() ? '?' + n : ''));
    route();
  };
  const sel = (name, values, current) => el('select', { name, onchange: (e) => setQuery({ [name]: e.target.value, cursor: '', prev: [] }) },
    el('option', { value: '' }, 'all'), values.map((v) => el('option', { value: v, selected: v === current }, v)));
  const tbody = el('tbody');
  const pager = el('div', { class: 'pager' });
  app.replaceChildren(
    el('h1', {}, 'Jobs ', el('a', { href: '/?new=1', id: 'new-job-link', class: 'small', onclick: (e) => { e.preventDefault(); history.pushState(null, '', '/?new=1'); route(); } }, '+ new job')),
    el('div', { class: 'toolbar' }, el('label', {}, 'Status ', sel('status', STATUSES, status)), el('label', {}, 'Kind ', sel('kind', KINDS, kind)),
      el('span', { class: 'muted', id: 'live' }, '')),
    el('table', { class: 'jobs' }, el('thead', {}, el('tr', {}, ['Status', 'Kind', 'Program', 'Created', 'Progress', 'Duration'].map((h) => el('th', {}, h)))), tbody),
    pager,
  );
  const params = new URLSearchParams({ limit: String(PAGE) });
  if (status) params.set('status', status);
  if (kind) params.set('kind', kind);
  if (cursor) params.set('cursor', cursor);

  const rows = new Map(); // id -> tr
  const latest = new Map(); // id -> the last progress event of its stream
  function fillRow(tr, job) {
    tr.dataset.status = job.status;
    tr.replaceChildren(
      el('td', {}, statusPill(job.status)),
      el('td', {}, job.kind),
      el('td', { class: 'prog' }, el('a', { href: '/jobs/' + job.id }, tr.dataset.prog || job.id.slice(0, 8) + '…')),
      el('td', {}, fmtDate(job.created_at)),
      el('td', {}, progressBar(job), job.status === 'queued' || job.status === 'running'
        ? el('button', { class: 'cancel small', title: 'Cancel this job', onclick: (e) => { e.target.disabled = true; cancelJob(job.id).then(() => load()).catch((err) => handleError(err, tr.cells[4])); } }, 'cancel') : null),
      el('td', {}, job.duration_seconds !== null && job.duration_seconds !== undefined ? fmt(job.duration_seconds, 2) + ' s' : ''),
    );
  }
  function startStream(job) {
    if (streams.has(job.id) || streams.size >= MAX_STREAMS) return;
    const ctl = new AbortController();
    streams.set(job.id, ctl);
    follow(job.id, (ev, data) => {
      const tr = rows.get(job.id);
      if (!tr) return;
      if (ev === 'progress') {
        latest.set(job.id, data);
        fillRow(tr, { ...job, status: data.status, progress: { done: data.done, total: data.total } });
      } else if (ev === 'status') { latest.delete(job.id); Object.assign(job, data); fillRow(tr, data); }
    }, ctl.signal).catch(() => {}).finally(() => { if (streams.get(job.id) === ctl) streams.delete(job.id); });
  }
  async function load() {
    let page;
    try { page = await getJson('/v1/jobs?' + params); } catch (e) {
      stopList();
      handleError(e);
      return false;
    }
    const ids = new Set(page.items.map((j) => j.id));
    for (const [id, c] of streams) if (!ids.has(id)) { c.abort(); streams.delete(id); }
    const order = [];
    for (const job of page.items) {
      let tr = rows.get(job.id);
      if (!tr) { tr = el('tr', { 'data-id': job.id }); rows.set(job.id, tr); programName(job).then((n) => { if (n) { tr.dataset.prog = n; const a = tr.querySelector('td.prog a'); if (a) a.textContent = safeText(n); } }); }
      // A row's event stream may be ahead of the list's copy: the further progress is kept.
      const live = latest.get(job.id);
      if (live && (job.status === 'queued' || job.status === 'running') && live.done >= (job.progress ? job.progress.done : 0)) {
        fillRow(tr, { ...job, status: live.status, progress: { done: live.done, total: live.total } });
      } else fillRow(tr, job);
      if (job.status === 'queued' || job.status === 'running') startStream(job);
      order.push(tr);
    }
    for (const id of [...rows.keys()]) if (!ids.has(id)) rows.delete(id);
    tbody.replaceChildren(...order);
    if (!order.length) tbody.append(el('tr', {}, el('td', { colspan: 6, class: 'muted' }, 'No jobs' + (status || kind ? ' match these filters.' : ' yet.'))));
    pager.replaceChildren(...[
      prev.length || cursor ? el('button', { onclick: () => setQuery({ cursor: prev[prev.length - 1] || '', prev: prev.slice(0, -1) }) }, '← Newer') : null,
      page.next_cursor ? el('button', { onclick: () => setQuery({ cursor: page.next_cursor, prev: [...prev, cursor] }) }, 'Older →') : null,
      el('span', { class: 'muted' }, page.items.length + ' job(s) on this page'),
    ].filter(Boolean));
    document.getElementById('live').textContent = cursor ? '' : 'updates live';
    return true;
  }
  if (!(await load())) return;
  // The first page picks up new jobs (and jobs beyond the streamed ones) by polling.
  if (!cursor) listTimer = setInterval(() => { load(); }, 2000);
}

