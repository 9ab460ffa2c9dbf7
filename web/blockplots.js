// The per-block plots of a simulate or optimize job (force, feed, MRR, power, torque,
// chatter margin), against block or against cycle time. Before and after optimization each
// run on their own clock: in cycle-time mode the "after" series are drawn at the optimized
// program's times, so the shorter program ends earlier on the same axis.
import { el, fmt, fmtTime, lowerBound } from './util.js';
import { XGroup, mergeHooks } from './panzoom.js';

const uPlot = window.uPlot;
const BLOCK_TICKS = [1, 2, 5, 10, 20, 50, 100, 200, 500, 1e3, 2e3, 5e3, 1e4, 2e4, 5e4, 1e5, 2e5, 5e5, 1e6, 2e6, 5e6];

// The end time of each row, s (rows are in program order).
function cumulative(values) {
  const out = new Float64Array(values.length);
  let t = 0;
  for (let i = 0; i < values.length; i++) { t += values[i] || 0; out[i] = t; }
  return out;
}

// Two series sets on their own sorted x, merged onto one x (O(n), unlike uPlot.join's
// sort): where a set has no point, `undefined`, which uPlot joins across.
function mergeX(xa, ya, xb, yb) {
  const n = xa.length + xb.length;
  const x = new Float64Array(n);
  const ys = [...ya, ...yb].map(() => new Array(n));
  let i = 0; let j = 0;
  for (let k = 0; k < n; k++) {
    if (j >= xb.length || (i < xa.length && xa[i] <= xb[j])) {
      x[k] = xa[i];
      for (let s = 0; s < ya.length; s++) ys[s][k] = ya[s][i];
      i++;
    } else {
      x[k] = xb[j];
      for (let s = 0; s < yb.length; s++) ys[ya.length + s][k] = yb[s][j];
      j++;
    }
  }
  return [x, ...ys];
}

// The plots as data: each series says which timeline it runs on (before or after).
function specs(rows, opt, limit, ctx_limits) {
  const c = (n) => rows.col(n);
  const list = [];
  const force = [
    { label: 'peak |F| before', values: c('force_peak_n'), color: '#c62828' },
    { label: 'mean |F| before', values: c('force_mean_n'), color: '#f39c9c' },
  ];
  if (opt) force.push({ label: 'peak |F| after', values: c('force_peak_opt_n'), color: '#2463eb', after: true });
  if (opt && rows.has('force_mean_opt_n')) force.push({ label: 'mean |F| after', values: c('force_mean_opt_n'), color: '#8fb3f5', after: true });
  if (limit != null) force.push({ label: 'limit', color: '#444', dash: [6, 4], constant: limit });
  list.push({ title: 'Cutting force', unit: 'N', series: force });
  // How the tool bends: its lowest cutting point, and the form error the move leaves
  // (+ material left, − overcut), beside the force that causes them.
  if (rows.has('deflection_peak_um')) {
    const bend = [
      { label: 'tool deflection', values: c('deflection_peak_um'), color: '#455a64' },
      { label: 'form error', values: c('form_error_um'), color: '#d81b60' },
    ];
    if (ctx_limits && ctx_limits.max_deflection_um != null) bend.push({ label: 'deflection limit', color: '#444', dash: [6, 4], constant: ctx_limits.max_deflection_um });
    list.push({ title: 'Deflection and form error', unit: 'µm', series: bend });
  }
  const feed = [{ label: 'feed before', values: c('feed_mm_min'), color: '#7a5c00' }];
  if (opt) feed.push({ label: 'feed after', values: c('feed_opt_mm_min'), color: '#18794e', after: true });
  list.push({ title: 'Feed', unit: 'mm/min', series: feed });
  const mrr = [{ label: 'MRR before', values: c('mrr_mm3_s'), color: '#6a1b9a' }];
  if (opt) {
    // The same volume in the optimized move's time: its mean MRR after.
    const v = c('removed_mm3'); const t = c('time_opt_s');
    mrr.push({ label: 'MRR after', values: v.map((x, i) => (t[i] > 0 ? x / t[i] : 0)), color: '#ba68c8', after: true });
  }
  list.push({ title: 'Material removal rate', unit: 'mm³/s', series: mrr });
  // After optimization: the same figures at the new feeds (each step evaluated again).
  const after = opt && rows.has('power_mean_opt_w');
  const power = [
    { label: 'peak power' + (after ? ' before' : ''), values: c('power_peak_w'), color: '#ef6c00' },
    { label: 'mean power' + (after ? ' before' : ''), values: c('power_mean_w'), color: '#ffb74d' },
  ];
  if (after) {
    power.push({ label: 'peak power after', values: c('power_peak_opt_w'), color: '#1565c0', after: true });
    power.push({ label: 'mean power after', values: c('power_mean_opt_w'), color: '#64b5f6', after: true });
  }
  list.push({ title: 'Spindle power', unit: 'W', series: power });
  const torque = [{ label: 'peak torque' + (after ? ' before' : ''), values: c('torque_peak_nm'), color: '#00838f' }];
  if (after) torque.push({ label: 'peak torque after', values: c('torque_peak_opt_nm'), color: '#5e35b1', after: true });
  list.push({ title: 'Torque', unit: 'N·m', series: torque });
  const chatter = c('chatter_margin');
  if (chatter.some((x) => x !== null)) {
    list.push({ title: 'Chatter margin', unit: '', series: [
      { label: 'axial depth / critical depth', values: chatter, color: '#ad1457' },
      { label: 'stability limit', color: '#444', dash: [6, 4], constant: 1 },
    ] });
  }
  return list;
}

