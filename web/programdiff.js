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
export function programDiff(view, orig, opt) {
  // Pairs lines that are equal but for their F word; a line of the optimized program that
  // pairs with none (a split part of a move) stands alone on the right.
  const pairs = [];
  let i = 0; let j = 0;
  while (i < orig.length || j < opt.length) {
    if (i < orig.length && j < opt.length && stripF(orig[i]) === stripF(opt[j])) { pairs.push([i, j]); i++; j++; }
    else if (j < opt.length && (i >= orig.length || opt.length - j > orig.length - i)) { pairs.push([null, j]); j++; }
    else { pairs.push([i, null]); i++; }
  }
  let changed = 0;
  const table = el('table', { class: 'diff' });
  const tbody = el('tbody');
  const byLine = new Map();
  for (const [a, b] of pairs) {
    const la = a === null ? null : orig[a];
    const lb = b === null ? null : opt[b];
    const differs = la !== null && lb !== null && fOf(la) !== fOf(lb);
    const added = la === null;
    if (differs || added) changed++;
    const tr = el('tr', { class: differs ? 'changed' : added ? 'added' : '' },
      el('td', { class: 'ln' }, a === null ? '' : String(a + 1)),
      el('td', { class: 'code' }, la === null ? '' : differs ? markF(la) : la),
      el('td', { class: 'ln' }, b === null ? '' : String(b + 1)),
      el('td', { class: 'code' }, lb === null ? '' : differs || added ? markF(lb) : lb));
    if (a !== null) byLine.set(a + 1, tr);
    tbody.append(tr);
  }
  table.append(el('thead', {}, el('tr', {}, el('th', {}, ''), el('th', {}, 'program'), el('th', {}, ''), el('th', {}, 'optimized'))), tbody);
  const scroller = el('div', { class: 'diffscroll' }, table);
  view.append(el('p', { class: 'muted', id: 'diffinfo' }, changed + ' line(s) with a changed or new F word · click a plot point to scroll here'), scroller);
  return {
    show(line) {
      const tr = byLine.get(line);
      if (!tr) return;
      for (const t of tbody.querySelectorAll('tr.focus')) t.classList.remove('focus');
      tr.classList.add('focus');
      scroller.scrollTop = tr.offsetTop - scroller.clientHeight / 2;
    },
  };
}
