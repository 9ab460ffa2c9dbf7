// Identify jobs: the six cutting coefficients fitted from force measurements, each axis's
// straight line through the mean forces against feed per tooth (the closed form), or the
// force model's fitted mean force per cut or line (least squares), and the residuals.
import { el, fmt, card } from './util.js';
import { app, handleError } from './api.js';
import { loadRows } from './rows.js';
import { xyPlot } from './xyplot.js';

const AXES = [['x', '#c62828'], ['y', '#2463eb'], ['z', '#18794e']];

export async function renderIdentify(job, s, summarySlot) {
  const k = s.coefficients || {};
  const cards = el('div', { class: 'cards', id: 'cards' },
    card('Ktc', fmt(k.ktc, 1) + ' N/mm²', 'tangential cutting'), card('Krc', fmt(k.krc, 1) + ' N/mm²', 'radial cutting'), card('Kac', fmt(k.kac, 1) + ' N/mm²', 'axial cutting'),
    card('Kte', fmt(k.kte, 2) + ' N/mm', 'tangential edge'), card('Kre', fmt(k.kre, 2) + ' N/mm', 'radial edge'), card('Kae', fmt(k.kae, 2) + ' N/mm', 'axial edge'));
  // The exponential law's exponents, and the least squares' 95% intervals and conditioning.
  for (const [name, what] of [['mtc', 'tangential'], ['mrc', 'radial'], ['mac', 'axial']]) if (k[name]) cards.append(card(name, fmt(k[name], 4), what + ' size-effect exponent'));
  const ci = s.confidence_95 || {};
  for (const name of ['ktc', 'kte']) if (ci[name] && ci[name].low != null) cards.append(card(name + ' 95%', fmt(ci[name].low, 2) + ' … ' + fmt(ci[name].high, 2), 'confidence interval'));
  if (s.condition_number) cards.append(card('Condition', fmt(s.condition_number, 1), 'of the design matrix'));
  const fit = s.fit || {};
  const leastSquares = s.method && s.method !== 'average force';
  for (const [a] of AXES) if (fit[a]) cards.append(card('Fit F' + a, 'R² ' + fmt(fit[a].r_squared, 5), 'RMS residual ' + fmt(fit[a].rms_residual_n, 3) + ' N'));
  if (s.material) cards.append(card('Material created', s.material.name, 'id ' + s.material.id));
  summarySlot.append(el('h2', {}, 'Coefficients'), el('p', { class: 'muted' }, s.tests || ''), cards);
  const plots = el('div', { id: 'plots' });
  app.append(el('h2', {}, 'Mean force against feed per tooth'), plots);
  let rows;
  try { rows = await loadRows(job.id); } catch (e) { handleError(e, plots); return; }
  // Sorted by feed (uPlot wants x in order); measurements keep their own points.
  const order = Array.from({ length: rows.length }, (_, i) => i).sort((a, b) => rows.col('feed_per_tooth_mm')[a] - rows.col('feed_per_tooth_mm')[b]);
  const fz = order.map((i) => rows.col('feed_per_tooth_mm')[i]);
  const series = [];
  for (const [a, color] of AXES) {
    const measured = order.map((i) => rows.col('f' + a + '_n')[i]);
    series.push({ label: 'F' + a + ' measured', values: measured, color, pointsOnly: true });
    // Least squares: the model's own mean force per cut (not a line in the feed).
    if (leastSquares) series.push({ label: 'F' + a + ' model', values: order.map((i) => rows.col('f' + a + '_fit_n')[i]), color, pointsOnly: true });
    else if (fit[a]) series.push({ label: 'F' + a + ' fit', values: fz.map((f) => fit[a].intercept_n + fit[a].slope_n_per_mm * f), color });
  }
  xyPlot(plots, 'Mean force against feed per tooth', 'feed per tooth (mm)', 'N', Float64Array.from(fz), series,
    (j) => 'fz ' + fmt(fz[j], 4) + ' mm · ' + AXES.map(([a]) => 'F' + a + ' ' + fmt(rows.col('f' + a + '_n')[order[j]], 2) + ' N (residual ' + fmt(rows.col('f' + a + '_residual_n')[order[j]], 3) + ')').join(' · '));
}
