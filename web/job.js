// One job (/jobs/{id}): its header, live progress with a cancel button while it runs, its
// problem when it failed, and the view of its kind once it succeeded.
import { el, fmt, fmtDate, statusPill, progressBar, problemView } from './util.js';
import { app, getJson, follow, handleError, programName, programSource, cancelJob, downloadLink } from './api.js';

let following = null; // the running job's event stream, closed when the page changes

export function stopJob() { if (following) { following.abort(); following = null; } }

export async function renderJob(id) {
  stopJob();
  let job;
  try { job = await getJson('/v1/jobs/' + encodeURIComponent(id)); } catch (e) { app.replaceChildren(el('h1', {}, 'Job ' + id)); handleError(e); return; }
  const name = await programName(job);
  const head = el('div', {},
    el('div', {}, el('a', { href: '/' }, '← all jobs')),
    el('h1', {}, job.kind + ' ', name ? el('span', { id: 'progname' }, name) : null, ' ', statusPill(job.status)),
    el('div', { class: 'meta' }, el('span', {}, 'id ' + job.id), el('span', {}, 'created ' + fmtDate(job.created_at)),
      job.finished_at ? el('span', {}, 'finished ' + fmtDate(job.finished_at)) : null,
      job.duration_seconds != null ? el('span', {}, 'ran ' + fmt(job.duration_seconds, 2) + ' s') : null,
      el('span', {}, 'attempts ' + job.attempts + ' / ' + job.max_attempts)));
  app.replaceChildren(head);

  if (job.status === 'queued' || job.status === 'running') {
    const bar = el('span', {}, progressBar(job));
    const note = el('span', { class: 'muted', id: 'cancelstate' });
    const cancel = el('button', { id: 'cancel-job', onclick: async () => {
      cancel.disabled = true;
      note.textContent = ' cancelling…';
      try {
        const after = await cancelJob(job.id);
        // A queued job is cancelled at once; a running one stops when its worker looks.
        if (after.status === 'cancelled') renderJob(id);
        else note.textContent = ' cancel requested: the worker stops at its next check';
      } catch (e) { cancel.disabled = false; note.textContent = ''; handleError(e, note); }
    } }, 'Cancel job');
    app.append(el('div', { id: 'jobprogress', class: 'toolbar' }, bar, cancel, note));
    const ctl = new AbortController();
    following = ctl;
    follow(job.id, (ev, data) => {
      if (ev === 'progress') bar.replaceChildren(progressBar({ ...job, status: data.status, progress: { done: data.done, total: data.total } }));
      else if (ev === 'status' && data.status !== 'queued' && data.status !== 'running') { ctl.abort(); renderJob(id); }
    }, ctl.signal).catch(() => {});
    return;
  }
  if (job.status === 'failed' && job.error) {
    app.append(el('h2', {}, 'Problem'), problemView(job.error));
    // The program's line the problem names, with a caret under its column.
    const line = job.error.line;
    const source = Number.isInteger(line) ? await programSource(job).catch(() => null) : null;
    if (source && source[line - 1] !== undefined) {
      const col = job.error.column;
      app.append(el('pre', { class: 'problem-source', id: 'problem-source' }, line + ': ' + source[line - 1] +
        (Number.isInteger(col) && col > 0 ? '\n' + ' '.repeat(String(line).length + 2 + col - 1) + '^' : '')));
    }
    return;
  }
  if (job.status !== 'succeeded') { app.append(el('p', { class: 'muted', id: 'ended' }, 'The job was ' + job.status + '.')); return; }

  const base = '/v1/jobs/' + encodeURIComponent(job.id);
  const s = job.summary || {};
  const downloads = el('div', { class: 'downloads', id: 'downloads' });
  const dl = (label, href, file) => downloadLink(label, href, file, downloads);
  const summarySlot = el('div');
  app.append(summarySlot, el('h2', {}, 'Downloads'), downloads);
  const cutting = (job.kind === 'simulate' || job.kind === 'optimize') && Array.isArray(s.row_columns) && s.row_columns.includes('force_peak_n');
  if (job.kind === 'optimize' || (job.kind === 'rotary-feed' && !Array.isArray(s.operations))) downloads.append(dl(job.kind === 'optimize' ? 'Optimized program' : 'Corrected program', base + '/program'));
  if (job.kind === 'accessibility' && typeof s.program === 'object' && s.program && !s.program.none) downloads.append(dl('Roughing program (G-code)', base + '/program'));
  if (Array.isArray(s.operations)) for (const o of s.operations) downloads.append(dl('Operation ' + o.operation + ' (G-code)', base + '/program?operation=' + o.operation, o.file_name));
  downloads.append(dl('Rows (CSV)', base + '/blocks?format=csv', 'job-' + job.id + '.csv'));
  if (job.kind === 'simulate' || job.kind === 'optimize' || job.kind === 'process') downloads.append(dl('Stock after machining (STL)', base + '/stock.stl', 'stock-' + job.id + '.stl'));
  // A process kept with keep_stocks: the stock after each operation but the last (the final one above).
  if (job.kind === 'process' && s.keep_stocks) for (const o of (s.operations || []).slice(0, -1)) downloads.append(dl('Stock after operation ' + o.operation + ' (STL)', base + '/stock.stl?operation=' + o.operation, 'stock-' + job.id + '-op' + o.operation + '.stl'));
  downloads.append(dl('Summary (JSON)', base + '/summary', 'summary-' + job.id + '.json'));

  // Each kind's view is its own module, loaded when a job of that kind is shown.
  if (cutting) (await import('/ui/cutting.js')).renderCutting(job, s, summarySlot);
  else if (job.kind === 'stability' && Array.isArray(s.row_columns)) (await import('/ui/stability.js')).renderStability(job, s, summarySlot);
  else if (job.kind === 'energy' && Array.isArray(s.pareto)) (await import('/ui/energy.js')).renderEnergy(s, summarySlot);
  else if (job.kind === 'interpret') (await import('/ui/interpret.js')).renderInterpret(job, s, summarySlot);
  else if (job.kind === 'rotary-feed') (await import('/ui/rotaryfeed.js')).renderRotaryFeed(job, s, summarySlot);
  else if (job.kind === 'identify') (await import('/ui/identify.js')).renderIdentify(job, s, summarySlot);
  else if (job.kind === 'process' && Array.isArray(s.operations)) (await import('/ui/process.js')).renderProcess(job, s, summarySlot);
  else if (job.kind === 'accessibility') (await import('/ui/accessibility.js')).renderAccessibility(job, s, summarySlot);
  else app.append(el('h2', {}, 'Summary (JSON)'), el('pre', {}, JSON.stringify(s, null, 2)));
}
