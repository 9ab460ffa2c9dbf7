// A process job's page in a real browser: a card per operation (cycle time before → after,
// removed volume, governing limits), the downloads of each operation's program and kept
// stock, and the per-block plots drawn in each operation's colour. The README's adaptive
// example as rough + the Ø2 finishing contour (examples/process); then the same two
// operations through the new-job form (refused first naming the field of the one without a
// program, then run: a card per operation). Run by
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

  // The new-job form: the same two operations picked in order (the rough's program stored,
  // the finish's uploaded, each tool by its T number), first without the finish's program
  // (the server's problem names the field), then submitted; the page follows the job.
  await page.goto(base + '/?new=1');
  await page.selectOption('form#new-job select[name=kind]', 'process');
  await page.waitForSelector('form#new-job .operation[data-operation="1"]');
  await page.selectOption('form#new-job select[name=stock_choice]', ex.stock.id);
  await page.selectOption('form#new-job select[name=machine_choice]', ex.machine.id);
  await page.selectOption('form#new-job select[name=material]', 'builtin:Al7075-T6');
  const op = (n, what) => 'form#new-job .operation[data-operation="' + n + '"] ' + what;
  await page.fill(op(1, 'input[name=op_name]'), 'rough');
  await page.selectOption(op(1, 'select[name=program_choice]'), ex.program.id);
  await page.click(op(1, 'button.add-tnumber'));
  await page.fill(op(1, 'input[name=t_number]'), '1');
  await page.selectOption(op(1, 'select[name=t_tool]'), ex.tool.id);
  await page.fill(op(1, 'input[name=max_force]'), '400');
  await page.fill(op(1, 'input[name=max_feed]'), '5000');
  await page.click('#add-operation');
  await page.fill(op(2, 'input[name=op_name]'), 'finish');
  await page.click(op(2, 'button.add-tnumber'));
  await page.fill(op(2, 'input[name=t_number]'), '2');
  await page.selectOption(op(2, 'select[name=t_tool]'), d2.id);
  await page.selectOption(op(2, 'select[name=mode]'), 'simulate');
  assert.ok(!(await page.isVisible(op(2, 'input[name=max_force]'))), 'a simulated operation shows no limits');
  // A fixture block well clear of the paths (one setup: options.fixture), after a look at
  // the cylinder's fields.
  await page.click('#add-fixture-body');
  await page.selectOption('#fixture-bodies select[name=body_kind]', 'cylinder');
  assert.ok(await page.isVisible('#fixture-bodies input[name=radius]'));
  assert.ok(!(await page.isVisible('#fixture-bodies input[name=body_min_x]')));
  await page.selectOption('#fixture-bodies select[name=body_kind]', 'block');
  await page.fill('#fixture-bodies input[name=body_name]', 'vise');
  for (const [k, v] of Object.entries({ body_min_x: 300, body_min_y: 300, body_min_z: -60, body_max_x: 310, body_max_y: 310, body_max_z: -50 })) {
    await page.fill('#fixture-bodies input[name=' + k + ']', String(v));
  }
  await page.click('form#new-job button[type=submit]');
  await page.waitForSelector('#form-result #problem');
  assert.equal(await page.textContent('#form-result #problem dd[data-field="field"]'), 'inputs.operations[1].program');
  // That refusal's 422 is the one console error the page may log (the browser's own line).
  const refused = consoleErrors.findIndex((e) => /status of 422 .* at .*\/v1\/jobs$/.test(e));
  assert.ok(refused >= 0, consoleErrors.join(' | '));
  consoleErrors.splice(refused, 1);
  await page.screenshot({ path: join(ARTIFACTS, 'process-form-refused.png'), fullPage: true });
  await page.setInputFiles(op(2, 'input[name=program]'), { name: 'finish_d2.nc', mimeType: 'text/plain', buffer: readFileSync(join(dir, 'finish_d2.nc')) });
  await page.screenshot({ path: join(ARTIFACTS, 'process-form.png'), fullPage: true });
  await page.click('form#new-job button[type=submit]');
  await page.waitForURL(/\/jobs\/[^/]+$/, { timeout: 60000 });
  const formId = decodeURIComponent(new URL(page.url()).pathname.split('/').pop());
  const formJob = await waitJob(base, formId, 300);
  assert.equal(formJob.status, 'succeeded', JSON.stringify(formJob.error));
  assert.equal(formJob.kind, 'process');
  // What the form sent, as the job record stores it.
  assert.equal(formJob.inputs['op1.program'], ex.program.id, JSON.stringify(formJob.inputs));
  assert.equal(formJob.inputs['op1.T1'], ex.tool.id);
  assert.equal(formJob.inputs['op2.T2'], d2.id);
  assert.ok(formJob.inputs['op2.program'], JSON.stringify(formJob.inputs));
  assert.deepEqual(formJob.options.operations.map((o) => o.name), ['rough', 'finish']);
  assert.deepEqual(formJob.options.fixture, { bodies: [{ name: 'vise', kind: 'block', min: [300, 300, -60], max: [310, 310, -50] }] });
  assert.equal(formJob.options.material, 'Al7075-T6');
  assert.equal(formJob.inputs.machine, ex.machine.id);
  assert.deepEqual(formJob.options.operations[0].options.limits, { max_force: 400, air_feed: 5000, max_feed: 5000 });
  const formOps = formJob.summary.operations;
  assert.deepEqual(formOps.map((o) => [o.name, o.optimized]), [['rough', true], ['finish', false]]);
  // The rough as the API's (same inputs, same limits); the finish simulated, not optimized.
  assert.equal(formOps[0].cycle_time_opt_s, ops[0].cycle_time_opt_s);
  assert.equal(formOps[1].cycle_time_s, ops[1].cycle_time_s);
  await page.waitForSelector('#operations [data-operation="2"]', { timeout: 60000 });
  assert.ok((await page.textContent('#operations [data-operation="1"]')).includes('1 · rough'));
  const finishCard = await page.textContent('#operations [data-operation="2"]');
  assert.ok(finishCard.includes('2 · finish') && finishCard.includes('simulated (no limits)'), finishCard);
  log('form process', formId, formOps.map((o) => o.name + (o.optimized ? ' optimized' : ' simulated')).join(', '));

  assert.deepEqual(consoleErrors, [], 'console errors');
  assert.deepEqual(foreign, [], 'requests that left the server origin');
  await context.close();
  await browser.close();
  log('ok; screenshot in', ARTIFACTS);
}

run('process', main);
