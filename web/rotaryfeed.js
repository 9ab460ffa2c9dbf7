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
  let rows;
  try { rows = await loadRows(job.id); } catch (e) { handleError(e, plots); return; }
  const n = rows.length;
  const feed = rows.col('feed'); const out = rows.col('output'); const lim = rows.col('limited'); const lines = rows.col('line');
  xyPlot(plots, 'Programmed and written F', 'row', 'F', Float64Array.from({ length: n }, (_, i) => i), [
    { label: 'programmed F', values: feed, color: '#7a5c00' },
    { label: 'written F', values: out, color: '#18794e' },
    { label: 'limited by the machine', values: out.map((v, i) => (lim[i] === 'true' ? v : null)), color: '#c62828', pointsOnly: true },
  ], (i) => 'line ' + lines[i] + ' · programmed F ' + fmt(feed[i], 1) + ' · written F ' + fmt(out[i], 1) + (lim[i] === 'true' ? ' · limited by the machine' : ''));
  if (ops) return;
  const view = el('div', { id: 'programs' });
  app.append(el('h2', {}, 'Program and corrected program'), view);
  try {
    const [source, corrected] = await Promise.all([programSource(job), api(base + '/program').then((r) => r.text())]);
    if (source) programDiff(view, source, corrected.split(/\r?\n/));
  } catch (e) { handleError(e, view); }
}
