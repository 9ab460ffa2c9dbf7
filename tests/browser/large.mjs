// A job of 10^5 blocks in the browser: how long its page takes to paint, load its rows and
// draw, and what zooming and panning its plots costs (each redraw of the five plots, and the
// gaps between animation frames while the mouse pans). Prints the figures; fails on a stall
// (a redraw or a frame gap over a second) or on a pan that does not move the plots.
//   MILLSIM_BIN=$CARGO_TARGET_DIR/debug/millsim node tests/browser/large.mjs
import { join } from 'node:path';
import assert from 'node:assert/strict';
import { ARTIFACTS, api, logger, openBrowser, run, startServer, waitJob } from './common.mjs';

const log = logger('large');
const BLOCKS = Number(process.env.LARGE_BLOCKS || 100000);

// Facing in layers of 1 mm (at least the 0.5 mm cell: a shallower cut is seen by the
// force model as no cut), passes 5 mm apart, each pass cut into 1 mm moves at feeds
// that vary along it (so the optimizer has something to change): BLOCKS moves in all.
function program() {
  const l = ['(10^5 blocks of facing)', 'G21 G90 G17', 'T1 M6', 'S12000 M3', 'G0 X-5 Y0 Z5'];
  let z = 0; let n = 0;
  while (n < BLOCKS) {
    z -= 1;
    l.push(`G0 X-5 Y0`, `G1 Z${z} F600`);
    for (let y = 0; y <= 100 && n < BLOCKS; y += 5) {
      l.push(`G1 Y${y} F800`);
      const dir = (y / 5) % 2 === 0 ? 1 : -1;
      for (let k = 1; k <= 110 && n < BLOCKS; k++, n++) l.push(`G1 X${dir > 0 ? k - 5 : 105 - k} F${Math.round(900 + 300 * Math.sin(k / 7))}`);
    }
    l.push('G0 Z5');
  }
  l.push('M30');
  return l.join('\n') + '\n';
}

const stats = (xs) => {
  if (!xs.length) return { n: 0, median: NaN, p95: NaN, max: NaN };
  const s = [...xs].sort((a, b) => a - b);
  const q = (p) => s[Math.min(s.length - 1, Math.floor(p * s.length))];
  return { n: s.length, median: +q(0.5).toFixed(1), p95: +q(0.95).toFixed(1), max: +s[s.length - 1].toFixed(1) };
};

