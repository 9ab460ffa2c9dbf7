// Simulate and optimize jobs: summary cards, collisions, the machined stock in 3-D, the
// per-block plots with their samples, and the program beside the optimized one.
import { el, fmt, fmtTime, card } from './util.js';
import { app, api, handleError, NeedKey, programSource } from './api.js';
import { loadRows } from './rows.js';
import { blockPlots } from './blockplots.js';
import { samplesPanel } from './samples.js';
import { programDiff } from './programdiff.js';

// The row columns this view reads.
const ROW_COLUMNS = ['block', 'line', 'n', 'kind', 'time_s', 'time_opt_s', 'feed_mm_min', 'feed_opt_mm_min',
  'force_peak_n', 'force_mean_n', 'force_peak_opt_n', 'force_mean_opt_n', 'removed_mm3', 'mrr_mm3_s',
  'power_peak_w', 'power_mean_w', 'power_peak_opt_w', 'power_mean_opt_w', 'torque_peak_nm', 'torque_peak_opt_nm', 'chatter_margin',
  'deflection_peak_um', 'form_error_um'];

function summaryCards(s, opt) {
  const cards = el('div', { class: 'cards', id: 'cards' });
  if (opt) {
    cards.append(card('Cycle time before', fmtTime(opt.cycle_time_before_s)));
    cards.append(card('Cycle time after', fmtTime(opt.cycle_time_after_s), cycleChange(opt.cycle_time_before_s, opt.cycle_time_after_s)));
    cards.append(card('At best constant feed', fmtTime(opt.cycle_time_constant_feed_s), 'F ' + fmt(opt.best_constant_feed_mm_min, 0) + ' mm/min'));
    cards.append(card('Ideal bound', fmtTime(opt.cycle_time_ideal_s)));
  } else {
    cards.append(card('Cycle time', fmtTime(s.cycle_time_s)));
  }
  cards.append(card(opt ? 'Peak force before' : 'Peak force', fmt(s.force_peak_n, 1) + ' N', s.force_peak_line != null ? 'line ' + s.force_peak_line : null));
  if (opt) cards.append(card('Peak force after', fmt(opt.peak_force_after, 1) + ' N', opt.limits && opt.limits.max_force != null ? 'limit ' + fmt(opt.limits.max_force, 0) + ' N' : null));
  cards.append(card('Removed volume', fmt(s.removed_volume_mm3, 0) + ' mm³'));
  cards.append(card('Air time', fmtTime(s.air_time_s), s.air_moves != null ? s.air_moves + ' air moves' : null));
  const ncoll = Array.isArray(s.collisions) ? s.collisions.length : 0;
  cards.append(card('Collisions', String(ncoll), null, ncoll ? 'bad' : ''));
  const warn = [];
  if (s.rapid_in_material_moves) warn.push(s.rapid_in_material_moves + ' rapid in material');
  if (s.holder_or_shank_contact_moves) warn.push(s.holder_or_shank_contact_moves + ' shank/holder contact');
  if (s.flute_length_exceeded_moves) warn.push(s.flute_length_exceeded_moves + ' flute length exceeded');
  if (Array.isArray(s.tool_warnings) && s.tool_warnings.length) warn.push(s.tool_warnings.length + ' tool warning(s)');
  if (opt && opt.force_limit_unreachable_moves) warn.push(opt.force_limit_unreachable_moves + ' moves cannot reach the force limit');
  cards.append(card('Warnings', String(warn.length), warn.join('; ') || 'none', warn.length ? 'bad' : ''));
  // What the program as a whole may have wrong, and what the interpreter said as it read it
  // (codes ignored, a compensation radius taken from the job's tool), each with its line.
  const notes = [...(Array.isArray(s.warnings) ? s.warnings : []), ...(Array.isArray(s.program_warnings) ? s.program_warnings : [])];
  if (notes.length) cards.append(card('Program notes', String(notes.length), notes.slice(0, 5).join(' · ') + (notes.length > 5 ? ' · …' : '')));
  // Each tool's worst form error, the one a CAM programmer acts on.
  for (const t of Array.isArray(s.deflection) ? s.deflection : []) {
    cards.append(card('T' + t.tool + ' form error', fmt(t.form_error_um, 1) + ' µm',
      'line ' + (t.form_error_line ?? '–') + ' · deflection ' + fmt(t.deflection_peak_um, 1) + ' µm (line ' + (t.deflection_line ?? '–') + ') · ' + fmt(t.bending_stress_mpa, 0) + ' MPa'));
  }
  // The speed chosen out of chatter (options.spindle) and what it changed.
  if (s.spindle) {
    const sp = s.spindle;
    cards.append(card('Spindle speed', fmt(sp.chosen_rpm, 0) + ' rpm',
      'programmed ' + fmt(sp.programmed_rpm, 0) + ' rpm · chatter margin ' + fmt(sp.chatter_margin_max_before, 2) + ' → ' + fmt(sp.chatter_margin_max_after, 2) +
      (sp.stable ? '' : ' · not stable') + ' · ' + fmtTime(sp.cycle_time_programmed_s) + ' → ' + fmtTime(sp.cycle_time_at_chosen_s), sp.stable ? '' : 'bad'));
  }
  if (s.cutting_energy_j != null) cards.append(card('Cutting energy', fmt(s.cutting_energy_j / 1000, 2) + ' kJ'));
  if (s.part) cards.append(card('Gouge', fmt(s.part.gouge_volume, 2) + ' mm³', 'deepest ' + fmt(s.part.max_gouge_depth, 3) + ' mm · allowance ' + fmt(s.part.allowance_min, 2) + '–' + fmt(s.part.allowance_max, 2) + ' mm', s.part.gouge_volume > 0 ? 'bad' : ''));
  return cards;
}

