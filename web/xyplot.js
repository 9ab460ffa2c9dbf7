// A plain x–y chart (lobes, Pareto front, identification fits) with a hover line.
import { el } from './util.js';

const uPlot = window.uPlot;

export function xyPlot(container, title, xLabel, yLabel, x, series, describe) {
  const box = el('div', { class: 'plot', 'data-plot': title }, el('div', { class: 'title' }, title));
  const hover = el('div', { class: 'hover' }, 'hover a point');
  container.append(box);
  new uPlot({
    width: Math.max(320, box.clientWidth - 20), height: 320,
    cursor: { drag: { x: true, y: true, uni: 20 } },
    scales: { x: { time: false } },
    axes: [{ label: xLabel }, { label: yLabel, size: 70 }],
    series: [{ label: xLabel }, ...series.map((s) => ({ label: s.label, stroke: s.color, width: s.width || 1.5, spanGaps: !!s.spanGaps,
      points: s.pointsOnly || s.points ? { show: true, size: s.pointsOnly ? 10 : 7, fill: s.color } : { show: false }, paths: s.pointsOnly ? () => null : undefined }))],
    hooks: { setCursor: [(u) => { const i = u.cursor.idx; if (i !== null && i !== undefined) hover.textContent = describe(i); }] },
  }, [x, ...series.map((s) => s.values)], box);
  box.append(hover);
}
