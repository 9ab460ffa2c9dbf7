// Small DOM and number helpers shared by every view.

// Bidi controls (U+202A–U+202E, U+2066–U+2069, U+200E/F) in text the dashboard shows are
// written out as [U+202E]: names come from users, and an override in one would reverse the
// rest of its line (a program 'x\u202Ecn.exe' shown as 'xexe.nc').
const BIDI_CONTROLS = /[\u200E\u200F\u202A-\u202E\u2066-\u2069]/g;
export function safeText(s) {
  return String(s).replace(BIDI_CONTROLS, (c) => '[U+' + c.charCodeAt(0).toString(16).toUpperCase() + ']');
}

// Every text child goes through safeText: user-given names reach the page only this way
// (or through safeText directly where textContent is set).
export function el(tag, attrs, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === null || v === undefined || v === false) continue;
    if (k === 'class') e.className = v;
    else if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
    else e.setAttribute(k, v === true ? '' : v);
  }
  for (const c of children.flat()) {
    if (c === null || c === undefined || c === false) continue;
    e.append(c instanceof Node ? c : document.createTextNode(safeText(c)));
  }
  return e;
}

export function fmt(x, digits) {
  if (x === null || x === undefined || Number.isNaN(x)) return '–';
  const d = digits === undefined ? (Math.abs(x) >= 100 ? 0 : Math.abs(x) >= 10 ? 1 : 2) : digits;
  // A value that rounds to zero is shown as 0, not -0.00.
  const v = Number(Number(x).toFixed(d)) === 0 ? 0 : Number(x);
  return v.toLocaleString('en-US', { minimumFractionDigits: d, maximumFractionDigits: d });
}

export function fmtTime(s) {
  if (s === null || s === undefined) return '–';
  if (s < 60) return fmt(s, 2) + ' s';
  const m = Math.floor(s / 60);
  return m + ' min ' + fmt(s - 60 * m, 1) + ' s';
}

export const fmtDate = (iso) => (iso ? new Date(iso).toLocaleString() : '–');
const pct = (p) => (p && p.total > 0 ? Math.min(100, (100 * p.done) / p.total) : 0);

export function card(k, v, n, cls) {
  return el('div', { class: 'card ' + (cls || ''), 'data-card': k }, el('div', { class: 'k' }, k), el('div', { class: 'v' }, v), n ? el('div', { class: 'n' }, n) : null);
}

export function statusPill(s) { return el('span', { class: 'status ' + s, 'data-status': s }, s); }

export function progressBar(job) {
  const p = job.progress || { done: 0, total: 0 };
  return el('span', {},
    el('span', { class: 'bar ' + job.status }, el('div', { style: 'width:' + pct(p).toFixed(1) + '%' })),
    el('span', { class: 'pct' }, p.total > 0 ? p.done + ' / ' + p.total : ''));
}

// A problem document (RFC 9457) as the API sends it: file, line, column and what is wrong.
export function problemView(p) {
  const dl = el('dl');
  const add = (k, v) => { if (v !== undefined && v !== null && v !== '') dl.append(el('dt', {}, k), el('dd', { 'data-field': k }, typeof v === 'object' ? JSON.stringify(v) : String(v))); };
  add('title', p.title); add('detail', p.detail); add('file', p.file); add('line', p.line); add('column', p.column);
  for (const [k, v] of Object.entries(p)) if (!['type', 'title', 'status', 'detail', 'file', 'line', 'column', 'errors'].includes(k)) add(k, v);
  const errs = Array.isArray(p.errors) ? el('table', { class: 'jobs' }, el('thead', {}, el('tr', {}, ['File', 'Line', 'Column', 'What is wrong'].map((h) => el('th', {}, h)))),
    el('tbody', {}, p.errors.map((e) => el('tr', {}, el('td', {}, e.file || p.file || ''), el('td', {}, e.line ?? ''), el('td', {}, e.column ?? ''), el('td', {}, e.message || e.detail || JSON.stringify(e)))))) : null;
  return el('div', { class: 'problem', id: 'problem' }, el('div', { class: 'muted' }, p.type || ''), dl, errs);
}

// The first index in a sorted array at or after x (binary search; the arrays hold 10^5 rows).
export function lowerBound(sorted, x) {
  let lo = 0; let hi = sorted.length;
  while (lo < hi) { const mid = (lo + hi) >> 1; if (sorted[mid] < x) lo = mid + 1; else hi = mid; }
  return lo;
}
