// Process jobs: a card per operation (cycle time before → after, removed volume, the limits
// that governed), the totals, and the per-block force and feed plots coloured by operation.
import { el, fmt, fmtTime, card } from './util.js';
import { app, handleError } from './api.js';
import { loadRows } from './rows.js';
import { xyPlot } from './xyplot.js';

// One colour per operation, in order (distinct at a glance, also in grey scale).
const COLOURS = ['#c62828', '#2463eb', '#2e7d32', '#ef6c00', '#6a1b9a', '#00838f', '#5d4037', '#ad1457'];
export const colourOf = (i) => COLOURS[i % COLOURS.length];

// What slowed the operation's moves (`limited_by`), or held them at their programmed feed
// because even that is over them (`limits_not_met`), over its tools: "force 120, guard_chip_thickness 40".
function limitList(o, key) {
  const counts = new Map();
  for (const t of (o.optimization && o.optimization.tools) || []) {
    for (const l of t[key] || []) counts.set(l.limit, (counts.get(l.limit) || 0) + l.moves);
  }
  return [...counts].sort((a, b) => b[1] - a[1]).map(([k, n]) => k + ' ' + n).join(', ');
}

function operationCard(o, i) {
  const opt = o.optimization;
  const before = o.cycle_time_s;
  const after = opt ? opt.cycle_time_after_s : null;
  const box = el('div', { class: 'opcard', 'data-operation': String(o.operation), style: 'border-left: 6px solid ' + colourOf(i) },
    el('h3', {}, o.operation + ' · ' + o.name, ' ', el('span', { class: 'muted' }, o.file || '')),
    el('div', { class: 'cards' },
      card('Cycle time', opt ? fmtTime(before) + ' → ' + fmtTime(after) : fmtTime(before),
        opt ? fmt(100 * (before - after) / before, 1) + '% shorter' : 'simulated (no limits)'),
      card('Removed volume', fmt(o.removed_volume_mm3, 0) + ' mm³', 'stock ' + fmt(o.stock_volume_before, 0) + ' → ' + fmt(o.stock_volume_after, 0) + ' mm³'),
      card('Peak force', fmt(o.force_peak_n, 1) + ' N' + (opt ? ' → ' + fmt(opt.peak_force_after, 1) + ' N' : ''), o.force_peak_line != null ? 'line ' + o.force_peak_line : null),
      card('Governing limits', opt ? (limitList(o, 'limited_by') || 'none') : '–',
        opt ? [opt.limits && opt.limits.max_force != null ? 'max force ' + fmt(opt.limits.max_force, 0) + ' N' : null,
          limitList(o, 'limits_not_met') ? 'not met (held at the programmed feed): ' + limitList(o, 'limits_not_met') : null].filter(Boolean).join(' · ') : null),
      o.spindle ? card('Spindle speed', fmt(o.spindle.chosen_rpm, 0) + ' rpm', 'programmed ' + fmt(o.spindle.programmed_rpm, 0) + ' rpm') : null,
      card('Collisions', String((o.collisions || []).length), null, (o.collisions || []).length ? 'bad' : '')));
  return box;
}

// Series of one column split by operation: each operation's values where its rows are,
// gaps elsewhere.
function byOperation(rows, column, ops) {
  const op = rows.col('operation');
  const v = rows.col(column);
  return ops.map((o, i) => {
    const values = new Array(rows.length);
    for (let k = 0; k < rows.length; k++) values[k] = op[k] === o.operation ? v[k] : null;
    return { label: o.operation + ' · ' + o.name, values, color: colourOf(i) };
  });
}

export async function renderProcess(job, s, summarySlot) {
  const ops = Array.isArray(s.operations) ? s.operations : [];
  summarySlot.append(el('h2', {}, 'Process'),
    el('div', { class: 'cards', id: 'cards' },
      card('Operations', String(ops.length), ops.map((o) => o.name).join(' → ')),
      card('Cycle time', fmtTime(s.cycle_time_s) + ' → ' + fmtTime(s.cycle_time_opt_s), s.cycle_time_s > 0 ? fmt(100 * (s.cycle_time_s - s.cycle_time_opt_s) / s.cycle_time_s, 1) + '% shorter' : null),
      card('Removed volume', fmt(s.removed_volume_mm3, 0) + ' mm³', 'stock ' + fmt(s.stock_volume_before, 0) + ' → ' + fmt(s.stock_volume_after, 0) + ' mm³'),
      card('Cell', fmt(s.cell_mm, 3) + ' mm', 'one grid for every operation')),
    el('div', { id: 'operations' }, ops.map(operationCard)));
  const plots = el('div', { id: 'plots' });
  const status = el('p', { class: 'muted', id: 'rowstatus' }, 'loading rows…');
  app.append(el('h2', {}, 'Per block, by operation'), status, plots);
  const wanted = ['operation', 'line', 'time_s', 'time_opt_s', 'force_peak_n', 'force_peak_opt_n', 'feed_mm_min', 'feed_opt_mm_min'].filter((c) => s.row_columns.includes(c));
  let rows;
  try { rows = await loadRows(job.id, (n) => { status.textContent = 'loading rows… ' + n + ' of ' + s.moves; }, wanted, s.moves); } catch (e) { handleError(e, plots); return; }
  status.textContent = rows.length + ' rows';
  // Against the process's cycle time (each operation's optimized time where it was
  // optimized): a short finish after a long rough keeps its share of the axis.
  const before = rows.col('time_s'); const opt = rows.col('time_opt_s');
  const wasOptimized = new Set(ops.filter((o) => o.optimized).map((o) => o.operation));
  const opOf = rows.col('operation'); const lines = rows.col('line');
  const x = new Float64Array(rows.length);
  let t = 0;
  for (let i = 0; i < rows.length; i++) { t += (wasOptimized.has(opOf[i]) && opt[i] != null ? opt[i] : before[i]) || 0; x[i] = t; }
  const describe = (col) => (i) => fmtTime(x[i]) + ' · operation ' + opOf[i] + ' · line ' + lines[i] + ' · ' + fmt(rows.col(col)[i], 1);
  const optimized = rows.has('force_peak_opt_n');
  const forceCol = optimized ? 'force_peak_opt_n' : 'force_peak_n';
  const feedCol = optimized ? 'feed_opt_mm_min' : 'feed_mm_min';
  // An operation not optimized has no "after": its own values stand.
  const after = (col, own) => byOperation(rows, col, ops).map((sr, i) => ops[i].optimized ? sr : byOperation(rows, own, ops)[i]);
  xyPlot(plots, 'Peak cutting force' + (optimized ? ' (optimized)' : ''), 'cycle time (s)', 'N', x, optimized ? after(forceCol, 'force_peak_n') : byOperation(rows, forceCol, ops), describe(forceCol));
  xyPlot(plots, 'Feed' + (optimized ? ' (optimized)' : ''), 'cycle time (s)', 'mm/min', x, optimized ? after(feedCol, 'feed_mm_min') : byOperation(rows, feedCol, ops), describe(feedCol));
}
