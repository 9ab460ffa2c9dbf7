// millsim dashboard: the job list (/) and one job (/jobs/{id}), read through the public API
// under /v1 on this same origin. No build step; uPlot (vendored, MIT) draws the charts.
'use strict';

(function () {
  const KEY_STORE = 'millsim.apiKey';
  const KINDS = ['interpret', 'simulate', 'optimize', 'stability', 'energy', 'rotary-feed', 'identify'];
  const STATUSES = ['queued', 'running', 'succeeded', 'failed', 'cancelled'];
  const PAGE = 25;
  // A browser keeps about 6 connections per host: at most this many event streams at once,
  // the rest of the list follows by polling.
  const MAX_STREAMS = 3;
  const app = document.getElementById('app');

  // ---------- helpers ----------
  function el(tag, attrs, ...children) {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (v === null || v === undefined || v === false) continue;
      if (k === 'class') e.className = v;
      else if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
      else e.setAttribute(k, v === true ? '' : v);
    }
    for (const c of children.flat()) {
      if (c === null || c === undefined || c === false) continue;
      e.append(c instanceof Node ? c : document.createTextNode(String(c)));
    }
    return e;
  }
  const apiKey = () => sessionStorage.getItem(KEY_STORE) || '';
  function authHeaders() {
    const k = apiKey();
    return k ? { Authorization: 'Bearer ' + k } : {};
  }
  class NeedKey extends Error {}
  async function api(path, opts) {
    const res = await fetch(path, { ...(opts || {}), headers: { ...authHeaders(), ...((opts && opts.headers) || {}) } });
    if (res.status === 401) throw new NeedKey('401');
    if (!res.ok) {
      let detail = res.status + ' ' + res.statusText;
      try { const p = await res.json(); detail = p.detail || p.title || detail; } catch (_) { /* not JSON */ }
      throw new Error(detail);
    }
    return res;
  }
  const getJson = async (path) => (await api(path)).json();
  function fmt(x, digits) {
    if (x === null || x === undefined || Number.isNaN(x)) return '–';
    const d = digits === undefined ? (Math.abs(x) >= 100 ? 0 : Math.abs(x) >= 10 ? 1 : 2) : digits;
    return Number(x).toLocaleString('en-US', { minimumFractionDigits: d, maximumFractionDigits: d });
  }
  function fmtTime(s) {
    if (s === null || s === undefined) return '–';
    if (s < 60) return fmt(s, 2) + ' s';
    const m = Math.floor(s / 60);
    return m + ' min ' + fmt(s - 60 * m, 1) + ' s';
  }
  const fmtDate = (iso) => (iso ? new Date(iso).toLocaleString() : '–');
  const pct = (p) => (p && p.total > 0 ? Math.min(100, (100 * p.done) / p.total) : 0);

  // ---------- API key ----------
  function renderKeyState() {
    const box = document.getElementById('keystate');
    box.replaceChildren();
    if (apiKey()) {
      box.append('API key set ', el('button', { onclick: () => { sessionStorage.removeItem(KEY_STORE); location.reload(); } }, 'Forget'));
    }
  }
  function askForKey(again) {
    app.replaceChildren(
      el('h1', {}, 'API key'),
      el('p', {}, again ? 'The server refused that key. ' : '', 'This server requires an API key. It is kept in this tab only (sessionStorage) and sent as ',
        el('code', {}, 'Authorization: Bearer KEY'), '.'),
      el('form', {
        id: 'keyform', onsubmit: (e) => {
          e.preventDefault();
          const v = e.target.elements.key.value.trim();
          if (v) { sessionStorage.setItem(KEY_STORE, v); renderKeyState(); route(); }
        },
      }, el('input', { name: 'key', type: 'password', autocomplete: 'off', placeholder: 'ms_…', size: 60 }), ' ', el('button', { type: 'submit' }, 'Use key')),
    );
  }
  function handleError(err, where) {
    if (err instanceof NeedKey) { const had = !!apiKey(); if (had) sessionStorage.removeItem(KEY_STORE); renderKeyState(); askForKey(had); return; }
    (where || app).append(el('p', { class: 'error' }, 'Error: ' + err.message));
  }

  // ---------- event streams (fetch, so the API key header can be sent) ----------
  async function follow(id, onEvent, signal) {
    const res = await fetch('/v1/jobs/' + encodeURIComponent(id) + '/events', { headers: authHeaders(), signal });
    if (!res.ok || !res.body) return;
    const reader = res.body.pipeThrough(new TextDecoderStream()).getReader();
    let buf = '';
    for (;;) {
      const { value, done } = await reader.read();
      if (done) return;
      buf += value.replace(/\r\n/g, '\n');
      let i;
      while ((i = buf.indexOf('\n\n')) >= 0) {
        const chunk = buf.slice(0, i);
        buf = buf.slice(i + 2);
        let ev = 'message';
        const data = [];
        for (const line of chunk.split('\n')) {
          if (line.startsWith('event:')) ev = line.slice(6).trim();
          else if (line.startsWith('data:')) data.push(line.slice(5).replace(/^ /, ''));
        }
        if (data.length) {
          let parsed;
          try { parsed = JSON.parse(data.join('\n')); } catch (_) { continue; }
          onEvent(ev, parsed);
        }
      }
    }
  }

  // Program names by resource id (the job's inputs name the program resource).
  const programNames = new Map();
  async function programName(job) {
    if (job.summary && job.summary.file) return job.summary.file;
    const pid = job.inputs && job.inputs.program;
    if (typeof pid !== 'string') return '';
    if (!programNames.has(pid)) {
      programNames.set(pid, getJson('/v1/programs/' + encodeURIComponent(pid)).then((r) => r.name || '').catch(() => ''));
    }
    return programNames.get(pid);
  }

  function statusPill(s) { return el('span', { class: 'status ' + s, 'data-status': s }, s); }
  function progressBar(job) {
    const p = job.progress || { done: 0, total: 0 };
    return el('span', {},
      el('span', { class: 'bar ' + job.status }, el('div', { style: 'width:' + pct(p).toFixed(1) + '%' })),
      el('span', { class: 'pct' }, p.total > 0 ? p.done + ' / ' + p.total : ''));
  }

  // ---------- the job list ----------
  let listTimer = null;
  const streams = new Map(); // job id -> AbortController
  function stopStreams() { for (const c of streams.values()) c.abort(); streams.clear(); }

  async function renderList() {
    const q = new URLSearchParams(location.search);
    const status = q.get('status') || '';
    const kind = q.get('kind') || '';
    const cursor = q.get('cursor') || '';
    const prev = q.getAll('prev');
    const setQuery = (changes) => {
      const n = new URLSearchParams(location.search);
      for (const [k, v] of Object.entries(changes)) { n.delete(k); if (Array.isArray(v)) v.forEach((x) => n.append(k, x)); else if (v) n.set(k, v); }
      history.pushState(null, '', '/' + (n.toString() ? '?' + n : ''));
      route();
    };
    const sel = (name, values, current) => el('select', { name, onchange: (e) => setQuery({ [name]: e.target.value, cursor: '', prev: [] }) },
      el('option', { value: '' }, 'all'), values.map((v) => el('option', { value: v, selected: v === current }, v)));
    const tbody = el('tbody');
    const pager = el('div', { class: 'pager' });
    app.replaceChildren(
      el('h1', {}, 'Jobs ', el('a', { href: '/?new=1', id: 'new-job-link', class: 'small', onclick: (e) => { e.preventDefault(); history.pushState(null, '', '/?new=1'); route(); } }, '+ new job')),
      el('div', { class: 'toolbar' }, el('label', {}, 'Status ', sel('status', STATUSES, status)), el('label', {}, 'Kind ', sel('kind', KINDS, kind)),
        el('span', { class: 'muted', id: 'live' }, '')),
      el('table', { class: 'jobs' }, el('thead', {}, el('tr', {}, ['Status', 'Kind', 'Program', 'Created', 'Progress', 'Duration'].map((h) => el('th', {}, h)))), tbody),
      pager,
    );
    const params = new URLSearchParams({ limit: String(PAGE) });
    if (status) params.set('status', status);
    if (kind) params.set('kind', kind);
    if (cursor) params.set('cursor', cursor);

    const rows = new Map(); // id -> tr
    const latest = new Map(); // id -> the last progress event of its stream
    function fillRow(tr, job) {
      tr.dataset.status = job.status;
      tr.replaceChildren(
        el('td', {}, statusPill(job.status)),
        el('td', {}, job.kind),
        el('td', { class: 'prog' }, el('a', { href: '/jobs/' + job.id }, tr.dataset.prog || job.id.slice(0, 8) + '…')),
        el('td', {}, fmtDate(job.created_at)),
        el('td', {}, progressBar(job)),
        el('td', {}, job.duration_seconds !== null && job.duration_seconds !== undefined ? fmt(job.duration_seconds, 2) + ' s' : ''),
      );
    }
    function startStream(job) {
      if (streams.has(job.id) || streams.size >= MAX_STREAMS) return;
      const ctl = new AbortController();
      streams.set(job.id, ctl);
      follow(job.id, (ev, data) => {
        const tr = rows.get(job.id);
        if (!tr) return;
        if (ev === 'progress') {
          latest.set(job.id, data);
          fillRow(tr, { ...job, status: data.status, progress: { done: data.done, total: data.total } });
        } else if (ev === 'status') { latest.delete(job.id); Object.assign(job, data); fillRow(tr, data); }
      }, ctl.signal).catch(() => {}).finally(() => { if (streams.get(job.id) === ctl) streams.delete(job.id); });
    }
    async function load() {
      let page;
      try { page = await getJson('/v1/jobs?' + params); } catch (e) {
        stopStreams();
        if (listTimer) { clearInterval(listTimer); listTimer = null; }
        handleError(e);
        return false;
      }
      const ids = new Set(page.items.map((j) => j.id));
      for (const [id, c] of streams) if (!ids.has(id)) { c.abort(); streams.delete(id); }
      const order = [];
      for (const job of page.items) {
        let tr = rows.get(job.id);
        if (!tr) { tr = el('tr', { 'data-id': job.id }); rows.set(job.id, tr); programName(job).then((n) => { if (n) { tr.dataset.prog = n; const a = tr.querySelector('td.prog a'); if (a) a.textContent = n; } }); }
        // A row's event stream may be ahead of the list's copy: the further progress is kept.
        const live = latest.get(job.id);
        if (live && (job.status === 'queued' || job.status === 'running') && live.done >= (job.progress ? job.progress.done : 0)) {
          fillRow(tr, { ...job, status: live.status, progress: { done: live.done, total: live.total } });
        } else fillRow(tr, job);
        if (job.status === 'queued' || job.status === 'running') startStream(job);
        order.push(tr);
      }
      for (const id of [...rows.keys()]) if (!ids.has(id)) rows.delete(id);
      tbody.replaceChildren(...order);
      if (!order.length) tbody.append(el('tr', {}, el('td', { colspan: 6, class: 'muted' }, 'No jobs' + (status || kind ? ' match these filters.' : ' yet.'))));
      pager.replaceChildren(...[
        prev.length || cursor ? el('button', { onclick: () => setQuery({ cursor: prev[prev.length - 1] || '', prev: prev.slice(0, -1) }) }, '← Newer') : null,
        page.next_cursor ? el('button', { onclick: () => setQuery({ cursor: page.next_cursor, prev: [...prev, cursor] }) }, 'Older →') : null,
        el('span', { class: 'muted' }, page.items.length + ' job(s) on this page'),
      ].filter(Boolean));
      document.getElementById('live').textContent = cursor ? '' : 'updates live';
      return true;
    }
    if (!(await load())) return;
    // The first page picks up new jobs (and jobs beyond the streamed ones) by polling.
    if (!cursor) listTimer = setInterval(() => { load(); }, 2000);
  }

  // ---------- one job ----------
  function card(k, v, n, cls) { return el('div', { class: 'card ' + (cls || ''), 'data-card': k }, el('div', { class: 'k' }, k), el('div', { class: 'v' }, v), n ? el('div', { class: 'n' }, n) : null); }

  function problemView(p) {
    const dl = el('dl');
    const add = (k, v) => { if (v !== undefined && v !== null && v !== '') dl.append(el('dt', {}, k), el('dd', { 'data-field': k }, typeof v === 'object' ? JSON.stringify(v) : String(v))); };
    add('title', p.title); add('detail', p.detail); add('file', p.file); add('line', p.line); add('column', p.column);
    for (const [k, v] of Object.entries(p)) if (!['type', 'title', 'status', 'detail', 'file', 'line', 'column', 'errors'].includes(k)) add(k, v);
    const errs = Array.isArray(p.errors) ? el('table', { class: 'jobs' }, el('thead', {}, el('tr', {}, ['File', 'Line', 'Column', 'What is wrong'].map((h) => el('th', {}, h)))),
      el('tbody', {}, p.errors.map((e) => el('tr', {}, el('td', {}, e.file || p.file || ''), el('td', {}, e.line ?? ''), el('td', {}, e.column ?? ''), el('td', {}, e.message || e.detail || JSON.stringify(e)))))) : null;
    return el('div', { class: 'problem', id: 'problem' }, el('div', { class: 'muted' }, p.type || ''), dl, errs);
  }

  async function fetchRows(id, onPage) {
    const rows = [];
    let cursor = '';
    for (;;) {
      const q = new URLSearchParams({ limit: '1000' });
      if (cursor) q.set('cursor', cursor);
      const page = await getJson('/v1/jobs/' + encodeURIComponent(id) + '/blocks?' + q);
      rows.push(...page.items);
      if (onPage) onPage(rows.length);
      if (!page.next_cursor) return rows;
      cursor = page.next_cursor;
    }
  }

  function makePlot(container, title, rows, series, opts) {
    const box = el('div', { class: 'plot', 'data-plot': title });
    const hover = el('div', { class: 'hover' }, 'hover a point: block, line, N');
    box.append(el('div', { class: 'title' }, title));
    container.append(box);
    const x = Float64Array.from(rows, (r) => r.block);
    const data = [x, ...series.map((s) => s.values)];
    const width = Math.max(320, box.clientWidth - 20);
    const u = new uPlot({
      width, height: 260,
      cursor: { drag: { x: true, y: false } },
      scales: { x: { time: false } },
      axes: [{ label: 'block' }, { label: opts.unit, size: 70 }],
      series: [{ label: 'block' }, ...series.map((s) => ({ label: s.label, stroke: s.color, width: s.width || 1, dash: s.dash, points: { show: false } }))],
      hooks: {
        setCursor: [(u) => {
          const i = u.cursor.idx;
          if (i === null || i === undefined) return;
          const r = rows[i];
          hover.replaceChildren('block ' + r.block + ' · line ' + r.line + ' · N ' + (r.n ?? '–') + ' · ' + r.kind + ' · ' +
            series.filter((s) => !s.constant).map((s) => s.label + ' ' + fmt(s.values[i], 1) + ' ' + opts.unit).join(' · '),
            opts.source && opts.source[r.line - 1] !== undefined ? el('div', { class: 'src' }, r.line + ': ' + opts.source[r.line - 1]) : '');
        }],
        ...(opts.hooks || {}),
      },
    }, data, box);
    box.append(hover);
    if (opts.onClick) u.over.addEventListener('click', () => { const i = u.cursor.idx; if (i !== null && i !== undefined) opts.onClick(rows[i], i); });
    return u;
  }

  async function renderJob(id) {
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
      const bar = el('div', { id: 'jobprogress' }, progressBar(job));
      app.append(bar);
      const ctl = new AbortController();
      follow(job.id, (ev, data) => {
        if (ev === 'progress') bar.replaceChildren(progressBar({ ...job, status: data.status, progress: { done: data.done, total: data.total } }));
        else if (ev === 'status') { ctl.abort(); renderJob(id); }
      }, ctl.signal).catch(() => {});
      return;
    }
    if (job.status === 'failed' && job.error) {
      app.append(el('h2', {}, 'Problem'), problemView(job.error));
      return;
    }
    if (job.status !== 'succeeded') { app.append(el('p', { class: 'muted' }, 'The job was ' + job.status + '.')); return; }

    const base = '/v1/jobs/' + encodeURIComponent(job.id);
    const s = job.summary || {};
    const opt = s.optimization || null;
    const hasRows = Array.isArray(s.row_columns) && s.row_columns.includes('force_peak_n');
    const downloads = el('div', { class: 'downloads', id: 'downloads' });
    const dl = (label, href, file) => el('a', { href, download: file || '', 'data-download': label,
      onclick: async (e) => {
        if (!apiKey()) return; // a plain link: the browser downloads it
        e.preventDefault();
        try { const b = await (await api(href)).blob(); const u = URL.createObjectURL(b); const a = el('a', { href: u, download: file || '' }); a.click(); setTimeout(() => URL.revokeObjectURL(u), 10000); } catch (err) { handleError(err, downloads); }
      } }, label);
    if (job.kind === 'optimize' || job.kind === 'rotary-feed') downloads.append(dl('Optimized program', base + '/program'));
    downloads.append(dl('Rows (CSV)', base + '/blocks?format=csv', 'job-' + job.id + '.csv'));
    if (job.kind === 'simulate' || job.kind === 'optimize') downloads.append(dl('Stock after machining (STL)', base + '/stock.stl', 'stock-' + job.id + '.stl'));
    downloads.append(dl('Summary (JSON)', base + '/summary', 'summary-' + job.id + '.json'));

    if (s.cycle_time_s !== undefined) {
      const cards = el('div', { class: 'cards', id: 'cards' });
      if (opt) {
        cards.append(card('Cycle time before', fmtTime(opt.cycle_time_before_s)));
        cards.append(card('Cycle time after', fmtTime(opt.cycle_time_after_s), opt.cycle_time_before_s > 0 ? fmt(100 * (1 - opt.cycle_time_after_s / opt.cycle_time_before_s), 1) + ' % shorter' : null));
        cards.append(card('At best constant feed', fmtTime(opt.cycle_time_constant_feed_s), 'F ' + fmt(opt.best_constant_feed_mm_min, 0) + ' mm/min'));
        cards.append(card('Ideal bound', fmtTime(opt.cycle_time_ideal_s)));
      } else {
        cards.append(card('Cycle time', fmtTime(s.cycle_time_s)));
      }
      cards.append(card(opt ? 'Peak force before' : 'Peak force', fmt(s.force_peak_n, 1) + ' N', s.force_peak_line != null ? 'line ' + s.force_peak_line : null));
      if (opt) cards.append(card('Peak force after', fmt(opt.peak_force_after, 1) + ' N', opt.limits && opt.limits.max_force != null ? 'limit ' + fmt(opt.limits.max_force, 0) + ' N' : null));
      cards.append(card('Removed volume', fmt(s.removed_volume_mm3, 0) + ' mm³'));
      cards.append(card('Air time', fmtTime(s.air_time_s), s.air_moves != null ? s.air_moves + ' air moves' : null));
      const ncoll = Array.isArray(s.collisions) ? s.collisions.length : 0;
      cards.append(card('Collisions', String(ncoll), null, ncoll ? 'bad' : ''));
      const warn = [];
      if (s.rapid_in_material_moves) warn.push(s.rapid_in_material_moves + ' rapid in material');
      if (s.holder_or_shank_contact_moves) warn.push(s.holder_or_shank_contact_moves + ' shank/holder contact');
      if (s.flute_length_exceeded_moves) warn.push(s.flute_length_exceeded_moves + ' flute length exceeded');
      if (Array.isArray(s.tool_warnings) && s.tool_warnings.length) warn.push(s.tool_warnings.length + ' tool warning(s)');
      if (opt && opt.force_limit_unreachable_moves) warn.push(opt.force_limit_unreachable_moves + ' moves cannot reach the force limit');
      cards.append(card('Warnings', String(warn.length), warn.join('; ') || 'none', warn.length ? 'bad' : ''));
      if (s.cutting_energy_j != null) cards.append(card('Cutting energy', fmt(s.cutting_energy_j / 1000, 2) + ' kJ'));
      app.append(el('h2', {}, 'Summary'), cards);
    }
    const summarySlot = el('div');
    app.append(summarySlot, el('h2', {}, 'Downloads'), downloads);

    if (s.collisions && s.collisions.length) {
      app.append(el('h2', {}, 'Collisions'), el('table', { class: 'jobs', id: 'collisions' },
        el('thead', {}, el('tr', {}, ['Block', 'Line', 'Kind'].map((h) => el('th', {}, h)))),
        el('tbody', {}, s.collisions.map((c) => el('tr', {}, el('td', {}, c.block), el('td', {}, c.line), el('td', {}, c.kind))))));
    }
    if (job.kind === 'simulate' || job.kind === 'optimize') {
      // The machined stock in 3-D: loaded on request (the STL can be tens of MB).
      const view = el('div', { id: 'stock3d' });
      const partId = job.inputs && typeof job.inputs.part === 'string' ? job.inputs.part : null;
      const button = el('button', { id: 'load-stock', onclick: async () => {
        button.disabled = true;
        view.replaceChildren(el('p', { class: 'muted' }, 'loading the stock…'));
        try {
          const [mod, stl, part] = await Promise.all([
            import('/ui/stock3d.js'),
            api(base + '/stock.stl').then((r) => r.arrayBuffer()),
            partId ? api('/v1/stocks/' + encodeURIComponent(partId) + '/content').then((r) => r.arrayBuffer()) : Promise.resolve(null),
          ]);
          view.replaceChildren();
          const v = mod.showStock(view, stl, part);
          view.append(el('p', { class: 'muted', id: 'stockinfo' }, v.triangles.toLocaleString('en-US') + ' triangles · ' + v.size.map((x) => fmt(x, 1)).join(' × ') + ' mm · drag to orbit, wheel to zoom, right-drag to pan',
            part ? el('label', {}, ' · ', el('input', { type: 'checkbox', checked: true, onchange: (e) => v.setPartVisible(e.target.checked) }), ' design part (green)') : ''));
        } catch (e) { view.replaceChildren(); handleError(e, view); }
      } }, 'Show the machined stock in 3-D');
      app.append(el('h2', {}, 'Stock after machining'), button, view);
    }
    if (hasRows) {
      const plots = el('div', { id: 'plots' });
      const status = el('p', { class: 'muted', id: 'rowstatus' }, 'loading rows…');
      app.append(el('h2', {}, 'Per block'), status, plots);
      // The program's source (for the hover and the program view) loads while the rows do.
      const pid = job.inputs && job.inputs.program;
      const sourceP = typeof pid === 'string' ? api('/v1/programs/' + encodeURIComponent(pid) + '/content').then((r) => r.text()).then((t) => t.split(/\r?\n/)) : Promise.resolve(null);
      sourceP.catch(() => {});
      let rows;
      try { rows = await fetchRows(job.id, (n) => { status.textContent = 'loading rows… ' + n; }); } catch (e) { handleError(e, plots); return; }
      status.textContent = rows.length + ' rows · drag to zoom, double-click to reset';
      if (opt && rows.length) {
        // The summary names the line of the peak before; the line of the peak after is read from the rows.
        let best = rows[0];
        for (const r of rows) if ((r.force_peak_opt_n || 0) > (best.force_peak_opt_n || 0)) best = r;
        const n = document.querySelector('[data-card="Peak force after"] .n');
        if (n) n.textContent = 'line ' + best.line + (opt.limits && opt.limits.max_force != null ? ' · limit ' + fmt(opt.limits.max_force, 0) + ' N' : '');
      }
      const limit = opt && opt.limits ? opt.limits.max_force : null;
      const forceSeries = [
        { label: 'peak |F| before', values: Float64Array.from(rows, (r) => r.force_peak_n), color: '#c62828' },
        { label: 'mean |F| before', values: Float64Array.from(rows, (r) => r.force_mean_n), color: '#f39c9c' },
      ];
      if (opt) forceSeries.push({ label: 'peak |F| after', values: Float64Array.from(rows, (r) => r.force_peak_opt_n), color: '#2463eb' });
      if (limit != null) forceSeries.push({ label: 'limit', values: Float64Array.from(rows, () => limit), color: '#444', dash: [6, 4], constant: true });
      // The source, for the hover and the program view (the original program's stored content).
      let source = null;
      try { source = await sourceP; } catch (e) { if (e instanceof NeedKey) { handleError(e); return; } }
      let programView = null;
      const goToLine = (r) => { if (programView) programView.show(r.line); };
      const samplesBox = el('div', { id: 'samples' });
      const forcePlot = makePlot(plots, 'Cutting force', rows, forceSeries, { unit: 'N', source, onClick: goToLine,
        hooks: { setScale: [(u, key) => { if (key === 'x') samplesBox.dispatchEvent(new CustomEvent('range', { detail: [u.scales.x.min, u.scales.x.max] })); }] } });
      plots.append(samplesBox);
      setUpSamples(samplesBox, base, rows, forcePlot);
      timePlot(plots, rows, opt, limit, source, goToLine);
      const feedSeries = [{ label: 'feed before', values: Float64Array.from(rows, (r) => r.feed_mm_min), color: '#7a5c00' }];
      if (opt) feedSeries.push({ label: 'feed after', values: Float64Array.from(rows, (r) => r.feed_opt_mm_min), color: '#18794e' });
      makePlot(plots, 'Feed', rows, feedSeries, { unit: 'mm/min', source, onClick: goToLine });
      makePlot(plots, 'Material removal rate', rows, [{ label: 'MRR', values: Float64Array.from(rows, (r) => r.mrr_mm3_s), color: '#6a1b9a' }], { unit: 'mm³/s', source, onClick: goToLine });
      makePlot(plots, 'Spindle power', rows, [
        { label: 'peak power', values: Float64Array.from(rows, (r) => r.power_peak_w), color: '#ef6c00' },
        { label: 'mean power', values: Float64Array.from(rows, (r) => r.power_mean_w), color: '#ffb74d' },
      ], { unit: 'W', source, onClick: goToLine });
      makePlot(plots, 'Torque', rows, [{ label: 'peak torque', values: Float64Array.from(rows, (r) => r.torque_peak_nm), color: '#00838f' }], { unit: 'N·m', source, onClick: goToLine });
      if (rows.some((r) => r.chatter_margin !== null && r.chatter_margin !== undefined)) {
        makePlot(plots, 'Chatter margin', rows, [
          { label: 'axial depth / critical depth', values: rows.map((r) => r.chatter_margin ?? null), color: '#ad1457' },
          { label: 'stability limit', values: Float64Array.from(rows, () => 1), color: '#444', dash: [6, 4], constant: true },
        ], { unit: '', source, onClick: goToLine });
      }
      performance.mark('plots-drawn');
      if (source && (job.kind === 'optimize')) {
        const view = el('div', { id: 'programs' });
        app.append(el('h2', {}, 'Program and optimized program'), view);
        try {
          const optimized = (await (await api(base + '/program')).text()).split(/\r?\n/);
          programView = programDiff(view, source, optimized);
        } catch (e) { handleError(e, view); }
      }
    } else if (job.kind === 'stability' && Array.isArray(s.row_columns)) {
      await renderStability(job, s, summarySlot);
    } else if (job.kind === 'energy' && Array.isArray(s.pareto)) {
      renderEnergy(s, summarySlot);
    } else if (job.summary) {
      app.append(el('h2', {}, 'Summary (JSON)'), el('pre', {}, JSON.stringify(job.summary, null, 2)));
    }
  }



  // ---------- peak force against cycle time (before, and after where optimized) ----------
  function timePlot(container, rows, opt, limit, source, goToLine) {
    const cumulative = (key) => { let t = 0; return Float64Array.from(rows, (r) => (t += r[key] || 0)); };
    const tb = cumulative('time_s');
    const tables = [[tb, Float64Array.from(rows, (r) => r.force_peak_n)]];
    const ta = opt ? cumulative('time_opt_s') : null;
    if (ta) tables.push([ta, Float64Array.from(rows, (r) => r.force_peak_opt_n)]);
    // One x (time) for both: uPlot.join aligns the two traces, leaving gaps where one has no point.
    const data = uPlot.join(tables);
    const series = [{ label: 'peak |F| before', color: '#c62828', spanGaps: true }];
    if (ta) series.push({ label: 'peak |F| after', color: '#2463eb', spanGaps: true });
    if (limit != null) { data.push(Array.from(data[0], () => limit)); series.push({ label: 'limit', color: '#444', dash: [6, 4] }); }
    // The row running at time x: the first whose end time is at or after it.
    const rowAt = (ends, x) => { let lo = 0; let hi = ends.length - 1; while (lo < hi) { const mid = (lo + hi) >> 1; if (ends[mid] < x) lo = mid + 1; else hi = mid; } return rows[lo]; };
    const title = 'Peak force against cycle time' + (ta ? ' (before: ' + fmtTime(tb[tb.length - 1]) + ', after: ' + fmtTime(ta[ta.length - 1]) + ')' : '');
    const box = el('div', { class: 'plot', 'data-plot': 'Force against time' }, el('div', { class: 'title' }, title));
    const hover = el('div', { class: 'hover' }, 'hover: the block running at that time, before and after');
    container.append(box);
    const u = new uPlot({
      width: Math.max(320, box.clientWidth - 20), height: 260,
      cursor: { drag: { x: true, y: false } },
      scales: { x: { time: false } },
      axes: [{ label: 'cycle time (s)' }, { label: 'N', size: 70 }],
      series: [{ label: 's' }, ...series.map((x) => ({ label: x.label, stroke: x.color, dash: x.dash, spanGaps: !!x.spanGaps, points: { show: false } }))],
      hooks: { setCursor: [(u) => {
        const i = u.cursor.idx;
        if (i === null || i === undefined) return;
        const x = u.data[0][i];
        const b = rowAt(tb, x);
        const parts = ['t ' + fmt(x, 2) + ' s', 'before: block ' + b.block + ' line ' + b.line + ' ' + fmt(b.force_peak_n, 1) + ' N'];
        if (ta) { const a = rowAt(ta, x); parts.push('after: block ' + a.block + ' line ' + a.line + ' ' + fmt(a.force_peak_opt_n, 1) + ' N'); }
        hover.replaceChildren(parts.join(' · '), source && source[b.line - 1] !== undefined ? el('div', { class: 'src' }, b.line + ': ' + source[b.line - 1]) : '');
      }] },
    }, data, box);
    u.over.addEventListener('click', () => { const i = u.cursor.idx; if (i !== null && i !== undefined) goToLine(rowAt(tb, u.data[0][i])); });
    box.append(hover);
  }

  // ---------- per-step samples of the blocks in view ----------
  const MAX_SAMPLE_ROWS = 400;
  function setUpSamples(box, base, rows, forcePlot) {
    const info = el('span', { class: 'muted' });
    const button = el('button', { id: 'load-samples' }, 'Per-step samples of the blocks in view');
    const holder = el('div');
    box.append(el('div', { class: 'toolbar' }, button, info), holder);
    let range = [0, rows.length - 1];
    const rowRange = (xmin, xmax) => {
      // x is the block number; rows are in block order.
      let a = rows.findIndex((r) => r.block >= xmin);
      let b = rows.length - 1;
      while (b > 0 && rows[b].block > xmax) b--;
      if (a < 0) a = rows.length - 1;
      return [a, Math.max(a, b)];
    };
    const update = () => {
      const n = range[1] - range[0] + 1;
      button.disabled = n > MAX_SAMPLE_ROWS;
      info.textContent = n > MAX_SAMPLE_ROWS ? n + ' rows in view: zoom the force plot to at most ' + MAX_SAMPLE_ROWS : 'rows ' + range[0] + '–' + range[1] + ' (blocks ' + rows[range[0]].block + '–' + rows[range[1]].block + ')';
    };
    box.addEventListener('range', (e) => { range = rowRange(e.detail[0], e.detail[1]); update(); });
    update();
    button.addEventListener('click', async () => {
      const [a, b] = range;
      holder.replaceChildren(el('p', { class: 'muted' }, 'loading samples…'));
      let page;
      try { page = await getJson(base + '/blocks/' + a + '-' + b + '/samples'); } catch (e) { holder.replaceChildren(); handleError(e, holder); return; }
      const pts = [];
      for (const item of page.items) {
        const r = rows[item.row];
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
  }


  // ---------- stability lobes and the energy Pareto front ----------
  function xyPlot(container, title, xLabel, yLabel, x, series, describe) {
    const box = el('div', { class: 'plot', 'data-plot': title }, el('div', { class: 'title' }, title));
    const hover = el('div', { class: 'hover' }, 'hover a point');
    container.append(box);
    new uPlot({
      width: Math.max(320, box.clientWidth - 20), height: 320,
      cursor: { drag: { x: true, y: true, uni: 20 } },
      scales: { x: { time: false } },
      axes: [{ label: xLabel }, { label: yLabel, size: 70 }],
      series: [{ label: xLabel }, ...series.map((s) => ({ label: s.label, stroke: s.color, width: s.width || 1.5, spanGaps: !!s.spanGaps,
        points: s.pointsOnly ? { show: true, size: 10, fill: s.color } : { show: false }, paths: s.pointsOnly ? () => null : undefined }))],
      hooks: { setCursor: [(u) => { const i = u.cursor.idx; if (i !== null && i !== undefined) hover.textContent = describe(i); }] },
    }, [x, ...series.map((s) => s.values)], box);
    box.append(hover);
  }

  async function renderStability(job, s, summarySlot) {
    const cards = el('div', { class: 'cards', id: 'cards' });
    if (s.minimum) cards.append(card('Smallest critical depth', fmt(s.minimum.depth_mm, 3) + ' mm', 'at ' + fmt(s.minimum.rpm, 0) + ' rpm'));
    const rec = s.recommendation;
    if (rec) cards.append(card('Recommended speed', fmt(rec.rpm, 0) + ' rpm', 'stable to ' + fmt(rec.stable_depth_mm, 3) + ' mm; pocket ' + fmt(rec.pocket_from_rpm, 0) + '–' + fmt(rec.pocket_to_rpm, 0) + ' rpm'));
    cards.append(card('Speeds', String(s.speeds ?? '–'), s.method ? 'method ' + s.method : null));
    summarySlot.append(el('h2', {}, 'Summary'), cards);
    const plots = el('div', { id: 'plots' });
    app.append(el('h2', {}, 'Stability lobes'), plots);
    let rows;
    try { rows = await fetchRows(job.id); } catch (e) { handleError(e, plots); return; }
    const palette = ['#2463eb', '#c62828', '#18794e', '#ef6c00', '#6a1b9a', '#00838f', '#ad1457', '#5d4037'];
    const rpms = [...new Set(rows.map((r) => r.rpm))].sort((a, b) => a - b);
    const at = new Map(rpms.map((r, i) => [r, i]));
    const groups = new Map();
    for (const r of rows) {
      const g = r.allowance_mm === undefined ? 'critical depth' : 'allowance ' + fmt(r.allowance_mm, 2) + ' mm';
      if (!groups.has(g)) groups.set(g, rpms.map(() => null));
      groups.get(g)[at.get(r.rpm)] = r.depth_mm;
    }
    const series = [...groups].map(([label, values], k) => ({ label, values, color: palette[k % palette.length], spanGaps: true }));
    if (rec) series.push({ label: 'recommended', values: rpms.map((r) => (r === rec.rpm ? rec.stable_depth_mm : null)), color: '#111', pointsOnly: true });
    xyPlot(plots, 'Critical axial depth against spindle speed', 'rpm', 'mm', Float64Array.from(rpms), series,
      (i) => fmt(rpms[i], 0) + ' rpm · ' + series.filter((x) => x.values[i] !== null).map((x) => x.label + ' ' + fmt(x.values[i], 3) + ' mm').join(' · '));
    if (groups.size > 1) plots.append(el('p', { class: 'muted' }, 'One lobe line per allowance (the 3-D lobe surface is not drawn yet).'));
  }

  function renderEnergy(s, summarySlot) {
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

  // ---------- the program beside the optimized program ----------
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
  function programDiff(view, orig, opt) {
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


  // ---------- a new simulate/optimize job ----------
  function renderNewJob() {
    const num = (name, value, attrs) => el('input', { name, type: 'number', step: 'any', value, ...(attrs || {}) });
    const field = (label, ...input) => el('label', { class: 'field' }, el('span', {}, label), ...input);
    const out = el('div', { id: 'form-result' });
    const form = el('form', { id: 'new-job', class: 'newjob' },
      el('fieldset', {}, el('legend', {}, 'Job'),
        field('Kind', el('select', { name: 'kind' }, el('option', { value: 'optimize' }, 'optimize (simulate, then schedule the feeds)'), el('option', { value: 'simulate' }, 'simulate'))),
        field('NC program', el('input', { name: 'program', type: 'file', required: true }))),
      el('fieldset', {}, el('legend', {}, 'Stock'),
        field('STL file (optional)', el('input', { name: 'stock_stl', type: 'file', accept: '.stl' })),
        el('div', { class: 'muted' }, 'or a block, min and max corners in mm:'),
        el('div', { class: 'row' }, 'min', num('min_x', 0), num('min_y', 0), num('min_z', -20), 'max', num('max_x', 100), num('max_y', 80), num('max_z', 0))),
      el('fieldset', {}, el('legend', {}, 'Tool (every tool number of the program)'),
        field('Type', el('select', { name: 'tool_type' }, ['flat', 'ball', 'bull', 'chamfer'].map((t) => el('option', { value: t }, t)))),
        field('Diameter mm', num('diameter_mm', 10)), field('Corner radius mm (bull)', num('corner_radius_mm', 1)),
        field('Flutes', num('flutes', 4, { step: 1 })), field('Helix °', num('helix_deg', 30)), field('Flute length mm', num('flute_length_mm', 25))),
      el('fieldset', {}, el('legend', {}, 'Material and machine'),
        field('Material', el('select', { name: 'material' }, ['Al7075-T6', 'Al6082-T6', 'TC6'].map((m) => el('option', { value: m }, m)))),
        field('Machine JSON (optional)', el('input', { name: 'machine', type: 'file', accept: '.json' }))),
      el('fieldset', {}, el('legend', {}, 'Limits (optimize)'),
        field('Max force N', num('max_force', 400)), field('Air feed mm/min', num('air_feed', 5000)), field('Max feed mm/min (optional)', num('max_feed', ''))),
      el('button', { type: 'submit' }, 'Submit'), ' ', el('a', { href: '/' }, 'cancel'), out);
    form.addEventListener('submit', async (e) => {
      e.preventDefault();
      const f = form.elements;
      out.replaceChildren(el('p', { class: 'muted' }, 'uploading…'));
      const post = async (path, body, type) => (await apiProblem(path, { method: 'POST', headers: { 'content-type': type }, body })).json();
      try {
        const prog = f.program.files[0];
        const program = await post('/v1/programs?name=' + encodeURIComponent(prog.name), await prog.arrayBuffer(), 'text/plain');
        const stl = f.stock_stl.files[0];
        const stock = stl ? await post('/v1/stocks?name=' + encodeURIComponent(stl.name), await stl.arrayBuffer(), 'application/octet-stream')
          : await post('/v1/stocks', JSON.stringify({ kind: 'block', min: [+f.min_x.value, +f.min_y.value, +f.min_z.value], max: [+f.max_x.value, +f.max_y.value, +f.max_z.value] }), 'application/json');
        const t = { type: f.tool_type.value, diameter_mm: +f.diameter_mm.value, flutes: +f.flutes.value, helix_deg: +f.helix_deg.value, flute_length_mm: +f.flute_length_mm.value };
        if (t.type === 'bull') t.corner_radius_mm = +f.corner_radius_mm.value;
        const tool = await post('/v1/tools', JSON.stringify(t), 'application/json');
        const inputs = { program: program.id, stock: stock.id, tool: tool.id };
        const mfile = f.machine.files[0];
        if (mfile) inputs.machine = (await post('/v1/machines?name=' + encodeURIComponent(mfile.name), await mfile.arrayBuffer(), 'application/json')).id;
        const options = { material: f.material.value };
        if (f.kind.value === 'optimize') {
          options.limits = {};
          for (const k of ['max_force', 'air_feed', 'max_feed']) if (f[k].value !== '') options.limits[k] = +f[k].value;
        }
        const job = await post('/v1/jobs', JSON.stringify({ kind: f.kind.value, inputs, options }), 'application/json');
        history.pushState(null, '', '/jobs/' + job.id);
        route();
      } catch (err) {
        out.replaceChildren();
        if (err.problem) out.append(el('h2', {}, 'The server refused it'), problemView(err.problem));
        else handleError(err, out);
      }
    });
    app.replaceChildren(el('div', {}, el('a', { href: '/' }, '← all jobs')), el('h1', {}, 'New job'), form);
  }
  // Like api(), but a refusal keeps its problem document (file, line, column) for the form.
  async function apiProblem(path, opts) {
    const res = await fetch(path, { ...opts, headers: { ...authHeaders(), ...(opts.headers || {}) } });
    if (res.status === 401) throw new NeedKey('401');
    if (!res.ok) {
      let p = null;
      try { p = await res.json(); } catch (_) { /* not JSON */ }
      const err = new Error((p && (p.detail || p.title)) || res.status + ' ' + res.statusText);
      err.problem = p;
      throw err;
    }
    return res;
  }

  // ---------- routing ----------
  function route() {
    if (listTimer) { clearInterval(listTimer); listTimer = null; }
    stopStreams();
    renderKeyState();
    const m = location.pathname.match(/^\/jobs\/([^/]+)$/);
    if (m) renderJob(decodeURIComponent(m[1]));
    else if (new URLSearchParams(location.search).get('new')) renderNewJob();
    else renderList();
  }
  window.addEventListener('popstate', route);
  route();
})();
