// Rotary-feed jobs: the F words rewritten so the tool tip moves at the programmed feed.
// The programmed against the written F per block, and the program beside the corrected one
// (a CLS input lists its posted operations instead).
import { el, fmt, card } from './util.js';
import { app, api, handleError, programSource } from './api.js';
import { loadRows } from './rows.js';
import { xyPlot } from './xyplot.js';
import { programDiff } from './programdiff.js';

export async function renderRotaryFeed(job, s, summarySlot) {
  const base = '/v1/jobs/' + encodeURIComponent(job.id);
  const cards = el('div', { class: 'cards', id: 'cards' }, card('Blocks', fmt(s.blocks, 0)));
  const ops = Array.isArray(s.operations) ? s.operations : null;
  const limited = ops ? ops.reduce((n, o) => n + (o.limited_blocks || 0), 0) : s.limited_blocks;
  cards.append(card('Limited by the machine', String(limited ?? 0), 'blocks whose feed the machine cannot reach', limited ? 'bad' : ''));
  if (s.skipped_moves != null) cards.append(card('Skipped moves', String(s.skipped_moves)));
  if (ops) cards.append(card('Operations', String(ops.length)));
  summarySlot.append(el('h2', {}, 'Summary'), cards);
  if (ops) {
    app.append(el('h2', {}, 'Operations'), el('table', { class: 'jobs', id: 'operations' },
      el('thead', {}, el('tr', {}, ['Operation', 'Tool', 'Moves', 'Limited blocks', 'File', 'Issues'].map((h) => el('th', {}, h)))),
      el('tbody', {}, ops.map((o) => el('tr', {}, el('td', {}, o.operation), el('td', {}, o.tool ?? ''), el('td', {}, o.moves), el('td', {}, o.limited_blocks),
        el('td', {}, o.file_name), el('td', {}, Array.isArray(o.issues) ? o.issues.length : ''))))));
  }
  const plots = el('div', { id: 'plots' });
  app.append(el('h2', {}, 'Feed per block'), plots);
  let rows; let source = null; let corrected = null;
  try {
    [rows, source, corrected] = await Promise.all([loadRows(job.id), programSource(job).catch(() => null), ops ? null : api(base + '/program').then((r) => r.text())]);
  } catch (e) { handleError(e, plots); return; }
  // The rows hold the written F (in `output`'s unit) per block; the F programmed for the
  // block is the one in force on its source line.
  const n = rows.length;
  const written = rows.col('feed'); const unit = rows.col('output'); const lim = rows.col('limited'); const lines = rows.col('line');
  const modal = source ? modalF(source) : null;
  const programmed = lines.map((l) => (modal ? modal[l - 1] ?? null : null));
  const few = n < 200;
  xyPlot(plots, 'Programmed and written F', 'row', 'F', Float64Array.from({ length: n }, (_, i) => i), [
    { label: 'programmed F', values: programmed, color: '#7a5c00', points: few },
    { label: 'written F', values: written, color: '#18794e', points: few },
    { label: 'limited by the machine', values: written.map((v, i) => (lim[i] === 'true' ? v : null)), color: '#c62828', pointsOnly: true },
  ], (i) => 'line ' + lines[i] + ' · programmed F ' + fmt(programmed[i], 1) + ' · written F ' + fmt(written[i], 1) + ' (' + unit[i] + ')' + (lim[i] === 'true' ? ' · limited by the machine' : ''));
  if (ops || !source) return;
  const view = el('div', { id: 'programs' });
  app.append(el('h2', {}, 'Program and corrected program'), view);
  programDiff(view, source, corrected.split(/\r?\n/), 'corrected');
}

// The F word in force on each source line (modal: a line without F keeps the last one).
function modalF(lines) {
  let f = null;
  return lines.map((line) => {
    const m = line.replace(/\([^)]*\)/g, '').replace(/;.*$/, '').match(/F\s*([-+]?(\d+\.?\d*|\.\d+))/i);
    if (m) f = Number(m[1]);
    return f;
  });
}
