// The dashboard's acceptance in a real browser: the list following a job live, the example
// optimize job's page (cards, plots against block and cycle time, zoom and pan kept in step,
// hover, F highlights, click-to-line, samples, the stock in 3-D, downloads), a failed job's
// problem, the new-job form (with a stored tool), and a server that wants API keys.
// Run by tests/dashboard_browser.rs, or alone:
//   MILLSIM_BIN=$CARGO_TARGET_DIR/debug/millsim node tests/browser/dashboard.mjs
// Screenshots go to tests/browser/artifacts/.
import { execFileSync } from 'node:child_process';
import { writeFileSync } from 'node:fs';
import { join } from 'node:path';
import assert from 'node:assert/strict';
import { ARTIFACTS, BIN, api, boxStl, canvasInk, colourInk, dbUrl, esc, exampleInputs, fmt, glPixels, logger, openBrowser, run, spawnMillsim, startServer, waitJob, work } from './common.mjs';

const log = logger('dashboard');

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

// The colours of each plot's series, before and after (web/blockplots.js).
const SERIES = {
  'Cutting force': ['#c62828', '#2463eb', '#8fb3f5'],
  'Deflection and form error': ['#455a64', '#d81b60'],
  Feed: ['#7a5c00', '#18794e'],
  'Material removal rate': ['#6a1b9a', '#ba68c8'],
  'Spindle power': ['#ef6c00', '#1565c0', '#64b5f6'],
  Torque: ['#00838f', '#5e35b1'],
};

const plotX = (page, title) => page.getAttribute(`[data-plot="${title}"]`, 'data-x');

