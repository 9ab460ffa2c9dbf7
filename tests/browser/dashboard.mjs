// Browser test of the dashboard: Debian's chromium driven by playwright-core (never a
// downloaded browser) against the real `millsim serve` on 127.0.0.1:0 with a temporary
// SQLite database. Run by tests/dashboard_browser.rs (`cargo test --workspace`), or alone:
//   MILLSIM_BIN=target/debug/millsim node tests/browser/dashboard.mjs
// Screenshots go to tests/browser/artifacts/.
import { spawn, execFileSync } from 'node:child_process';
import { mkdtempSync, mkdirSync, writeFileSync, readFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, dirname } from 'node:path';
import { fileURLToPath } from 'node:url';
import { createInterface } from 'node:readline';
import assert from 'node:assert/strict';
import { chromium } from 'playwright-core';

const here = dirname(fileURLToPath(import.meta.url));
const root = join(here, '..', '..');
const BIN = process.env.MILLSIM_BIN || join(root, 'target', 'debug', 'millsim');
const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';
const ARTIFACTS = join(here, 'artifacts');
mkdirSync(ARTIFACTS, { recursive: true });
const work = mkdtempSync(join(tmpdir(), 'millsim-dash-'));
const children = [];

function log(...a) { console.log('[dashboard]', ...a); }

function spawnMillsim(args) {
  const child = spawn(BIN, args, { stdio: ['ignore', 'pipe', 'inherit'], env: { ...process.env, RUST_LOG: 'warn' } });
  children.push(child);
  return child;
}

async function startServer(name, extra) {
  const child = spawnMillsim(['serve', '--bind', '127.0.0.1:0', '--database', dbUrl(name), ...extra]);
  const rl = createInterface({ input: child.stdout });
  const line = await new Promise((resolve, reject) => {
    rl.once('line', resolve);
    child.once('exit', (c) => reject(new Error('millsim serve exited ' + c)));
  });
  const m = line.match(/^millsim listening on (http:\/\/\S+)$/);
  assert.ok(m, 'unexpected first line: ' + line);
  return m[1];
}
const dbUrl = (name) => `sqlite://${join(work, name + '.db')}`;

async function api(base, path, body, headers) {
  const raw = body instanceof Uint8Array || typeof body === 'string';
  const res = await fetch(base + path, {
    method: body === undefined ? 'GET' : 'POST',
    headers: { 'content-type': 'application/json', ...(headers || {}) },
    body: body === undefined ? undefined : raw ? body : JSON.stringify(body),
  });
  const text = await res.text();
  assert.ok(res.ok, `${path}: ${res.status} ${text}`);
  return JSON.parse(text);
}

// A zigzag facing program long enough that its progress is seen moving.
function zigzag(passes) {
  const l = ['(dashboard test zigzag)', 'G21 G90 G17', 'T1 M6', 'S12000 M3', 'G0 X-6 Y0 Z5', 'G1 Z-1.5 F600'];
  for (let i = 0; i < passes; i++) {
    const y = (i * 4).toFixed(1);
    l.push(`G1 Y${y} F${800 + (i % 5) * 200}`, `G1 X${i % 2 === 0 ? 66 : -6}`);
  }
  l.push('G0 Z5', 'M30');
  return l.join('\n') + '\n';
}

async function submit(base, headers, kind, programName, program, options) {
  const stock = await api(base, '/v1/stocks', { kind: 'block', min: [0, 0, -10], max: [60, 80, 0] }, headers);
  const tool = await api(base, '/v1/tools', { type: 'flat', diameter_mm: 8, flutes: 3, helix_deg: 35, flute_length_mm: 20 }, headers);
  return api(base, '/v1/jobs', { kind, inputs: { program: { name: programName, content: program }, stock: stock.id, tool: tool.id }, options }, headers);
}

const fmt = (x, d) => Number(x).toLocaleString('en-US', { minimumFractionDigits: d, maximumFractionDigits: d });

