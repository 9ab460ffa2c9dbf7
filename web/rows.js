// A job's rows, read in one request as the API's CSV (streamed, parsed as it arrives) into
// columns. Paging the JSON would take 100 requests for 10^5 blocks, and 10^5 row objects
// weigh several times the columns.
import { api } from './api.js';

// Columns whose values are words even when they look like numbers (the rest are numbers
// where they parse as one; empty is null).
const WORDS = new Set(['kind', 'feed_mode', 'flags', 'governing', 'limited', 'dialect']);

// One CSV line into fields ("..." quoting with "" inside, as src/csv.rs writes it; no
// field of the rows holds a line break, so a line is a row).
function fields(line) {
  if (!line.includes('"')) return line.split(',');
  const out = [];
  let i = 0;
  while (i <= line.length) {
    if (line[i] === '"') {
      let v = '';
      i++;
      for (;;) {
        const q = line.indexOf('"', i);
        if (q < 0) { v += line.slice(i); i = line.length; break; }
        v += line.slice(i, q);
        if (line[q + 1] === '"') { v += '"'; i = q + 2; } else { i = q + 1; break; }
      }
      out.push(v);
      i++; // the comma
    } else {
      const c = line.indexOf(',', i);
      const end = c < 0 ? line.length : c;
      out.push(line.slice(i, end));
      i = end + 1;
    }
  }
  return out;
}

// A column of numbers stays a Float64Array (unboxed, grown by doubling) until it meets an
// empty field or a word; it then becomes a plain array (null for empty). 10^5 rows of
// numbers read several times faster so.
export class Rows {
  constructor(names, capacity) {
    this.names = names;
    this.cap = Math.max(16, capacity || 0);
    this.cols = names.map((n) => (WORDS.has(n) ? [] : new Float64Array(this.cap)));
    this.words = names.map((n) => WORDS.has(n));
    this.index = new Map(names.map((n, i) => [n, i]));
    this.length = 0;
  }

  push(f) {
    const i = this.length;
    if (i === this.cap) {
      this.cap *= 2;
      for (let j = 0; j < this.cols.length; j++) {
        const c = this.cols[j];
        if (c instanceof Float64Array) { const g = new Float64Array(this.cap); g.set(c); this.cols[j] = g; }
      }
    }
    for (let j = 0; j < this.cols.length; j++) {
      const v = f[j];
      const c = this.cols[j];
      if (this.words[j]) { c.push(v === undefined ? '' : v); continue; }
      const x = v === undefined || v === '' ? NaN : +v;
      if (c instanceof Float64Array && x === x) { c[i] = x; continue; }
      // Empty, or a word in a column of numbers (true/false, a name): a plain array.
      const a = c instanceof Float64Array ? Array.from(c.subarray(0, i)) : c;
      a.push(v === undefined || v === '' ? null : Number.isNaN(x) ? v : x);
      this.cols[j] = a;
    }
    this.length++;
  }

  has(name) { return this.index.has(name); }
  // The column (numbers, or null where empty; words for the word columns); absent: all null.
  col(name) {
    const j = this.index.get(name);
    if (j === undefined) return new Array(this.length).fill(null);
    const c = this.cols[j];
    if (c instanceof Float64Array && c.length !== this.length) this.cols[j] = c.slice(0, this.length);
    return this.cols[j];
  }
  // Row i as an object, for hovers and the samples (the columns stay the storage).
  row(i) {
    const o = {};
    for (let j = 0; j < this.names.length; j++) o[this.names[j]] = this.cols[j][i];
    return o;
  }
}

// Reads /v1/jobs/{id}/blocks?format=csv (only `columns` where given: a view that plots a
// third of the columns reads a third of the text; numbers to six significant digits); onProgress(rowsSoFar) after each chunk.
// `expected`: the number of rows, where known (the columns are sized for them).
export async function loadRows(jobId, onProgress, columns, expected) {
  // Six significant digits: what a plot or a hover shows, in half the text.
  const res = await api('/v1/jobs/' + encodeURIComponent(jobId) + '/blocks?format=csv&digits=6' + (columns ? '&columns=' + encodeURIComponent(columns.join(',')) : ''));
  const reader = res.body.pipeThrough(new TextDecoderStream()).getReader();
  let rows = null;
  let rest = '';
  const take = (line) => {
    if (line === '') return;
    if (!rows) rows = new Rows(fields(line), expected);
    else rows.push(fields(line));
  };
  for (;;) {
    const { value, done } = await reader.read();
    if (done) break;
    const text = rest + value;
    let start = 0;
    for (;;) {
      const nl = text.indexOf('\n', start);
      if (nl < 0) break;
      take(text.charCodeAt(nl - 1) === 13 ? text.slice(start, nl - 1) : text.slice(start, nl));
      start = nl + 1;
    }
    rest = text.slice(start);
    if (onProgress && rows) onProgress(rows.length);
  }
  take(rest);
  return rows || new Rows([]);
}
