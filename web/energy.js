// Energy jobs: the chosen cutting point and the Pareto front of time against energy.
import { el, fmt, fmtTime, card } from './util.js';
import { app } from './api.js';
import { xyPlot } from './xyplot.js';

export function renderEnergy(s, summarySlot) {
  const b = s.best || {};
  const cards = el('div', { class: 'cards', id: 'cards' });
  cards.append(card('Chosen point', fmt(b.spindle_rpm, 0) + ' rpm', 'F ' + fmt(b.feed_mm_min, 0) + ' mm/min · fz ' + fmt(b.feed_per_tooth_mm, 3) + ' mm'));
  cards.append(card('Passes', (b.axial_passes ?? '–') + ' × ' + (b.radial_passes ?? '–'), 'ap ' + fmt(b.axial_depth_mm, 2) + ' mm · ae ' + fmt(b.radial_width_mm, 2) + ' mm'));
  cards.append(card('Time', fmtTime(b.time_s)));
  cards.append(card('Energy', fmt(b.energy_j / 1000, 2) + ' kJ', 'cutting ' + fmt(b.cutting_energy_j / 1000, 2) + ' kJ'));
  cards.append(card('Utilization', fmt(100 * b.utilization, 1) + ' %', s.objective ? 'objective ' + s.objective : null));
  summarySlot.append(el('h2', {}, 'Summary'), cards);
  const plots = el('div', { id: 'plots' });
  app.append(el('h2', {}, 'Pareto front'), plots);
  // The chosen point is usually one of the front's: marked there, else added beside it.
  const same = (p) => Math.abs(p.time_s - b.time_s) <= 1e-9 * Math.abs(b.time_s) && Math.abs(p.energy_j - b.energy_j) <= 1e-9 * Math.abs(b.energy_j);
  const pts = s.pareto.map((p) => ({ p, best: same(p), front: true }));
  if (!pts.some((x) => x.best)) pts.push({ p: b, best: true, front: false });
  pts.sort((x, y) => x.p.time_s - y.p.time_s);
  xyPlot(plots, 'Energy against time', 's', 'kJ', Float64Array.from(pts, (x) => x.p.time_s), [
    { label: 'Pareto front', values: pts.map((x) => (x.front ? x.p.energy_j / 1000 : null)), color: '#2463eb', spanGaps: true },
    { label: 'chosen', values: pts.map((x) => (x.best ? x.p.energy_j / 1000 : null)), color: '#c62828', pointsOnly: true },
  ], (i) => { const p = pts[i].p; return (pts[i].best ? 'chosen · ' : '') + fmt(p.time_s, 3) + ' s · ' + fmt(p.energy_j / 1000, 3) + ' kJ · ' + fmt(p.spindle_rpm, 0) + ' rpm · F ' + fmt(p.feed_mm_min, 0) + ' · ' + p.axial_passes + '×' + p.radial_passes + ' passes'; });
}