// ctx: { opt, limit, source (lines), goToLine(row), onRange(firstRow, lastRow) }.
export function blockPlots(container, rows, ctx) {
  const group = new XGroup();
  const tBefore = cumulative(rows.col('time_s'));
  const tAfter = ctx.opt ? cumulative(rows.col('time_opt_s')) : null;
  const blocks = rows.col('block');
  const lines = rows.col('line');
  const ns = rows.col('n');
  const kinds = rows.col('kind');
  const list = specs(rows, ctx.opt, ctx.limit, ctx.opt && ctx.opt.limits);
  const holder = el('div');
  const toggle = el('div', { class: 'toolbar', id: 'xmode' }, 'x axis: ',
    ...[['block', 'block'], ['time', 'cycle time']].map(([v, label]) => el('label', {},
      el('input', { type: 'radio', name: 'xmode', value: v, checked: v === 'block', onchange: () => draw(v) }), ' ' + label)),
    el('span', { class: 'muted' }, 'drag: zoom · wheel: zoom · shift-drag or middle-drag: pan · double click: all'));
  container.append(toggle, holder);
  let mode = 'block';
  let forcePlot = null;

  // The rows in view on the x axis, for the samples.
  group.onChange((min, max) => {
    if (!ctx.onRange) return;
    const key = mode === 'block' ? blocks : tBefore;
    const a = Math.min(rows.length - 1, lowerBound(key, min));
    const b = Math.max(a, lowerBound(key, max + (mode === 'block' ? 1 : 0)) - (mode === 'block' ? 1 : 0));
    ctx.onRange(a, Math.min(rows.length - 1, b));
  });

  function describe(i, spec, at) {
    // at(series) -> the row index that series shows at the cursor.
    const r0 = at(spec.series[0]);
    const parts = [];
    if (mode === 'time') parts.push('t ' + fmt(hoverX, 2) + ' s');
    parts.push('block ' + blocks[r0] + ' · line ' + lines[r0] + ' · N ' + (ns[r0] ?? '–') + ' · ' + kinds[r0]);
    for (const s of spec.series) {
      if (s.constant !== undefined) continue;
      const r = at(s);
      parts.push(s.label + ' ' + fmt(s.values[r], 1) + ' ' + spec.unit + (mode === 'time' && s.after ? ' (block ' + blocks[r] + ', line ' + lines[r] + ')' : ''));
    }
    return [parts.join(' · '), ctx.source && ctx.source[lines[r0] - 1] !== undefined ? el('div', { class: 'src' }, lines[r0] + ': ' + ctx.source[lines[r0] - 1]) : ''];
  }
  let hoverX = 0;

  function plot(spec) {
    const box = el('div', { class: 'plot', 'data-plot': spec.title }, el('div', { class: 'title' }, spec.title + (mode === 'time' ? ' against cycle time' : '')));
    const hover = el('div', { class: 'hover' }, 'hover a point: block, line, N and the source line');
    holder.append(box);
    let data; let at;
    const variable = spec.series.filter((s) => s.constant === undefined);
    if (mode === 'block') {
      data = [blocks, ...variable.map((s) => s.values)];
      at = (i) => () => i;
    } else {
      const before = variable.filter((s) => !s.after);
      const after = variable.filter((s) => s.after);
      data = after.length ? mergeX(tBefore, before.map((s) => s.values), tAfter, after.map((s) => s.values))
        : [tBefore, ...before.map((s) => s.values)];
      // The row running at time x on each clock: the first whose end is at or after it.
      at = (i) => (s) => { const clock = s.after ? tAfter : tBefore; return Math.min(rows.length - 1, lowerBound(clock, data[0][i])); };
    }
    const n = data[0].length;
    const ordered = [...variable];
    for (const s of spec.series) if (s.constant !== undefined) { data.push(new Array(n).fill(s.constant)); ordered.push(s); }
    const g = group.options();
    const u = new uPlot({
      width: Math.max(320, box.clientWidth - 20), height: 240,
      cursor: g.cursor,
      scales: { x: { time: false } },
      // Blocks are whole numbers: no ticks between them.
      axes: [mode === 'block' ? { label: 'block', incrs: BLOCK_TICKS } : { label: 'cycle time (s)' }, { label: spec.unit, size: 70 }],
      series: [{ label: mode === 'block' ? 'block' : 's' }, ...ordered.map((s) => ({ label: s.label, stroke: s.color, width: 1, dash: s.dash, points: { show: false }, spanGaps: mode === 'time' }))],
      hooks: mergeHooks(g.hooks, { setScale: [(u, key) => {
        // The range in view, on the element: what the tests (and a reader of the DOM) see.
        if (key === 'x') box.dataset.x = u.scales.x.min.toFixed(3) + ',' + u.scales.x.max.toFixed(3);
      }], setCursor: [(u) => {
        const i = u.cursor.idx;
        if (i === null || i === undefined) return;
        hoverX = u.data[0][i];
        hover.replaceChildren(...describe(i, { ...spec, series: ordered }, at(i)));
      }] }),
    }, data, box);
    box.append(hover);
    if (ctx.goToLine) u.over.addEventListener('click', () => { const i = u.cursor.idx; if (i !== null && i !== undefined) ctx.goToLine(lines[at(i)(ordered[0])]); });
    group.add(u);
    return u;
  }

  function draw(m) {
    mode = m;
    group.clear();
    holder.replaceChildren();
    const made = list.map(plot);
    forcePlot = made[0];
    const total = mode === 'time' ? ' (before: ' + fmtTime(tBefore[tBefore.length - 1]) + (tAfter ? ', after: ' + fmtTime(tAfter[tAfter.length - 1]) : '') + ')' : '';
    made[0].root.closest('.plot').querySelector('.title').append(total);
    if (ctx.onRange) ctx.onRange(0, rows.length - 1);
  }
  draw('block');
  addEventListener('resize', () => { if (holder.isConnected) for (const u of group.plots) u.setSize({ width: Math.max(320, u.root.parentElement.clientWidth - 20), height: 240 }); });
  return { group, get forcePlot() { return forcePlot; }, get mode() { return mode; } };
}
