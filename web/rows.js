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

export class Rows {
  constructor(names) {
    this.names = names;
    this.cols = names.map(() => []);
    this.words = names.map((n) => WORDS.has(n));
    this.index = new Map(names.map((n, i) => [n, i]));
    this.length = 0;
  }

  push(f) {
    for (let j = 0; j < this.cols.length; j++) {
      const v = f[j];
      if (this.words[j]) this.cols[j].push(v === undefined ? '' : v);
      else if (v === undefined || v === '') this.cols[j].push(null);
      else {
        // A word in a column of numbers (true/false, a name) stays a word.
        const x = +v;
        this.cols[j].push(Number.isNaN(x) ? v : x);
      }
    }
    this.length++;
  }

  has(name) { return this.index.has(name); }
  // The column as an array (numbers or null; words for the word columns); absent: all null.
  col(name) {
    const j = this.index.get(name);
    return j === undefined ? new Array(this.length).fill(null) : this.cols[j];
  }
  // Row i as an object, for hovers and the samples (the columns stay the storage).
  row(i) {
    const o = {};
    for (let j = 0; j < this.names.length; j++) o[this.names[j]] = this.cols[j][i];
    return o;
  }
}

// Reads /v1/jobs/{id}/blocks?format=csv (only `columns` where given: a view that plots a
// third of the columns reads a third of the text); onProgress(rowsSoFar) after each chunk.
export async function loadRows(jobId, onProgress, columns) {
  const res = await api('/v1/jobs/' + encodeURIComponent(jobId) + '/blocks?format=csv' + (columns ? '&columns=' + encodeURIComponent(columns.join(',')) : ''));
  const reader = res.body.pipeThrough(new TextDecoderStream()).getReader();
  let rows = null;
  let rest = '';
  const take = (line) => {
    if (line === '') return;
    if (!rows) rows = new Rows(fields(line));
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