function stockView(job, base, s) {
  // Loaded on request: the STL can be tens of MB.
  const view = el('div', { id: 'stock3d' });
  const partId = job.inputs && typeof job.inputs.part === 'string' ? job.inputs.part : null;
  const button = el('button', { id: 'load-stock', onclick: async () => {
    button.disabled = true;
    view.replaceChildren(el('p', { class: 'muted' }, 'loading the stock…'));
    try {
      const [mod, stl, part] = await Promise.all([
        import('/ui/stock3d.js'),
        api(base + '/stock.stl').then((r) => r.arrayBuffer()),
        partId ? api('/v1/stocks/' + encodeURIComponent(partId) + '/content').then((r) => r.arrayBuffer()) : Promise.resolve(null),
      ]);
      view.replaceChildren();
      const marks = (s.collisions || []).filter((c) => Array.isArray(c.from) && Array.isArray(c.to));
      const gouges = (s.part && Array.isArray(s.part.gouges)) ? s.part.gouges : [];
      const v = mod.showStock(view, stl, part, marks, gouges);
      view.append(el('p', { class: 'muted', id: 'stockinfo' }, v.triangles.toLocaleString('en-US') + ' triangles · ' + v.size.map((x) => fmt(x, 1)).join(' × ') + ' mm · drag to orbit, wheel to zoom, right-drag to pan',
        marks.length ? ' · ' + marks.length + ' collision(s) marked in red' : '',
        gouges.length ? ' · ' + gouges.length + ' gouge(s) marked in magenta' : '',
        part ? el('label', {}, ' · ', el('input', { type: 'checkbox', checked: true, onchange: (e) => v.setPartVisible(e.target.checked) }), ' design part (green)') : ''));
    } catch (e) { view.replaceChildren(); handleError(e, view); }
  } }, 'Show the machined stock in 3-D');
  return [el('h2', {}, 'Stock after machining'), button, view];
}

