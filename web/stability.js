// Stability jobs: the lobe diagram (critical axial depth against spindle speed) with the
// recommended speed, and for lobes over the workpiece's allowance the 3-D lobe surface.
import { el, fmt, card } from './util.js';
import { app, handleError } from './api.js';
import { loadRows } from './rows.js';
import { xyPlot } from './xyplot.js';

const PALETTE = ['#2463eb', '#c62828', '#18794e', '#ef6c00', '#6a1b9a', '#00838f', '#ad1457', '#5d4037'];

export async function renderStability(job, s, summarySlot) {
  const cards = el('div', { class: 'cards', id: 'cards' });
  if (s.minimum) cards.append(card('Smallest critical depth', fmt(s.minimum.depth_mm, 3) + ' mm', 'at ' + fmt(s.minimum.rpm, 0) + ' rpm'));
  const rec = s.recommendation;
  if (rec) cards.append(card('Recommended speed', fmt(rec.rpm, 0) + ' rpm', 'stable to ' + fmt(rec.stable_depth_mm, 3) + ' mm; pocket ' + fmt(rec.pocket_from_rpm, 0) + '–' + fmt(rec.pocket_to_rpm, 0) + ' rpm'));
  cards.append(card('Speeds', String(s.speeds ?? (s.points && s.allowances ? s.points / s.allowances : '–')), s.method ? 'method ' + s.method : null));
  if (s.allowances) cards.append(card('Allowances', String(s.allowances), s.points + ' points'));
  summarySlot.append(el('h2', {}, 'Summary'), cards);
  const plots = el('div', { id: 'plots' });
  app.append(el('h2', {}, 'Stability lobes'), plots);
  let rows;
  try { rows = await loadRows(job.id); } catch (e) { handleError(e, plots); return; }
  const rpm = rows.col('rpm');
  const depth = rows.col('depth_mm');
  const allowance = rows.has('allowance_mm') ? rows.col('allowance_mm') : null;
  const rpms = [...new Set(rpm)].sort((a, b) => a - b);
  const at = new Map(rpms.map((r, i) => [r, i]));
  const groups = new Map(); // allowance (or null) -> depth per rpm
  for (let i = 0; i < rows.length; i++) {
    const g = allowance ? allowance[i] : null;
    if (!groups.has(g)) groups.set(g, rpms.map(() => null));
    groups.get(g)[at.get(rpm[i])] = depth[i];
  }
  const series = [...groups].map(([a, values], k) => ({ label: a === null ? 'critical depth' : 'allowance ' + fmt(a, 2) + ' mm', values, color: PALETTE[k % PALETTE.length], spanGaps: true }));
  if (rec) series.push({ label: 'recommended', values: rpms.map((r) => (r === rec.rpm ? rec.stable_depth_mm : null)), color: '#111', pointsOnly: true });
  xyPlot(plots, 'Critical axial depth against spindle speed', 'rpm', 'mm', Float64Array.from(rpms), series,
    (i) => fmt(rpms[i], 0) + ' rpm · ' + series.filter((x) => x.values[i] !== null).map((x) => x.label + ' ' + fmt(x.values[i], 3) + ' mm').join(' · '));
  if (allowance && groups.size > 1) {
    const view = el('div', { id: 'lobes3d' });
    app.append(el('h2', {}, 'Lobe surface over the allowance'), view);
    const allowances = [...groups.keys()].sort((a, b) => a - b);
    const grid = allowances.map((a) => groups.get(a));
    const { showLobeSurface } = await import('/ui/lobes3d.js');
    const v = showLobeSurface(view, rpms, allowances, grid);
    view.append(el('p', { class: 'muted', id: 'lobes3dinfo' },
      'x: spindle speed ' + fmt(rpms[0], 0) + '–' + fmt(rpms[rpms.length - 1], 0) + ' rpm · y: allowance ' + fmt(allowances[0], 2) + '–' + fmt(allowances[allowances.length - 1], 2) +
      ' mm · up: critical depth 0–' + fmt(v.maxDepth, 2) + ' mm (blue shallow, red deep) · drag to orbit, wheel to zoom'));
  }
}
