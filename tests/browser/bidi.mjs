// Names with bidi controls (issue 34): a program and a tool whose names carry a right-to-left
// override are shown with the control written out ([U+202E]) on the job list, the job's page
// and the new-job form, so the rest of the line keeps its order. Run by
// tests/dashboard_browser.rs, or alone:
//   MILLSIM_BIN=$CARGO_TARGET_DIR/debug/millsim node tests/browser/bidi.mjs
import assert from 'node:assert/strict';
import { api, logger, openBrowser, run, startServer, waitJob } from './common.mjs';

const log = logger('bidi');
const CONTROLS = /[\u200E\u200F\u202A-\u202E\u2066-\u2069]/;

async function main() {
  const base = await startServer('bidi', ['--workers', '1']);
  const name = 'report\u202Ecn.exe';
  const job = await api(base, '/v1/jobs', { kind: 'interpret', inputs: { program: { name, content: 'G0 X1\nM30\n' } } });
  await waitJob(base, job.id, 30);
  await api(base, '/v1/tools?name=' + encodeURIComponent('end\u2067mill\u2069\u200F'), { type: 'flat', diameter_mm: 8, flutes: 3, helix_deg: 35, flute_length_mm: 20 });
  const { browser, context, page, consoleErrors } = await openBrowser(base);
  const shown = async (selector) => {
    await page.waitForFunction((s) => { const e = document.querySelector(s); return e && e.textContent.includes('report'); }, selector);
    return page.textContent(selector);
  };
  // The list: the program's name is filled in after the row is drawn (textContent).
  await page.goto(base + '/');
  const listed = await shown(`tr[data-id="${job.id}"] td.prog a`);
  log('list shows', JSON.stringify(listed));
  assert.doesNotMatch(listed, CONTROLS);
  assert.equal(listed, 'report[U+202E]cn.exe');
  // The job's page.
  await page.goto(base + '/jobs/' + job.id);
  const heading = await shown('#progname');
  assert.doesNotMatch(heading, CONTROLS);
  assert.equal(heading, 'report[U+202E]cn.exe');
  // The form's stored tools.
  await page.goto(base + '/?new=1');
  await page.waitForSelector('select[name=tool_choice] option', { state: 'attached' });
  const options = await page.$$eval('select[name=tool_choice] option', (os) => os.map((o) => o.textContent));
  const tool = options.find((o) => o.includes('end'));
  log('tool option', JSON.stringify(tool));
  assert.ok(tool, JSON.stringify(options));
  assert.doesNotMatch(tool, CONTROLS);
  assert.ok(tool.includes('end[U+2067]mill[U+2069][U+200F]'), tool);
  assert.deepEqual(consoleErrors, [], 'console errors');
  await context.close();
  await browser.close();
}

run('bidi', main);
