// Interpret jobs: what the interpreter read (moves, blocks), its warnings with their source
// lines, and the tool path in 3-D.
import { el, fmt, card } from './util.js';
import { app, handleError, programSource } from './api.js';
import { loadRows } from './rows.js';

export async function renderInterpret(job, s, summarySlot) {
  const warnings = Array.isArray(s.warnings) ? s.warnings : [];
  const cards = el('div', { class: 'cards', id: 'cards' },
    card('Moves', fmt(s.moves, 0)), card('Blocks', fmt(s.blocks, 0)),
    card('Warnings', String(warnings.length), warnings.length ? 'first on line ' + warnings[0].line : 'none', warnings.length ? 'bad' : ''));
  summarySlot.append(el('h2', {}, 'Summary'), cards);
  const source = await programSource(job).catch(() => null);
  if (warnings.length) {
    app.append(el('h2', {}, 'Warnings'), el('table', { class: 'jobs', id: 'warnings' },
      el('thead', {}, el('tr', {}, ['Line', 'Column', 'What', 'Source'].map((h) => el('th', {}, h)))),
      el('tbody', {}, warnings.map((w) => el('tr', {}, el('td', {}, w.line ?? ''), el('td', {}, w.column ?? ''), el('td', {}, w.message),
        el('td', { class: 'code' }, source && w.line ? source[w.line - 1] ?? '' : ''))))));
  }
  const view = el('div', { id: 'toolpath3d' });
  const status = el('p', { class: 'muted' }, 'loading moves…');
  app.append(el('h2', {}, 'Tool path'), status, view);
  let rows;
  try { rows = await loadRows(job.id, (n) => { status.textContent = 'loading moves… ' + n; }); } catch (e) { handleError(e, view); return; }
  status.remove();
  if (!rows.has('end_x')) { view.append(el('p', { class: 'muted' }, 'The moves carry no positions.')); return; }
  const kinds = rows.col('kind');
  const count = (k) => kinds.reduce((n, x) => n + (x === k ? 1 : 0), 0);
  const { showToolpath } = await import('/ui/toolpath3d.js');
  const v = showToolpath(view, rows);
  view.append(el('p', { class: 'muted', id: 'toolpathinfo' }, count('rapid') + ' rapids (orange) · ' + (count('linear') + count('arc')) + ' feed moves (blue, ' + count('arc') + ' arcs) · ' +
    v.size.map((x) => fmt(x, 1)).join(' × ') + ' mm · drag to orbit, wheel to zoom, right-drag to pan'));
}