async function main() {
  const base = await startServer('large', ['--workers', '1']);
  const text = program();
  const prog = await api(base, '/v1/programs?name=facing-1e5.nc', text, { 'content-type': 'text/plain' });
  const stock = await api(base, '/v1/stocks', { kind: 'block', min: [0, 0, -50], max: [100, 100, 0] });
  const tool = await api(base, '/v1/tools', { type: 'flat', diameter_mm: 8, flutes: 3, helix_deg: 35, flute_length_mm: 50 });
  const t0 = Date.now();
  const job = await api(base, '/v1/jobs', { kind: 'optimize', inputs: { program: prog.id, stock: stock.id, tool: tool.id },
    options: { material: 'Al7075-T6', cell_mm: 0.5, limits: { max_force: 300, air_feed: 5000, max_feed: 3000 } } });
  const done = await waitJob(base, job.id, 1500);
  assert.equal(done.status, 'succeeded', JSON.stringify(done.error));
  assert.ok(done.summary.force_peak_n > 0, 'the job has no force to plot');
  log('peak force', done.summary.force_peak_n.toFixed(1), 'N; job of', done.summary.moves, 'moves (', text.split('\n').length, 'lines) ran in', ((Date.now() - t0) / 1000).toFixed(1), 's');

  const { browser, page, consoleErrors, foreign } = await openBrowser(base);
  await page.goto(base + '/jobs/' + job.id);
  try {
    await page.waitForFunction(() => performance.getEntriesByName('plots-drawn').length > 0, null, { timeout: 300000 });
  } catch (e) {
    log('the plots were not drawn; the page says:', await page.textContent('#rowstatus').catch(() => '?'), '; console errors:', consoleErrors.join(' | '));
    throw e;
  }
  const at = (name) => page.evaluate((n) => Math.round((performance.getEntriesByName(n)[0] || {}).startTime || -1), name);
  const paint = { fcp: await at('first-contentful-paint'), cards: await at('cards-shown'), rows: await at('rows-loaded'), plots: await at('plots-drawn') };
  const requests = await page.evaluate(() => performance.getEntriesByType('resource').filter((r) => r.name.includes('/v1/'))
    .map((r) => r.name.replace(/^.*\/v1\//, '').slice(0, 50) + ': ' + Math.round(r.responseStart - r.startTime) + ' ms to the first byte, ' + Math.round(r.duration) + ' ms in all, ' + Math.round(r.transferSize / 1024) + ' KiB'));
  log('API requests:', requests.join('; '));
  log('page of 10^5 blocks, ms since navigation: first contentful paint', paint.fcp, '; cards', paint.cards, '; rows loaded (one CSV request)', paint.rows, '; plots drawn', paint.plots);
  assert.ok(paint.fcp > 0 && paint.fcp < 1000, 'first paint ' + paint.fcp + ' ms');

  // Frame gaps and redraws from here on.
  await page.evaluate(() => {
    window.__gaps = [];
    let last = performance.now();
    const tick = (t) => { window.__gaps.push(t - last); last = t; if (!window.__stop) requestAnimationFrame(tick); };
    requestAnimationFrame(tick);
    performance.clearMeasures('plots-redraw');
  });
  const phase = async (name, act) => {
    await page.evaluate(() => { window.__gaps.length = 0; performance.clearMeasures('plots-redraw'); });
    const x0 = await page.getAttribute('[data-plot="Torque"]', 'data-x');
    await act();
    await page.waitForTimeout(200);
    const r = await page.evaluate(() => ({ gaps: window.__gaps.slice(1), redraws: performance.getEntriesByName('plots-redraw').map((m) => m.duration) }));
    const x1 = await page.getAttribute('[data-plot="Torque"]', 'data-x');
    const g = stats(r.gaps); const d = stats(r.redraws);
    log(`${name}: ${d.n} redraws of 5 plots, ms: median ${d.median}, p95 ${d.p95}, max ${d.max}; ${g.n} frames, gap ms: median ${g.median}, p95 ${g.p95}, max ${g.max}; x ${x0} -> ${x1}`);
    assert.notEqual(x0, x1, name + ' did not move the plots');
    assert.ok(d.n > 0, name + ': no redraw');
    assert.ok(d.max < 1000 && g.max < 1000, name + ': a stall over a second');
    return { redraw: d, gaps: g };
  };
  let bb; let y;
  const aim = async () => {
    await page.$eval('[data-plot="Cutting force"]', (e) => e.scrollIntoView());
    bb = await (await page.$('[data-plot="Cutting force"] .u-over')).boundingBox();
    y = bb.y + bb.height / 2;
  };
  await aim();
  await page.mouse.move(bb.x + bb.width * 0.5, y);
  const results = {};
  results.zoomIn = await phase('wheel zoom in (20 notches, all 10^5 rows to 4%)', async () => { for (let i = 0; i < 20; i++) { await page.mouse.wheel(0, -110); await page.waitForTimeout(16); } });
  const pan = async () => {
    await page.keyboard.down('Shift');
    await page.mouse.move(bb.x + bb.width * 0.9, y);
    await page.mouse.down();
    await page.mouse.move(bb.x + bb.width * 0.1, y, { steps: 60 });
    await page.mouse.up();
    await page.keyboard.up('Shift');
  };
  results.pan = await phase('shift-drag pan across 80% of the width', pan);
  results.zoomOut = await phase('wheel zoom out (20 notches)', async () => { for (let i = 0; i < 20; i++) { await page.mouse.wheel(0, 110); await page.waitForTimeout(16); } });
  results.panWide = await phase('pan at 10^5 rows less a third', async () => {
    for (let i = 0; i < 3; i++) { await page.mouse.wheel(0, -90); await page.waitForTimeout(16); }
    await page.mouse.move(bb.x + bb.width * 0.5, y);
    await pan();
  });
  await page.screenshot({ path: join(ARTIFACTS, 'large-job.png'), fullPage: false });

  // Against cycle time: the before and after series are merged onto one axis (2×10^5 x).
  await page.check('#xmode input[value=time]');
  await page.waitForSelector('[data-plot="Cutting force"] .title:has-text("against cycle time")');
  await aim();
  await page.mouse.move(bb.x + bb.width * 0.5, y);
  results.timeZoom = await phase('cycle time: wheel zoom in (10 notches)', async () => { for (let i = 0; i < 10; i++) { await page.mouse.wheel(0, -110); await page.waitForTimeout(16); } });
  results.timePan = await phase('cycle time: shift-drag pan', pan);
  await page.evaluate(() => { window.__stop = true; });
  await page.screenshot({ path: join(ARTIFACTS, 'large-job-time.png'), fullPage: false });
  console.log('LARGE-JOB-FIGURES ' + JSON.stringify({ blocks: done.summary.moves, paint, ...results }));
  assert.deepEqual(consoleErrors, [], 'console errors');
  assert.deepEqual(foreign, [], 'requests that left the server origin');
  await browser.close();
}

run('large', main);
