// Per-step force samples (the /samples endpoint) of the rows in view on the plots: zoom to
// at most MAX_SAMPLE_ROWS rows, then load them.
import { el, fmt } from './util.js';
import { getJson, handleError } from './api.js';

const uPlot = window.uPlot;
const MAX_SAMPLE_ROWS = 400;

// Returns setRange(firstRow, lastRow), for the plots to call as they zoom and pan.
export function samplesPanel(box, base, rows) {
  const info = el('span', { class: 'muted' });
  const button = el('button', { id: 'load-samples' }, 'Per-step samples of the blocks in view');
  const holder = el('div');
  box.append(el('div', { class: 'toolbar' }, button, info), holder);
  const blocks = rows.col('block');
  let range = [0, rows.length - 1];
  const update = () => {
    const n = range[1] - range[0] + 1;
    button.disabled = n > MAX_SAMPLE_ROWS;
    info.textContent = n > MAX_SAMPLE_ROWS ? n + ' rows in view: zoom the plots to at most ' + MAX_SAMPLE_ROWS
      : 'rows ' + range[0] + '–' + range[1] + ' (blocks ' + blocks[range[0]] + '–' + blocks[range[1]] + ')';
  };
  update();
  button.addEventListener('click', async () => {
    const [a, b] = range;
    holder.replaceChildren(el('p', { class: 'muted' }, 'loading samples…'));
    let page;
    try { page = await getJson(base + '/blocks/' + a + '-' + b + '/samples'); } catch (e) { holder.replaceChildren(); handleError(e, holder); return; }
    const pts = [];
    for (const item of page.items) {
      const r = rows.row(item.row);
      for (const smp of item.samples) pts.push({ r, smp });
    }
    holder.replaceChildren();
    if (!pts.length) { holder.append(el('p', { class: 'muted' }, 'No engaged steps in rows ' + a + '–' + b + '.')); return; }
    const plotBox = el('div', { class: 'plot', 'data-plot': 'Samples' }, el('div', { class: 'title' }, 'Per-step force, rows ' + a + '–' + b + ' (' + pts.length + ' steps with the tool engaged)'));
    const hover = el('div', { class: 'hover' }, 'hover a step: block, line, position along the move');
    holder.append(plotBox);
    new uPlot({
      width: Math.max(320, plotBox.clientWidth - 20), height: 220,
      scales: { x: { time: false } },
      axes: [{ label: 'engaged step' }, { label: 'N', size: 70 }],
      series: [{ label: 'step' }, { label: 'peak |F|', stroke: '#c62828', points: { show: false } }, { label: 'mean |F|', stroke: '#f39c9c', points: { show: false } }],
      hooks: { setCursor: [(u) => { const i = u.cursor.idx; if (i === null || i === undefined) return; const p = pts[i];
        hover.textContent = 'block ' + p.r.block + ' · line ' + p.r.line + ' · at ' + fmt(p.smp.at, 2) + ' mm · peak ' + fmt(p.smp.peak_force, 1) + ' N · mean ' + fmt(p.smp.mean_force, 1) + ' N · torque ' + fmt(p.smp.peak_torque, 3) + ' N·m'; }] },
    }, [Float64Array.from(pts, (_, i) => i), Float64Array.from(pts, (p) => p.smp.peak_force), Float64Array.from(pts, (p) => p.smp.mean_force)], plotBox);
    plotBox.append(hover);
  });
  return (a, b) => { range = [a, b]; update(); };
}
