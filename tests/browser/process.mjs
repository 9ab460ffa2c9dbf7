// A process job's page in a real browser: a card per operation (cycle time before → after,
// removed volume, governing limits), the downloads of each operation's program and kept
// stock, and the per-block plots drawn in each operation's colour. The README's adaptive
// example as rough + the Ø2 finishing contour (examples/process). Run by
// tests/dashboard_browser.rs, or:
//   MILLSIM_BIN=$CARGO_TARGET_DIR/debug/millsim node tests/browser/process.mjs
import { join } from 'node:path';
import { readFileSync } from 'node:fs';
import assert from 'node:assert/strict';
import { ARTIFACTS, api, colourInk, exampleInputs, fmt, logger, openBrowser, root, run, startServer, waitJob } from './common.mjs';

const log = logger('process');

async function main() {
  const base = await startServer('process', ['--workers', '1']);
  const { browser, context, page, consoleErrors, foreign } = await openBrowser(base);
  const ex = await exampleInputs(base);
  const dir = join(root, 'examples', 'process');
  const finish = await api(base, '/v1/programs?name=finish_d2.nc', readFileSync(join(dir, 'finish_d2.nc')), { 'content-type': 'text/plain' });
  const d2 = await api(base, '/v1/tools', readFileSync(join(dir, 'tool_d2.json'), 'utf8'));
  const limits = (f) => ({ limits: { max_force: f, air_feed: 5000, max_feed: 5000 } });
  const job = await api(base, '/v1/jobs', { kind: 'process', inputs: { stock: ex.stock.id, machine: ex.machine.id, operations: [
    { name: 'rough', program: ex.program.id, T1: ex.tool.id, options: limits(400) },
    { name: 'finish', program: finish.id, T2: d2.id, options: limits(150) }] },
  options: { material: 'Al7075-T6', keep_stocks: true } });
  const done = await waitJob(base, job.id, 300);
  assert.equal(done.status, 'succeeded', JSON.stringify(done.error));
  const ops = done.summary.operations;
  log('operations:', ops.map((o) => o.name + ' ' + fmt(o.cycle_time_s, 1) + ' → ' + fmt(o.cycle_time_opt_s, 1) + ' s').join('; '));

  await page.goto(base + '/jobs/' + job.id);
  await page.waitForSelector('#operations [data-operation="2"]', { timeout: 60000 });
  for (const o of ops) {
    const text = await page.textContent('#operations [data-operation="' + o.operation + '"]');
    assert.ok(text.includes(o.name), text);
    // Cycle time before → after, as the summary says.
    assert.ok(text.includes(fmt(100 * (o.cycle_time_s - o.cycle_time_opt_s) / o.cycle_time_s, 1) + '% shorter'), text);
    assert.ok(text.includes(fmt(o.removed_volume_mm3, 0) + ' mm³'), text);
    const governing = o.optimization.tools.flatMap((t) => [...t.limited_by, ...t.limits_not_met].map((l) => l.limit + ' '));
    assert.ok(governing.length > 0);
    for (const g of governing) assert.ok(text.includes(g), g + ' not in ' + text);
  }
  const links = await page.$$eval('#downloads a', (as) => as.map((a) => a.getAttribute('href')));
  for (const want of ['/program?operation=1', '/program?operation=2', '/stock.stl', '/stock.stl?operation=1']) {
    assert.ok(links.some((h) => h.endsWith(want)), want + ' not among ' + links);
  }
  // The plots: both drawn, each operation's series in its own colour.
  await page.waitForSelector('[data-plot^="Peak cutting force"] canvas', { timeout: 60000 });
  await page.waitForSelector('[data-plot^="Feed"] canvas', { timeout: 60000 });
  const red = await colourInk(page, '[data-plot^="Feed"] canvas', '#c62828');
  const blue = await colourInk(page, '[data-plot^="Feed"] canvas', '#2463eb');
  log('feed plot ink: rough (red)', red.join(','), 'finish (blue)', blue.join(','));
  assert.ok(Math.max(...red) > 300, 'the rough is not drawn in its colour');
  assert.ok(Math.max(...blue) > 30, 'the finish is not drawn in its colour');
  const legend = await page.$$eval('[data-plot^="Feed"] .u-legend .u-series', (s) => s.map((e) => e.textContent));
  assert.ok(legend.some((t) => t.includes('1 · rough')) && legend.some((t) => t.includes('2 · finish')), legend.join('|'));
  await page.screenshot({ path: join(ARTIFACTS, 'process.png'), fullPage: true });

  assert.deepEqual(consoleErrors, [], 'console errors');
  assert.deepEqual(foreign, [], 'requests that left the server origin');
  await context.close();
  await browser.close();
  log('ok; screenshot in', ARTIFACTS);
}

run('process', main);
