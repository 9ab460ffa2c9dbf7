// The program beside its rewritten copy (optimized feeds, rotary feed correction): lines
// paired where they are equal but for their F word, changed F words marked.
import { el } from './util.js';

const F_WORD = /F\s*[-+]?(\d+\.?\d*|\.\d+)/i;
function stripF(line) { return line.replace(/\([^)]*\)/g, '').replace(/F\s*[-+]?(\d+\.?\d*|\.\d+)/gi, '').replace(/\s+/g, ''); }
function fOf(line) { const m = line.replace(/\([^)]*\)/g, '').match(F_WORD); return m ? m[0].replace(/\s+/g, '').toUpperCase() : null; }
function markF(line) {
  // The line with its F word wrapped in <mark> (outside comments).
  const frag = document.createDocumentFragment();
  let depth = 0; let i = 0;
  for (; i < line.length; i++) {
    const c = line[i];
    if (c === '(') depth++;
    else if (c === ')') depth = Math.max(0, depth - 1);
    else if (depth === 0 && (c === 'F' || c === 'f')) {
      const m = line.slice(i).match(/^[Ff]\s*[-+]?(\d+\.?\d*|\.\d+)/);
      if (m) { frag.append(line.slice(0, i), el('mark', {}, m[0]), line.slice(i + m[0].length)); return frag; }
    }
  }
  frag.append(line);
  return frag;
}
// Height of one line of the listing, px (dashboard.css sets it): the listing draws only the
// lines in view, so that a program of 10^5 lines costs no more than one of 100.
const LINE_PX = 17;
const OVERSCAN = 20;

export function programDiff(view, orig, opt, rightTitle) {
  // Pairs lines that are equal but for their F word; a line of the optimized program that
  // pairs with none (a split part of a move) stands alone on the right.
  const left = []; const right = []; const kind = [];
  let i = 0; let j = 0;
  const byLine = new Map(); // source line -> pair index
  let changed = 0;
  const add = (a, b) => {
    const la = a === null ? null : orig[a];
    const lb = b === null ? null : opt[b];
    const k = la !== null && lb !== null && fOf(la) !== fOf(lb) ? 'changed' : la === null ? 'added' : '';
    if (k) changed++;
    if (a !== null) byLine.set(a + 1, left.length);
    left.push(a); right.push(b); kind.push(k);
  };
  while (i < orig.length || j < opt.length) {
    if (i < orig.length && j < opt.length && stripF(orig[i]) === stripF(opt[j])) { add(i, j); i++; j++; }
    else if (j < opt.length && (i >= orig.length || opt.length - j > orig.length - i)) { add(null, j); j++; }
    else { add(i, null); i++; }
  }
  const n = left.length;
  const cols = () => el('colgroup', {}, el('col', { class: 'ln' }), el('col', {}), el('col', { class: 'ln' }), el('col', {}));
  const head = el('table', { class: 'diff head' }, cols(), el('thead', {}, el('tr', {}, el('th', {}, ''), el('th', {}, 'program'), el('th', {}, ''), el('th', {}, rightTitle || 'optimized'))));
  const tbody = el('tbody');
  const table = el('table', { class: 'diff', 'data-changed': changed }, cols(), tbody);
  const spacer = el('div', { style: 'position:relative;height:' + n * LINE_PX + 'px' }, table);
  const scroller = el('div', { class: 'diffscroll' }, head, spacer);
  let focus = -1;
  function draw() {
    const first = Math.max(0, Math.floor(scroller.scrollTop / LINE_PX) - OVERSCAN);
    const last = Math.min(n, Math.ceil((scroller.scrollTop + scroller.clientHeight) / LINE_PX) + OVERSCAN);
    table.style.top = first * LINE_PX + 'px';
    const rows = [];
    for (let k = first; k < last; k++) {
      const a = left[k]; const b = right[k]; const mark = kind[k];
      rows.push(el('tr', { class: (mark || '') + (k === focus ? ' focus' : '') },
        el('td', { class: 'ln' }, a === null ? '' : String(a + 1)),
        el('td', { class: 'code' }, a === null ? '' : mark === 'changed' ? markF(orig[a]) : orig[a]),
        el('td', { class: 'ln' }, b === null ? '' : String(b + 1)),
        el('td', { class: 'code' }, b === null ? '' : mark ? markF(opt[b]) : opt[b])));
    }
    tbody.replaceChildren(...rows);
  }
  let queued = false;
  scroller.addEventListener('scroll', () => { if (!queued) { queued = true; requestAnimationFrame(() => { queued = false; draw(); }); } });
  view.append(el('p', { class: 'muted', id: 'diffinfo' }, changed + ' line(s) with a changed or new F word · click a plot point to scroll here'), scroller);
  draw();
  return {
    show(line) {
      const k = byLine.get(line);
      if (k === undefined) return;
      focus = k;
      scroller.scrollTop = k * LINE_PX - scroller.clientHeight / 2;
      draw();
    },
  };
}