async function main() {
  // No workers in the server: the job waits queued until the test starts a worker process
  // on the same database, so the page is seen following it from queued to succeeded.
  const base = await startServer('open', ['--workers', '0']);
  log('server', base);
  const { browser, context, page, consoleErrors, foreign } = await openBrowser(base);

  // 1. The list, open before the job exists: the job appears, and reaches succeeded live.
  await page.goto(base + '/');
  await page.waitForSelector('table.jobs');
  const ex = await exampleInputs(base);
  const job = await api(base, '/v1/jobs', { kind: 'optimize', inputs: { program: ex.program.id, stock: ex.stock.id, tool: ex.tool.id, machine: ex.machine.id },
    // Guards off: with the Ø2.65 tool's default guards most of this program keeps its
    // programmed feed (it is over them as written), and the 'after' lines would cover the
    // 'before' lines this test looks for.
    options: { material: 'Al7075-T6', limits: { max_force: 400, air_feed: 5000, max_feed: 5000, tool_guards: false } } });
  log('submitted optimize job', job.id);
  const row = `tr[data-id="${job.id}"]`;
  await page.waitForSelector(row + '[data-status="queued"]', { timeout: 15000 });
  assert.equal(await page.textContent(row + ' td.prog a'), '1055_utab_265bit.nc');
  assert.ok(await page.$(row + ' button.cancel'), 'a queued row offers cancel');
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
    assert.ok(Date.now() - t0 < 240000, 'job did not succeed within 240 s on the page');
    await page.waitForTimeout(50);
  }
  log('statuses seen on the list without reloading:', seen.join(' -> '), '; bar widths seen:', [...widths].join(' '));
  assert.equal(seen[0], 'queued');
  assert.equal(await page.$eval(row + ' .bar > div', (d) => d.style.width), '100%');
  assert.equal(await page.$(row + ' button.cancel'), null, 'a finished row offers no cancel');
  await page.screenshot({ path: join(ARTIFACTS, 'list.png'), fullPage: true });

  // Filters: the kind filter keeps it, a status filter that does not match drops it.
  await page.selectOption('select[name=kind]', 'optimize');
  await page.waitForSelector(row);
  await page.selectOption('select[name=status]', 'failed');
  await page.waitForSelector('text=No jobs match these filters.');

  // 2. The job's page, loaded afresh: time to first paint, cards and plots.
  await page.goto(base + '/jobs/' + job.id);
  await page.waitForFunction(() => performance.getEntriesByName('plots-drawn').length > 0, null, { timeout: 60000 });
  const timing = await page.evaluate(() => ({
    fcp: Math.round((performance.getEntriesByName('first-contentful-paint')[0] || {}).startTime || -1),
    cards: Math.round((performance.getEntriesByName('cards-shown')[0] || {}).startTime || -1),
    plots: Math.round((performance.getEntriesByName('plots-drawn')[0] || {}).startTime || -1),
    requests: performance.getEntriesByType('resource').filter((r) => r.name.includes('/v1/')).map((r) => r.name.replace(/^.*\/v1\//, '').slice(0, 50) + ' ' + Math.round(r.duration) + ' ms'),
  }));
  log('job page of 6.5k blocks (ms since navigation): first contentful paint', timing.fcp, '; cards', timing.cards, '; plots drawn', timing.plots, '; API:', timing.requests.join(', '));
  assert.ok(timing.fcp > 0 && timing.fcp < 1000, 'first paint ' + timing.fcp + ' ms');
  assert.ok(timing.cards > 0 && timing.cards < 1000, 'cards ' + timing.cards + ' ms');
  const s = (await api(base, '/v1/jobs/' + job.id)).summary;
  const o = s.optimization;
  const cardText = async (k) => page.textContent(`[data-card="${k}"]`);
  assert.match(await cardText('Peak force before'), new RegExp(esc(fmt(s.force_peak_n, 1)) + ' N'));
  assert.match(await cardText('Peak force before'), new RegExp('line ' + s.force_peak_line + '$'));
  assert.match(await cardText('Peak force after'), new RegExp(esc(fmt(o.peak_force_after, 1)) + ' N'));
  assert.match(await cardText('Removed volume'), new RegExp(esc(fmt(s.removed_volume_mm3, 0))));
  for (const [k, v] of [['Cycle time before', o.cycle_time_before_s], ['Cycle time after', o.cycle_time_after_s], ['At best constant feed', o.cycle_time_constant_feed_s]]) {
    const text = await cardText(k);
    const secs = v < 60 ? fmt(v, 2) + ' s' : Math.floor(v / 60) + ' min ' + fmt(v - 60 * Math.floor(v / 60), 1) + ' s';
    assert.ok(text.includes(secs), `${k}: ${text} lacks ${secs}`);
  }
  assert.match(await cardText('Collisions'), new RegExp('^Collisions' + s.collisions.length));
  // The program's own warnings and the interpreter's, counted, the first shown.
  const notes = [...(s.warnings || []), ...(s.program_warnings || [])];
  if (notes.length) {
    const text = await cardText('Program notes');
    assert.ok(text.startsWith('Program notes' + notes.length) && text.includes(notes[0]), text);
  } else {
    assert.equal(await page.$('[data-card="Program notes"]'), null, 'a notes card with no notes');
  }
  const titles = ['Cutting force', 'Deflection and form error', 'Feed', 'Material removal rate', 'Spindle power', 'Torque'];
  // Each tool's worst form error, as the summary gives it.
  for (const t of s.deflection) {
    assert.match(await cardText('T' + t.tool + ' form error'), new RegExp(esc(fmt(t.form_error_um, 1)) + ' µm'));
  }
  assert.ok(s.deflection.length > 0, 'no tool bends: ' + JSON.stringify(s.deflection));
  const ink = await canvasInk(page, '#plots .plot:not([data-plot="Samples"]) canvas');
  log('plots against block, ink (pixels drawn):', ink.join(', '));
  assert.equal(ink.length, titles.length);
  for (const n of ink) assert.ok(n > 2000, 'a plot canvas is (nearly) empty: ' + n);
  // Each plot's lines, by their colours (the grid and axes alone have none of them).
  const lines = async () => {
    const out = {};
    for (const [title, colours] of Object.entries(SERIES)) {
      out[title] = [];
      for (const c of colours) out[title].push((await colourInk(page, `[data-plot="${title}"] canvas`, c))[0]);
    }
    return out;
  };
  const drawn = await lines();
  log('pixels of each series colour, against block:', JSON.stringify(drawn));
  for (const [title, counts] of Object.entries(drawn)) for (const n of counts) assert.ok(n > 100, `${title}: a series is not drawn (${counts})`);

  // Hover the middle of the force plot: block, line, N and the source line.
  const over = async (title) => (await page.$(`[data-plot="${title}"] .u-over`)).boundingBox();
  await page.$eval('[data-plot="Cutting force"]', (e) => e.scrollIntoView());
  let bb = await over('Cutting force');
  await page.mouse.move(bb.x + bb.width / 2, bb.y + bb.height / 2);
  const hover = await page.textContent('[data-plot="Cutting force"] .hover');
  log('hover:', hover);
  assert.match(hover, /^block \d+ · line \d+ · N \S+ · \w+ · peak \|F\| before [\d,.]+ N · mean \|F\| before [\d,.]+ N · peak \|F\| after [\d,.]+ N/);
  const hoverLine = Number(hover.match(/line (\d+)/)[1]);
  assert.match(await page.textContent('[data-plot="Cutting force"] .hover .src'), new RegExp('^' + hoverLine + ': '));

  // The program beside the optimized one: changed F words marked; a click on a plot point
  // scrolls to its line.
  await page.waitForSelector('#programs table.diff tr.changed mark');
  const changed = await page.$$eval('#programs table.diff tr.changed', (trs) => trs.map((tr) => [...tr.querySelectorAll('mark')].map((m) => m.textContent)));
  log('diff:', await page.textContent('#diffinfo'), '; summary changed_blocks', o.changed_blocks, 'restored_f_words', o.restored_f_words, '; first changed F words:', JSON.stringify(changed.slice(0, 3)));
  // The listing draws the lines in view: those marked are checked, the count is the table's.
  assert.ok(changed.length > 10, 'few marked lines in view: ' + changed.length);
  for (const m of changed) assert.ok(m.length === 2 ? m[1] !== m[0] : m.length === 1, 'a changed line without a new F on the right: ' + m);
  // A line gets a new F word where the optimizer changed its feed (changed_blocks) and where it
  // writes the programmed feed back after a changed one (restored_f_words: a plunge kept at its F).
  assert.equal(Number(await page.getAttribute('#programs table.diff[data-changed]', 'data-changed')), o.changed_blocks + o.restored_f_words, 'changed lines against the summary\'s changed_blocks + restored_f_words');
  await page.mouse.click(bb.x + bb.width / 2, bb.y + bb.height / 2);
  await page.waitForSelector('#programs tr.focus');
  assert.equal(await page.textContent('#programs tr.focus td.ln'), String(hoverLine));
  await page.locator('#programs').screenshot({ path: join(ARTIFACTS, 'program-diff.png') });

  // Zoom with the wheel on the force plot: every plot follows to the same range; shift-drag
  // pans them all; a double click shows everything again.
  await page.$eval('[data-plot="Cutting force"]', (e) => e.scrollIntoView());
  bb = await over('Cutting force');
  const full = await plotX(page, 'Feed');
  await page.mouse.move(bb.x + bb.width * 0.5, bb.y + bb.height / 2);
  for (let i = 0; i < 8; i++) { await page.mouse.wheel(0, -300); await page.waitForTimeout(30); }
  await page.waitForTimeout(100);
  const zoomed = await Promise.all(titles.map((t) => plotX(page, t)));
  log('x range: all', full, '; after the wheel', zoomed[0]);
  assert.notEqual(zoomed[0], full);
  for (const z of zoomed) assert.equal(z, zoomed[0], 'the plots did not follow one another: ' + zoomed.join(' | '));
  const [zmin, zmax] = zoomed[0].split(',').map(Number);
  const [fmin, fmax] = full.split(',').map(Number);
  assert.ok(zmax - zmin < 0.5 * (fmax - fmin), 'the wheel did not zoom in');
  await page.keyboard.down('Shift');
  await page.mouse.move(bb.x + bb.width * 0.6, bb.y + bb.height / 2);
  await page.mouse.down();
  await page.mouse.move(bb.x + bb.width * 0.4, bb.y + bb.height / 2, { steps: 8 });
  await page.mouse.up();
  await page.keyboard.up('Shift');
  await page.waitForTimeout(100);
  const panned = (await plotX(page, 'Torque')).split(',').map(Number);
  log('after a shift-drag of 20% of the width:', panned.join(','));
  assert.ok(panned[0] > zmin && Math.abs((panned[1] - panned[0]) - (zmax - zmin)) < 1e-6 * (fmax - fmin) + 1e-3, 'shift-drag did not pan: ' + panned);
  assert.equal(await plotX(page, 'Feed'), await plotX(page, 'Torque'));

  // Per-step samples of the blocks in view: zoom further with a drag, then load them.
  await page.mouse.dblclick(bb.x + bb.width / 2, bb.y + bb.height / 2);
  await page.waitForTimeout(100);
  assert.equal(await plotX(page, 'Torque'), full, 'a double click shows everything');
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
  assert.ok((await colourInk(page, '[data-plot="Samples"] canvas', '#c62828'))[0] > 300, 'the samples\' peak force is not drawn');
  await page.screenshot({ path: join(ARTIFACTS, 'job.png'), fullPage: true });

  // Against cycle time: the after series end at the optimized cycle time.
  await page.check('#xmode input[value=time]');
  await page.waitForSelector('[data-plot="Cutting force"] .title:has-text("against cycle time")');
  const tink = await canvasInk(page, '#plots .plot:not([data-plot="Samples"]) canvas');
  log('plots against cycle time, ink:', tink.join(', '), ';', await page.textContent('[data-plot="Cutting force"] .title'));
  for (const n of tink) assert.ok(n > 2000, 'a time plot is (nearly) empty: ' + n);
  const tdrawn = await lines();
  log('pixels of each series colour, against cycle time:', JSON.stringify(tdrawn));
  for (const [title, counts] of Object.entries(tdrawn)) for (const n of counts) assert.ok(n > 100, `${title} against time: a series is not drawn (${counts})`);
  const [t0x, t1x] = (await plotX(page, 'Feed')).split(',').map(Number);
  assert.ok(Math.abs(t1x - o.cycle_time_before_s) < 0.01 * o.cycle_time_before_s && t0x < 0.05 * o.cycle_time_before_s, 'time axis ' + t0x + '..' + t1x + ' against ' + o.cycle_time_before_s);
  await page.$eval('[data-plot="Feed"]', (e) => e.scrollIntoView());
  const fb = await over('Feed');
  await page.mouse.move(fb.x + fb.width * 0.2, fb.y + fb.height / 2);
  const thover = await page.textContent('[data-plot="Feed"] .hover');
  log('time hover:', thover);
  assert.match(thover, /^t [\d,.]+ s · block \d+ · line \d+ .* · feed before [\d,.]+ mm\/min · feed after [\d,.]+ mm\/min \(block \d+, line \d+\)/);
  await page.locator('[data-plot="Cutting force"]').screenshot({ path: join(ARTIFACTS, 'force-against-time.png') });

  // The machined stock in 3-D: the canvas shows the mesh, and a drag orbits it.
  await page.click('#load-stock');
  await page.waitForSelector('#stockinfo', { timeout: 60000 });
  const before3d = await glPixels(page, '#stock3d canvas');
  const cb = await (await page.$('#stock3d canvas')).boundingBox();
  await page.mouse.move(cb.x + cb.width / 2, cb.y + cb.height / 2);
  await page.mouse.down();
  await page.mouse.move(cb.x + cb.width / 2 + 120, cb.y + cb.height / 2 + 30, { steps: 6 });
  await page.mouse.up();
  const after3d = await glPixels(page, '#stock3d canvas');
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
  await page.screenshot({ path: join(ARTIFACTS, 'job-time-3d.png'), fullPage: true });

  // 3. A failed job shows its problem document.
  const bad = await submit(base, {}, 'simulate', 'bad.nc', 'G21 G90\nG1 X10 Y0 Z-1 F100\nG1 X1000000000000\nM30\n', { material: 'Al7075-T6' });
  await page.goto(base + '/jobs/' + bad.id);
  await page.waitForSelector('#problem', { timeout: 60000 });
  assert.equal(await page.textContent('#problem dd[data-field="file"]'), 'bad.nc');
  assert.equal(await page.textContent('#problem dd[data-field="line"]'), '3');
  assert.match(await page.textContent('#problem dd[data-field="detail"]'), /outside the machine's travel/);
  await page.waitForSelector('#problem-source');
  assert.equal(await page.textContent('#problem-source'), '3: G1 X1000000000000');
  await page.screenshot({ path: join(ARTIFACTS, 'failed.png'), fullPage: true });

  // 4. The new-job form with a stored tool picked: the page then follows the job.
  await page.goto(base + '/');
  await page.click('#new-job-link');
  await page.waitForSelector('form#new-job');
  await page.setInputFiles('form#new-job input[name=program]', { name: 'form.nc', mimeType: 'text/plain', buffer: Buffer.from(zigzag(10)) });
  await page.selectOption('form#new-job select[name=tool_choice]', ex.tool.id);
  assert.match(await page.$eval('form#new-job select[name=tool_choice]', (s) => s.selectedOptions[0].textContent), /^stored: (.* · )?flat Ø2\.65 2 flutes · /);
  assert.equal(await page.isVisible('#new-tool'), false, 'the new tool fields hide when a stored tool is picked');
  await page.selectOption('form#new-job select[name=machine_choice]', ex.machine.id);
  await page.fill('form#new-job input[name=max_force]', '300');
  // A design part 1 mm under the stock's top: the zigzag at Z-1.5 gouges it.
  await page.setInputFiles('form#new-job input[name=part_stl]', { name: 'part.stl', mimeType: 'model/stl', buffer: Buffer.from(boxStl([0, 0, -20], [100, 80, -1])) });
  await page.screenshot({ path: join(ARTIFACTS, 'new-job.png'), fullPage: true });
  await page.click('form#new-job button[type=submit]');
  await page.waitForURL(/\/jobs\/[0-9a-f-]+$/);
  const formJobId = page.url().split('/').pop();
  await page.waitForSelector('#cards', { timeout: 90000 });
  const fj = await api(base, '/v1/jobs/' + formJobId);
  log('form job', fj.kind, fj.status, 'inputs', JSON.stringify(fj.inputs), 'limits', JSON.stringify(fj.options.limits));
  assert.equal(fj.kind, 'optimize');
  assert.equal(fj.inputs.tool, ex.tool.id);
  assert.equal(fj.inputs.machine, ex.machine.id);
  assert.equal(fj.options.limits.max_force, 300);
  assert.ok(fj.inputs.part, 'the design part is an input');
  assert.ok(fj.summary.part.gouge_volume > 0 && fj.summary.part.gouges.length > 0, JSON.stringify(fj.summary.part));
  await page.waitForSelector('#gouges tbody tr');
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

  assert.deepEqual(consoleErrors, [], 'console errors');
  assert.deepEqual(foreign, [], 'requests that left the server origin');
  await context.close();

  // 5. A server that requires API keys: the page asks for one and sends it.
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

run('dashboard', main);
