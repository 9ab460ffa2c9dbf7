// Accessibility jobs: the fixed tool axis and largest tool that reach the target section,
// the free region seen along that axis (the job's SVG), and each depth segment's reach.
import { el, fmt, card } from './util.js';
import { api, handleError } from './api.js';

export async function renderAccessibility(job, s, summarySlot) {
  const axis = (s.axis || []).map((v) => fmt(v, 4)).join(', ');
  summarySlot.append(el('h2', {}, 'Reach'), el('div', { class: 'cards', id: 'cards' },
    card('Tool diameter', fmt(s.tool_diameter_mm, 3) + ' mm', s.tool ? 'chosen: ' + (s.tool.name || s.tool) : 'largest that plunges along the axis'),
    card('Axis', axis, 'tilt ' + fmt(s.tilt_deg, 2) + '°'),
    card('Free area', fmt(s.free_area_mm2, 1) + ' mm²', 'reach ' + fmt(s.reach_mm, 2) + ' mm'),
    card('Axes evaluated', String(s.axes_evaluated ?? '–'), fmt(s.seconds, 2) + ' s')));
  const region = el('div', { id: 'free-region' });
  summarySlot.append(el('h2', {}, 'Free region along the axis'), region);
  try {
    // Fetched (not an <img src>) so that the API key goes with it.
    const svg = await (await api('/v1/jobs/' + job.id + '/free_region.svg')).blob();
    region.append(el('img', { src: URL.createObjectURL(svg), alt: 'free region', style: 'max-width: 100%; background: #fff' }));
  } catch (e) { handleError(e, region); }
  const segments = Array.isArray(s.segments) ? s.segments : [];
  if (segments.length) {
    const head = ['Segment', 'Tilt °', 'Tool Ø mm', 'Free area mm²', 'Reach mm', 'Tool'];
    summarySlot.append(el('h2', {}, 'Depth segments'), el('table', { id: 'segments' },
      el('tr', {}, ...head.map((h) => el('th', {}, h))),
      ...segments.map((g, i) => el('tr', {}, el('td', {}, String(g.segment ?? i + 1)), el('td', {}, fmt(g.tilt_deg, 2)),
        el('td', {}, fmt(g.tool_diameter_mm, 3)), el('td', {}, fmt(g.free_area_mm2, 1)), el('td', {}, fmt(g.reach_mm, 2)),
        el('td', {}, g.tool ? String(g.tool.name || g.tool) : '–')))));
  }
}