async function canvasInk(page, selector) {
  return page.$$eval(selector, (canvases) => canvases.map((c) => {
    const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    let ink = 0;
    for (let i = 3; i < d.length; i += 4) if (d[i] > 0) ink++;
    return ink;
  }));
}

async function main() {
  // No workers in the server: the job waits queued until the test starts a worker process
  // on the same database, so the page is seen following it from queued to succeeded.
  const base = await startServer('open', ['--workers', '0']);
  log('server', base);
  const browser = await chromium.launch({ executablePath: CHROMIUM, args: ['--no-sandbox', '--disable-background-networking'] });
  const context = await browser.newContext({ viewport: { width: 1300, height: 900 } });
  const page = await context.newPage();
  const consoleErrors = [];
  const foreign = [];
  page.on('console', (m) => { if (m.type() === 'error') consoleErrors.push(m.text() + ' at ' + (m.location().url || '?')); });
  page.on('pageerror', (e) => consoleErrors.push(String(e)));
  context.on('request', (r) => { const u = r.url(); if (!u.startsWith(base + '/') && !u.startsWith('blob:') && !u.startsWith('data:')) foreign.push(u); });

  // 1. The list, open before the job exists: the job appears, and reaches succeeded live.
  await page.goto(base + '/');
  await page.waitForSelector('table.jobs');
  // examples/adaptive: the Fusion 360 adaptive roughing program (6.5k blocks), optimized.
  const ex = join(root, 'examples', 'adaptive');
  const program = await api(base, '/v1/programs?name=1055_utab_265bit.nc', readFileSync(join(ex, '1055_utab_265bit.nc')), { 'content-type': 'text/plain' });
  const stock = await api(base, '/v1/stocks', readFileSync(join(ex, 'stock.json'), 'utf8'));
  const tool = await api(base, '/v1/tools', readFileSync(join(ex, 'tool.json'), 'utf8'));
  const machine = await api(base, '/v1/machines', readFileSync(join(ex, 'machine.json'), 'utf8'));
  const job = await api(base, '/v1/jobs', { kind: 'optimize', inputs: { program: program.id, stock: stock.id, tool: tool.id, machine: machine.id },
    options: { material: 'Al7075-T6', limits: { max_force: 400, air_feed: 5000, max_feed: 5000 } } });
  log('submitted optimize job', job.id);
  const row = `tr[data-id="${job.id}"]`;
  await page.waitForSelector(row + '[data-status="queued"]', { timeout: 15000 });
  assert.equal(await page.textContent(row + ' td.prog a'), '1055_utab_265bit.nc');
  const t0 = Date.now();
  spawnMillsim(['worker', '--database', dbUrl('open'), '--workers', '1']);
  const seen = [];
  const widths = new Set();
  for (;;) {
    const st = await page.getAttribute(row, 'data-status');
    if (seen[seen.length - 1] !== st) seen.push(st);
    widths.add(await page.$eval(row + ' .bar > div', (d) => d.style.width));
    if (st === 'succeeded') break;
    assert.ok(st !== 'failed' && st !== 'cancelled', 'job ended ' + st);
    assert.ok(Date.now() - t0 < 180000, 'job did not succeed within 180 s on the page');
    await page.waitForTimeout(50);
  }
  log('statuses seen on the list without reloading:', seen.join(' -> '), '; bar widths seen:', [...widths].join(' '));
  assert.equal(seen[0], 'queued');
  assert.equal(await page.$eval(row + ' .bar > div', (d) => d.style.width), '100%');
  await page.screenshot({ path: join(ARTIFACTS, 'list.png'), fullPage: true });

  // Filters: the kind filter keeps it, a status filter that does not match drops it.
  await page.selectOption('select[name=kind]', 'optimize');
  await page.waitForSelector(row);
  await page.selectOption('select[name=status]', 'failed');
  await page.waitForSelector('text=No jobs match these filters.');
  await page.goto(base + '/');

  // 2. The job's page: cards with the summary's numbers, plots drawn, downloads served.
  await page.click(row + ' td.prog a');
  await page.waitForURL(base + '/jobs/' + job.id);
  await page.waitForSelector('#plots .plot canvas');
  const s = (await api(base, '/v1/jobs/' + job.id)).summary;
  const o = s.optimization;
  const cardText = async (k) => page.textContent(`[data-card="${k}"]`);
  assert.match(await cardText('Peak force before'), new RegExp(fmt(s.force_peak_n, 1).replace(/[.,]/g, '\\$&') + ' N'));
  assert.match(await cardText('Peak force before'), new RegExp('line ' + s.force_peak_line + '$'));
  assert.match(await cardText('Peak force after'), new RegExp(fmt(o.peak_force_after, 1).replace(/[.,]/g, '\\$&') + ' N'));
  assert.match(await cardText('Removed volume'), new RegExp(fmt(s.removed_volume_mm3, 0).replace(/[.,]/g, '\\$&')));
  for (const [k, v] of [['Cycle time before', o.cycle_time_before_s], ['Cycle time after', o.cycle_time_after_s], ['At best constant feed', o.cycle_time_constant_feed_s]]) {
    const text = await cardText(k);
    const secs = v < 60 ? fmt(v, 2) + ' s' : Math.floor(v / 60) + ' min ' + fmt(v - 60 * Math.floor(v / 60), 1) + ' s';
    assert.ok(text.includes(secs), `${k}: ${text} lacks ${secs}`);
  }
  assert.match(await cardText('Collisions'), new RegExp('^Collisions' + s.collisions.length));
  await page.waitForFunction(() => performance.getEntriesByName('plots-drawn').length > 0);
  const timing = await page.evaluate(() => ({
    nav: Math.round(performance.getEntriesByType('navigation')[0].duration),
    plots: Math.round((performance.getEntriesByName('plots-drawn')[0] || {}).startTime || -1),
    fcp: Math.round((performance.getEntriesByName('first-contentful-paint')[0] || {}).startTime || -1),
    requests: performance.getEntriesByType('resource').filter((r) => r.name.includes('/v1/')).map((r) => r.name.replace(/^.*\/v1\//, '').slice(0, 60) + ' ' + Math.round(r.duration) + ' ms'),
  }));
  log('job page timing (ms since navigation): first contentful paint', timing.fcp, '; plots drawn by', timing.plots, '; API requests:', timing.requests.join(', '));
  const ink = await canvasInk(page, '#plots .plot:not([data-plot="Samples"]) canvas');
  log('plot canvases ink (pixels drawn):', ink.join(', '));
  assert.equal(ink.length, 6, 'force, force against time, feed, MRR, power and torque plots');
  const timeTitle = await page.textContent('[data-plot="Force against time"] .title');
  log('time plot:', timeTitle);
  assert.ok(timeTitle.includes('before: ' + (o.cycle_time_before_s >= 60 ? Math.floor(o.cycle_time_before_s / 60) + ' min' : '')), timeTitle);
  await page.$eval('[data-plot="Force against time"]', (e) => e.scrollIntoView());
  const tover = await (await page.$('[data-plot="Force against time"] .u-over')).boundingBox();
  await page.mouse.move(tover.x + tover.width * 0.2, tover.y + tover.height / 2);
  const thover = await page.textContent('[data-plot="Force against time"] .hover');
  log('time hover:', thover);
  await page.locator('[data-plot="Force against time"]').screenshot({ path: join(ARTIFACTS, 'force-against-time.png') });
  assert.match(thover, /^t [\d,.]+ s · before: block \d+ line \d+ [\d,.]+ N · after: block \d+ line \d+ [\d,.]+ N/);
  for (const n of ink) assert.ok(n > 2000, 'a plot canvas is (nearly) empty: ' + n);
  // Hover the middle of the force plot: block, line, N.
  await page.$eval('[data-plot="Cutting force"]', (e) => e.scrollIntoView());
  const over = await page.$('[data-plot="Cutting force"] .u-over');
  const bb = await over.boundingBox();
  await page.mouse.move(bb.x + bb.width / 2, bb.y + bb.height / 2);
  const hover = await page.textContent('[data-plot="Cutting force"] .hover');
  log('hover:', hover);
  assert.match(hover, /^block \d+ · line \d+ · N \S+ · .*peak \|F\| before [\d,.]+ N/);
  // The program beside the optimized one: changed F words marked; a click on a plot point
  // scrolls to its line.
  await page.waitForSelector('#programs table.diff tr.changed mark');
  const changed = await page.$$eval('#programs table.diff tr.changed', (trs) => trs.map((tr) => [...tr.querySelectorAll('mark')].map((m) => m.textContent)));
  log('diff:', await page.textContent('#diffinfo'), '; summary changed_blocks', o.changed_blocks, '; first changed F words:', JSON.stringify(changed.slice(0, 3)));
  assert.ok(changed.length > 0, 'no changed F words');
  // Each marked line has a new F on the right: a different value, or an F where the line had none (modal feed).
  for (const m of changed) assert.ok(m.length >= 1 && m[m.length - 1] !== m[0] || m.length === 1, 'a changed line with the same F on both sides: ' + m);
  assert.equal(changed.length, o.changed_blocks, 'marked lines against the summary\'s changed_blocks');
  await page.mouse.click(bb.x + bb.width / 2, bb.y + bb.height / 2);
  const hoverLine = Number(hover.match(/line (\d+)/)[1]);
  await page.waitForSelector('#programs tr.focus');
  assert.equal(await page.textContent('#programs tr.focus td.ln'), String(hoverLine));
  assert.match(await page.textContent('[data-plot="Cutting force"] .hover .src'), new RegExp('^' + hoverLine + ': '));
  // Per-step samples of a zoomed range: drag over ~30 px of the force plot.
  await page.mouse.move(bb.x + bb.width * 0.3, bb.y + bb.height / 2);
  await page.mouse.down();
  await page.mouse.move(bb.x + bb.width * 0.3 + 30, bb.y + bb.height / 2, { steps: 5 });
  await page.mouse.up();
  await page.waitForSelector('#load-samples:not([disabled])');
  await page.click('#load-samples');
  await page.waitForSelector('[data-plot="Samples"] canvas');
  const sink = await canvasInk(page, '[data-plot="Samples"] canvas');
  log('samples:', await page.textContent('[data-plot="Samples"] .title'), '; ink', sink.join(','));
  assert.ok(sink[0] > 1000, 'the samples plot is (nearly) empty');
  // The machined stock in 3-D: the canvas shows the mesh (not just the clear colour), and a
  // drag orbits it (the picture changes).
  await page.click('#load-stock');
  await page.waitForSelector('#stockinfo', { timeout: 60000 });
  const glPixels = () => page.$eval('#stock3d canvas', (c) => {
    const t = document.createElement('canvas'); t.width = c.width; t.height = c.height;
    const g = t.getContext('2d'); g.drawImage(c, 0, 0);
    const d = g.getImageData(0, 0, t.width, t.height).data;
    let shape = 0; let sum = 0;
    for (let i = 0; i < d.length; i += 4) { if (Math.abs(d[i] - 0xf4) + Math.abs(d[i + 1] - 0xf6) + Math.abs(d[i + 2] - 0xf9) > 24) shape++; sum = (sum + d[i] * 7 + d[i + 1] * 13 + d[i + 2] * 17 + i) % 1000000007; }
    return { shape, total: d.length / 4, sum };
  });
  const before3d = await glPixels();
  const cb = await (await page.$('#stock3d canvas')).boundingBox();
  await page.mouse.move(cb.x + cb.width / 2, cb.y + cb.height / 2);
  await page.mouse.down();
  await page.mouse.move(cb.x + cb.width / 2 + 120, cb.y + cb.height / 2 + 30, { steps: 6 });
  await page.mouse.up();
  const after3d = await glPixels();
  log('3-D stock:', await page.textContent('#stockinfo'), '; pixels on the mesh', before3d.shape, 'of', before3d.total, '; after orbit', after3d.shape);
  assert.ok(before3d.shape > before3d.total * 0.05, 'the 3-D view is (nearly) blank');
  assert.notEqual(before3d.sum, after3d.sum, 'orbiting did not change the picture');
  const links = await page.$$eval('#downloads a', (as) => as.map((a) => [a.textContent, a.getAttribute('href')]));
  assert.deepEqual(links.map((l) => l[0]), ['Optimized program', 'Rows (CSV)', 'Stock after machining (STL)', 'Summary (JSON)']);
  for (const [, href] of links) {
    const r = await page.request.get(base + href);
    assert.equal(r.status(), 200, href);
    assert.ok((await r.body()).length > 0, href);
  }
  await page.screenshot({ path: join(ARTIFACTS, 'job.png'), fullPage: true });

  // 3. A failed job shows its problem document.
  const bad = await submit(base, {}, 'simulate', 'bad.nc', 'G21 G90\nG1 X10 Y0 Z-1 F100\nG1 X1000000000000\nM30\n', { material: 'Al7075-T6' });
  await page.goto(base + '/jobs/' + bad.id);
  await page.waitForSelector('#problem', { timeout: 60000 });
  assert.equal(await page.textContent('#problem dd[data-field="file"]'), 'bad.nc');
  assert.equal(await page.textContent('#problem dd[data-field="line"]'), '3');
  assert.match(await page.textContent('#problem dd[data-field="detail"]'), /outside the machine's travel/);
  await page.screenshot({ path: join(ARTIFACTS, 'failed.png'), fullPage: true });

  // 4. The new-job form: a program file, a block stock, a tool; the page then follows the job.
  await page.goto(base + '/');
  await page.click('#new-job-link');
  await page.waitForSelector('form#new-job');
  await page.setInputFiles('form#new-job input[name=program]', { name: 'form.nc', mimeType: 'text/plain', buffer: Buffer.from(zigzag(10)) });
  await page.fill('form#new-job input[name=max_force]', '300');
  await page.screenshot({ path: join(ARTIFACTS, 'new-job.png'), fullPage: true });
  await page.click('form#new-job button[type=submit]');
  await page.waitForURL(/\/jobs\/[0-9a-f-]+$/);
  const formJobId = page.url().split('/').pop();
  await page.waitForSelector('#cards', { timeout: 60000 });
  const fj = await api(base, '/v1/jobs/' + formJobId);
  log('form job', fj.kind, fj.status, 'program', (await api(base, '/v1/programs/' + fj.inputs.program)).name, 'limits', JSON.stringify(fj.options.limits));
  assert.equal(fj.kind, 'optimize');
  assert.equal(fj.options.limits.max_force, 300);
  assert.match(await page.textContent('#progname'), /^form\.nc$/);
  // A program that does not parse is refused with its line and column, shown on the form.
  await page.goto(base + '/?new=1');
  await page.setInputFiles('form#new-job input[name=program]', { name: 'syntax.nc', mimeType: 'text/plain', buffer: Buffer.from('G1 X10 F100\nG1 X#@!\n') });
  await page.click('form#new-job button[type=submit]');
  await page.waitForSelector('#form-result #problem');
  assert.equal(await page.textContent('#form-result #problem dd[data-field="file"]'), 'syntax.nc');
  assert.equal(await page.textContent('#form-result #problem dd[data-field="line"]'), '2');
  assert.equal(await page.textContent('#form-result #problem dd[data-field="column"]'), '6');
  await page.screenshot({ path: join(ARTIFACTS, 'new-job-refused.png'), fullPage: true });
  // The 422 of the refused upload is logged by the browser as a failed resource load: expected.
  for (let i = consoleErrors.length - 1; i >= 0; i--) if (/status of 422/.test(consoleErrors[i])) consoleErrors.splice(i, 1);

  // 5. A stability job: the lobes with the recommended speed; an energy job: the Pareto front.
  const stab = await api(base, '/v1/jobs', { kind: 'stability', options: { method: 'sdm', teeth: 2, ktc_n_mm2: 600, krc_n_mm2: 200, radial_immersion: 0.05, milling: 'down',
    modes_x: [{ freq_hz: 922, damping: 0.011, stiffness_n_m: 1.34005e6 }], modes_y: [], rpm: { from: 5000, to: 25000, step: 250 }, steps_per_period: 40,
    recommend: { near_rpm: 15000, depth_mm: 0.5 } } });
  const energy = await api(base, '/v1/jobs', { kind: 'energy', inputs: { tool: tool.id, machine: machine.id }, options: { material: 'Al7075-T6', length_mm: 200, width_mm: 8, depth_mm: 12,
    cutting_speed_m_min: { min: 100, max: 300 }, feed_per_tooth_mm: { min: 0.02, max: 0.2 }, objective: 'min_energy', pareto: true } });
  await page.goto(base + '/jobs/' + stab.id);
  await page.waitForSelector('[data-plot^="Critical axial depth"] canvas', { timeout: 60000 });
  const ss = (await api(base, '/v1/jobs/' + stab.id)).summary;
  assert.match(await page.textContent('[data-card="Recommended speed"]'), new RegExp(fmt(ss.recommendation.rpm, 0).replace(',', '\\,') + ' rpm'));
  const sink2 = await canvasInk(page, '#plots canvas');
  log('stability lobes ink', sink2.join(','));
  assert.ok(sink2[0] > 2000);
  await page.screenshot({ path: join(ARTIFACTS, 'stability.png'), fullPage: true });
  await page.goto(base + '/jobs/' + energy.id);
  await page.waitForSelector('[data-plot="Energy against time"] canvas', { timeout: 60000 });
  const es = (await api(base, '/v1/jobs/' + energy.id)).summary;
  assert.match(await page.textContent('[data-card="Chosen point"]'), new RegExp(fmt(es.best.spindle_rpm, 0).replace(',', '\\,') + ' rpm'));
  const eink = await canvasInk(page, '#plots canvas');
  log('energy Pareto ink', eink.join(','), '; front of', es.pareto.length, 'points');
  assert.ok(eink[0] > 1000);
  await page.screenshot({ path: join(ARTIFACTS, 'energy.png'), fullPage: true });

  assert.deepEqual(consoleErrors, [], 'console errors');
  assert.deepEqual(foreign, [], 'requests that left the server origin');
  await context.close();

  // 6. A server that requires API keys: the page asks for one and sends it.
  const out = execFileSync(BIN, ['api-key', 'dash']).toString();
  const key = out.match(/^key: (\S+)$/m)[1];
  const keyLine = out.match(/^key file line: (.+)$/m)[1];
  writeFileSync(join(work, 'keys'), keyLine + '\n');
  const kbase = await startServer('keys', ['--api-key-file', join(work, 'keys')]);
  const kjob = await submit(kbase, { authorization: 'Bearer ' + key }, 'simulate', 'keyed.nc', zigzag(3), { material: 'Al7075-T6' });
  const kctx = await browser.newContext();
  const kpage = await kctx.newPage();
  const kerrors = [];
  kpage.on('pageerror', (e) => kerrors.push(String(e)));
  await kpage.goto(kbase + '/');
  await kpage.waitForSelector('#keyform');
  await kpage.fill('#keyform input[name=key]', key);
  await kpage.click('#keyform button');
  await kpage.waitForSelector(`tr[data-id="${kjob.id}"][data-status="succeeded"]`, { timeout: 60000 });
  assert.equal(await kpage.evaluate(() => sessionStorage.getItem('millsim.apiKey')), key);
  await kpage.click(`tr[data-id="${kjob.id}"] td.prog a`);
  await kpage.waitForSelector('#plots .plot canvas');
  await kpage.screenshot({ path: join(ARTIFACTS, 'job-with-key.png'), fullPage: true });
  assert.deepEqual(kerrors, []);
  await browser.close();
  log('ok; screenshots in', ARTIFACTS);
}

let code = 0;
try {
  await main();
} catch (e) {
  console.error('[dashboard] FAILED:', e);
  code = 1;
} finally {
  for (const c of children) c.kill('SIGTERM');
  rmSync(work, { recursive: true, force: true });
}
process.exit(code);
