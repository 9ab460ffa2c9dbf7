// Every job kind's view in a real browser, and the cancel button: stability lobes with the
// 3-D lobe surface over the allowance, the energy Pareto front, interpret's tool path in
// 3-D, rotary-feed's corrected F words, identify's fits, a simulate job's collision and a
// gouge marked in 3-D, and a long job cancelled from its page. Run by tests/dashboard_browser.rs, or:
//   MILLSIM_BIN=$CARGO_TARGET_DIR/debug/millsim node tests/browser/kinds.mjs
import { join } from 'node:path';
import assert from 'node:assert/strict';
import { ARTIFACTS, api, boxStl, canvasInk, colourInk, esc, exampleInputs, fmt, glPixels, logger, openBrowser, run, startServer, waitJob } from './common.mjs';

const log = logger('kinds');

const STABILITY = { method: 'sdm', teeth: 2, ktc_n_mm2: 600, krc_n_mm2: 200, radial_immersion: 0.05, milling: 'down',
  modes_x: [{ freq_hz: 922, damping: 0.011, stiffness_n_m: 1.34005e6 }], modes_y: [], rpm: { from: 5000, to: 25000, step: 250 }, steps_per_period: 40 };

async function main() {
  const base = await startServer('kinds', ['--workers', '1']);
  const { browser, context, page, consoleErrors, foreign } = await openBrowser(base);
  const ex = await exampleInputs(base);
  const submitJob = (body) => api(base, '/v1/jobs', body);

  // Cancel first, while the worker is free: a long stability job, cancelled from its page
  // while it runs; the page then says so.
  // (tests/common's long_stability_job: two modes a direction, 20,001 speeds.)
  const m2 = (f) => ({ freq_hz: f, damping: 0.02, stiffness_n_m: 2e6 });
  const long = await submitJob({ kind: 'stability', options: { ...STABILITY, radial_immersion: 0.5, modes_x: [m2(900), m2(1400)], modes_y: [m2(950), m2(1500)],
    rpm: { from: 5000, to: 25000, step: 1 } } });
  await page.goto(base + '/jobs/' + long.id);
  await page.waitForSelector('#cancel-job');
  for (let i = 0; i < 100 && (await api(base, '/v1/jobs/' + long.id)).status !== 'running'; i++) await page.waitForTimeout(100);
  await page.click('#cancel-job');
  await page.waitForSelector('#ended', { timeout: 60000 });
  assert.equal(await page.textContent('#ended'), 'The job was cancelled.');
  assert.equal(await page.getAttribute('h1 .status', 'data-status'), 'cancelled');
  assert.equal((await api(base, '/v1/jobs/' + long.id)).status, 'cancelled');
  log('cancel: the running stability job ended cancelled from its page');
  await page.screenshot({ path: join(ARTIFACTS, 'cancelled.png'), fullPage: true });

  // Stability: lobes with the recommended speed.
  const stab = await submitJob({ kind: 'stability', options: { ...STABILITY, recommend: { near_rpm: 15000, depth_mm: 0.5 } } });
  const mode = (k) => [{ freq_hz: 600, damping: 0.02, stiffness_n_m: k }];
  const surface = await submitJob({ kind: 'stability', options: { ...STABILITY, radial_immersion: 0.5, modes_x: [], rpm: { from: 5000, to: 25000, step: 100 },
    allowance: [{ allowance_mm: 0.5, modes_x: mode(2e6) }, { allowance_mm: 3.0, modes_x: mode(8e6) }], allowances_mm: [0.5, 1.0, 1.5, 2.0, 2.5, 3.0] } });
  await waitJob(base, stab.id, 120);
  await page.goto(base + '/jobs/' + stab.id);
  await page.waitForSelector('[data-plot^="Critical axial depth"] canvas', { timeout: 60000 });
  const ss = (await api(base, '/v1/jobs/' + stab.id)).summary;
  assert.match(await page.textContent('[data-card="Recommended speed"]'), new RegExp(esc(fmt(ss.recommendation.rpm, 0)) + ' rpm'));
  const sink = await canvasInk(page, '#plots canvas');
  log('stability lobes ink', sink.join(','));
  assert.ok(sink[0] > 2000);
  assert.ok((await colourInk(page, '#plots canvas', '#2463eb'))[0] > 300, 'the lobe line is not drawn');
  await page.screenshot({ path: join(ARTIFACTS, 'stability.png'), fullPage: true });

  // The 3-D lobe surface over the allowance: six lobe curves, and the surface drawn.
  await waitJob(base, surface.id, 180);
  await page.goto(base + '/jobs/' + surface.id);
  await page.waitForSelector('#lobes3dinfo', { timeout: 60000 });
  const lines = await page.$$eval('[data-plot^="Critical axial depth"] .u-legend .u-series', (s) => s.length);
  assert.equal(lines, 1 + 6, 'one lobe line per allowance');
  const lobes = await glPixels(page, '#lobes3d canvas');
  log('lobe surface:', await page.textContent('#lobes3dinfo'), '; pixels off the background', lobes.shape, 'of', lobes.total);
  assert.ok(lobes.shape > lobes.total * 0.1, 'the lobe surface is (nearly) blank');
  await page.screenshot({ path: join(ARTIFACTS, 'stability-surface.png'), fullPage: true });

  // Energy: the Pareto front and the chosen point.
  const energy = await submitJob({ kind: 'energy', inputs: { tool: ex.tool.id, machine: ex.machine.id }, options: { material: 'Al7075-T6', length_mm: 200, width_mm: 8, depth_mm: 12,
    cutting_speed_m_min: { min: 100, max: 300 }, feed_per_tooth_mm: { min: 0.02, max: 0.2 }, objective: 'min_energy', pareto: true } });
  await waitJob(base, energy.id, 120);
  await page.goto(base + '/jobs/' + energy.id);
  await page.waitForSelector('[data-plot="Energy against time"] canvas', { timeout: 60000 });
  const es = (await api(base, '/v1/jobs/' + energy.id)).summary;
  assert.match(await page.textContent('[data-card="Chosen point"]'), new RegExp(esc(fmt(es.best.spindle_rpm, 0)) + ' rpm'));
  const eink = await canvasInk(page, '#plots canvas');
  log('energy Pareto ink', eink.join(','), '; front of', es.pareto.length, 'points');
  assert.ok(eink[0] > 1000);
  assert.ok((await colourInk(page, '#plots canvas', '#2463eb'))[0] > 300, 'the Pareto front is not drawn');
  assert.ok((await colourInk(page, '#plots canvas', '#c62828'))[0] > 30, 'the chosen point is not drawn');
  await page.screenshot({ path: join(ARTIFACTS, 'energy.png'), fullPage: true });

  // Interpret: the example program's tool path in 3-D, rapids and feed moves coloured.
  const interp = await submitJob({ kind: 'interpret', inputs: { program: ex.program.id } });
  await waitJob(base, interp.id, 60);
  await page.goto(base + '/jobs/' + interp.id);
  await page.waitForSelector('#toolpathinfo', { timeout: 60000 });
  const is = (await api(base, '/v1/jobs/' + interp.id)).summary;
  assert.match(await page.textContent('[data-card="Moves"]'), new RegExp(esc(fmt(is.moves, 0))));
  const feedBlue = await glPixels(page, '#toolpath3d canvas', [0x24, 0x63, 0xeb]);
  const rapidOrange = await glPixels(page, '#toolpath3d canvas', [0xef, 0x6c, 0x00]);
  log('tool path:', await page.textContent('#toolpathinfo'), '; blue (feed) pixels', feedBlue.coloured, '; orange (rapid) pixels', rapidOrange.coloured);
  assert.ok(feedBlue.coloured > 2000, 'no feed moves drawn');
  assert.ok(rapidOrange.coloured > 50, 'no rapids drawn');
  await page.screenshot({ path: join(ARTIFACTS, 'interpret.png'), fullPage: true });

  // Rotary feed: a B turn at F500, 50 mm from the axis; the written F is marked.
  const bTable = await api(base, '/v1/machines', { name: 'B table', kinematics: 'xyz_b', rapid_rate: 20000.0, max_feed: 10000.0,
    acceleration: [1000.0, 1000.0, 1000.0], spindle_min_rpm: 0.0, spindle_max_rpm: 12000.0, rated_power: 10000.0 });
  const rotary = await submitJob({ kind: 'rotary-feed', inputs: { program: { name: 'b.nc', content: 'G21 G90 G94\nG0 X50 Y0 Z0 B0\nG1 B90 F500\nG1 X60 F500\nM30\n' }, machine: bTable.id } });
  await waitJob(base, rotary.id, 60);
  await page.goto(base + '/jobs/' + rotary.id);
  await page.waitForSelector('#programs table.diff tr.changed mark', { timeout: 60000 });
  const marked = await page.$$eval('#programs table.diff tr.changed', (trs) => trs.map((tr) => [...tr.querySelectorAll('mark')].map((m) => m.textContent)));
  log('rotary feed: marked F words', JSON.stringify(marked));
  assert.equal(marked.length, 1, 'only the B move changes F');
  assert.equal(marked[0][0], 'F500');
  const expected = 90 / ((Math.PI / 2) * 50 / 500);
  assert.ok(Math.abs(Number(marked[0][1].slice(1)) - expected) < 0.01 * expected, marked[0][1] + ' against F' + expected.toFixed(1));
  const fink = await Promise.all(['#7a5c00', '#18794e'].map(async (c) => (await colourInk(page, '[data-plot="Programmed and written F"] canvas', c))[0]));
  log('rotary feed plot: programmed and written F pixels', fink.join(', '));
  for (const n of fink) assert.ok(n > 30, 'a feed series is not drawn: ' + fink);
  await page.screenshot({ path: join(ARTIFACTS, 'rotary-feed.png'), fullPage: true });

  // Identify: coefficients from mean slotting forces (straight lines in the feed per tooth).
  // A slot's mean Fz is negative in the generalized convention (the flank pulls the tool in).
  const feeds = [0.025, 0.05, 0.075, 0.1, 0.125];
  const measurements = feeds.map((c, i) => ({ feed_per_tooth_mm: c, fx_n: -400 * c - 20 + 0.05 * (i % 2), fy_n: 1000 * c + 40 - 0.05 * (i % 2), fz_n: -150 * c - 5 }));
  const ident = await submitJob({ kind: 'identify', inputs: { tool: ex.tool.id }, options: { depth_mm: 2, measurements } });
  const done = await waitJob(base, ident.id, 60);
  assert.equal(done.status, 'succeeded', JSON.stringify(done.error));
  await page.goto(base + '/jobs/' + ident.id);
  await page.waitForSelector('[data-plot="Mean force against feed per tooth"] canvas', { timeout: 60000 });
  assert.match(await page.textContent('[data-card="Ktc"]'), new RegExp(esc(fmt(done.summary.coefficients.ktc, 1)) + ' N/mm²'));
  const iink = await canvasInk(page, '#plots canvas');
  log('identify: Ktc', fmt(done.summary.coefficients.ktc, 1), '; fit ink', iink.join(','));
  assert.ok(iink[0] > 1000);
  for (const c of ['#c62828', '#2463eb', '#18794e']) assert.ok((await colourInk(page, '#plots canvas', c))[0] > 300, 'a force fit is not drawn: ' + c);
  await page.screenshot({ path: join(ARTIFACTS, 'identify.png'), fullPage: true });

  // A rapid through the stock: the collision's move is drawn in red over the 3-D stock.
  const stock = await api(base, '/v1/stocks', { kind: 'block', min: [0, 0, -10], max: [60, 40, 0] });
  const tool = await api(base, '/v1/tools', { type: 'flat', diameter_mm: 8, flutes: 3, helix_deg: 35, flute_length_mm: 20 });
  const crash = await submitJob({ kind: 'simulate', inputs: { program: { name: 'crash.nc', content: 'G21 G90\nT1 M6\nS10000 M3\nG0 X-10 Y20 Z10\nG0 Z-3\nG0 X70\nG0 Z10\nM88\nM30\n' }, stock: stock.id, tool: tool.id },
    options: { material: 'Al7075-T6' } });
  const cj = await waitJob(base, crash.id, 120);
  assert.equal(cj.status, 'succeeded', JSON.stringify(cj.error));
  const coll = cj.summary.collisions;
  log('collisions:', JSON.stringify(coll));
  assert.equal(coll.length, 1, 'one rapid through the stock (line 6)');
  assert.equal(coll[0].line, 6);
  assert.deepEqual([coll[0].from, coll[0].to], [[-10, 20, -3], [70, 20, -3]]);
  await page.goto(base + '/jobs/' + crash.id);
  await page.waitForSelector('#collisions');
  assert.match(await page.textContent('#collisions tbody tr'), /rapid_in_material.*-10\.00, 20\.00, -3\.00 → 70\.00, 20\.00, -3\.00/);
  // The interpreter's warning of the machine's own M88 (through-spindle coolant), with its line.
  assert.ok(cj.summary.program_warnings.some((w) => w.startsWith('8:1: M88')), JSON.stringify(cj.summary.program_warnings));
  assert.match(await page.textContent('[data-card="Program notes"]'), /^Program notes1.*8:1: M88 is not a standard M code/);
  await page.click('#load-stock');
  await page.waitForSelector('#stockinfo', { timeout: 60000 });
  const red = await glPixels(page, '#stock3d canvas', [0xd5, 0x00, 0x00]);
  log('3-D stock with the collision:', await page.textContent('#stockinfo'), '; red pixels', red.coloured);
  assert.ok(red.coloured > 200, 'the collision is not marked');
  await page.screenshot({ path: join(ARTIFACTS, 'collision.png'), fullPage: true });

  // A slot 1 mm into the design part: the gouge is listed where it is and marked in
  // magenta over the 3-D stock.
  const part = await api(base, '/v1/stocks', boxStl([0, 0, -10], [60, 40, -2]), { 'content-type': 'model/stl' });
  const gouging = await submitJob({ kind: 'simulate', inputs: { program: { name: 'gouge.nc', content: 'G21 G90\nT1 M6\nS10000 M3\nG0 X-10 Y20 Z5\nG0 Z-3\nG1 X40 F800\nG0 Z5\nM30\n' },
    stock: stock.id, tool: tool.id, part: part.id }, options: { material: 'Al7075-T6' } });
  const gj = await waitJob(base, gouging.id, 120);
  assert.equal(gj.status, 'succeeded', JSON.stringify(gj.error));
  const gp = gj.summary.part;
  log('gouges:', gp.gouge_regions, 'region(s):', JSON.stringify(gp.gouges));
  assert.equal(gp.gouge_regions, 1);
  await page.goto(base + '/jobs/' + gouging.id);
  await page.waitForSelector('#gouges');
  const grow = await page.$$eval('#gouges tbody tr', (trs) => trs.map((tr) => [...tr.children].map((td) => td.textContent)));
  assert.equal(grow.length, 1);
  assert.equal(grow[0][1], '1.000', 'the gouge is 1 mm deep: ' + grow[0]);
  const [gx, gy, gz] = grow[0][0].split(', ').map(Number);
  assert.ok(gx >= 0 && gx <= 44 && Math.abs(gy - 20) <= 0.5 && gz === -2.5, 'its deepest point is on the slot, halfway down the gouge: ' + grow[0]);
  await page.click('#load-stock');
  await page.waitForSelector('#stockinfo', { timeout: 60000 });
  const magenta = await glPixels(page, '#stock3d canvas', [0xd5, 0x00, 0xf9]);
  log('3-D stock with the gouge:', await page.textContent('#stockinfo'), '; magenta pixels', magenta.coloured);
  assert.match(await page.textContent('#stockinfo'), /1 gouge\(s\) marked in magenta/);
  assert.ok(magenta.coloured > 100, 'the gouge is not marked');
  await page.screenshot({ path: join(ARTIFACTS, 'gouge.png'), fullPage: true });

  assert.deepEqual(consoleErrors, [], 'console errors');
  assert.deepEqual(foreign, [], 'requests that left the server origin');
  await context.close();
  await browser.close();
  log('ok; screenshots in', ARTIFACTS);
}

run('kinds', main);