export async function renderCutting(job, s, summarySlot) {
  const base = '/v1/jobs/' + encodeURIComponent(job.id);
  const opt = s.optimization || null;
  summarySlot.append(el('h2', {}, 'Summary'), summaryCards(s, opt));
  if (s.spindle) summarySlot.append(el('p', { class: 'muted', id: 'spindle-reason' }, 'Spindle speed: ' + s.spindle.reason));
  performance.mark('cards-shown');
  if (s.collisions && s.collisions.length) {
    app.append(el('h2', {}, 'Collisions'), el('table', { class: 'jobs', id: 'collisions' },
      el('thead', {}, el('tr', {}, ['Block', 'Line', 'Kind', 'Tool tip from → to (mm)'].map((h) => el('th', {}, h)))),
      el('tbody', {}, s.collisions.map((c) => el('tr', {}, el('td', {}, c.block), el('td', {}, c.line), el('td', {}, c.kind),
        el('td', {}, Array.isArray(c.from) ? c.from.map((x) => fmt(x, 2)).join(', ') + ' → ' + c.to.map((x) => fmt(x, 2)).join(', ') : '–'))))));
  }
  const gouges = s.part && Array.isArray(s.part.gouges) ? s.part.gouges : [];
  if (gouges.length) {
    const xyz = (p) => p.map((x) => fmt(x, 2)).join(', ');
    app.append(el('h2', {}, 'Gouges'), el('p', { class: 'muted' }, s.part.gouge_regions + ' region(s) cut below the design part' + (s.part.gouge_regions > gouges.length ? ', the ' + gouges.length + ' largest listed' : '') + '; marked in magenta on the 3-D stock.'),
      el('table', { class: 'jobs', id: 'gouges' },
        el('thead', {}, el('tr', {}, ['Deepest at X, Y, Z (mm)', 'Depth (mm)', 'Volume (mm³)', 'From X, Y, Z', 'To X, Y, Z'].map((h) => el('th', {}, h)))),
        el('tbody', {}, gouges.map((g) => el('tr', {}, el('td', {}, xyz(g.at)), el('td', {}, fmt(g.depth, 3)), el('td', {}, fmt(g.volume, 2)), el('td', {}, xyz(g.min)), el('td', {}, xyz(g.max)))))));
  }
  app.append(...stockView(job, base, s));
  const plots = el('div', { id: 'plots' });
  const status = el('p', { class: 'muted', id: 'rowstatus' }, 'loading rows…');
  app.append(el('h2', {}, 'Per block'), status, plots);
  // The program's source (for the hover and the program view) loads while the rows do.
  const sourceP = programSource(job);
  sourceP.catch(() => {});
  let rows;
  const total = s.moves;
  // Only the columns the plots, hovers and samples read (the CSV download has them all).
  const wanted = ROW_COLUMNS.filter((c) => !Array.isArray(s.row_columns) || s.row_columns.includes(c));
  try { rows = await loadRows(job.id, (n) => { status.textContent = 'loading rows… ' + n + (total ? ' of ' + total : ''); }, wanted, total); } catch (e) { handleError(e, plots); return; }
  status.textContent = rows.length + ' rows';
  performance.mark('rows-loaded');
  const limit = opt && opt.limits ? opt.limits.max_force : null;
  if (opt && rows.length) {
    // The summary names the line of the peak before; the line of the peak after is read from the rows.
    const after = rows.col('force_peak_opt_n'); const lines = rows.col('line');
    let best = 0;
    for (let i = 1; i < rows.length; i++) if ((after[i] || 0) > (after[best] || 0)) best = i;
    const n = document.querySelector('[data-card="Peak force after"] .n');
    if (n) n.textContent = 'line ' + lines[best] + (limit != null ? ' · limit ' + fmt(limit, 0) + ' N' : '');
  }
  let source = null;
  try { source = await sourceP; } catch (e) { if (e instanceof NeedKey) { handleError(e); return; } }
  let programView = null;
  const samplesBox = el('div', { id: 'samples' });
  let setRange = null;
  const plotsCtl = blockPlots(plots, rows, { opt, limit, source,
    goToLine: (line) => { if (programView) programView.show(line); },
    onRange: (a, b) => { if (setRange) setRange(a, b); } });
  plots.append(samplesBox);
  setRange = samplesPanel(samplesBox, base, rows);
  performance.mark('plots-drawn');
  // A simulate job with a chosen spindle speed has the program at that speed to compare.
  if (source && (job.kind === 'optimize' || s.spindle)) {
    const view = el('div', { id: 'programs' });
    app.append(el('h2', {}, job.kind === 'optimize' ? 'Program and optimized program' : 'Program and program at the chosen speed'), view);
    try {
      const optimized = (await (await api(base + '/program')).text()).split(/\r?\n/);
      programView = programDiff(view, source, optimized);
    } catch (e) { handleError(e, view); }
  }
}

// The change of the cycle time in words: "12.3 % shorter", "4.5 % longer" (a longer cycle is
// never shown as a negative "shorter"), "unchanged".
export function cycleChange(before, after) {
  if (!(before > 0)) return null;
  const pct = 100 * (after - before) / before;
  if (Math.abs(pct) < 0.05) return 'unchanged';
  return fmt(Math.abs(pct), 1) + (pct < 0 ? ' % shorter' : ' % longer');
}
