// Cross-site requests (issue 34): a page of another origin (a second server on loopback) that a
// CAM-station user opens tries, from Chromium, what the campaign did: register a webhook to
// itself with JSON sent as text/plain (no preflight), submit a job, upload a program. The server
// refuses each (403 cross-origin-refused, seen by the server: nothing is stored). A server told
// `--cors-origin` that origin accepts the same page's JSON request. Run by
// tests/dashboard_browser.rs, or alone:
//   MILLSIM_BIN=$CARGO_TARGET_DIR/debug/millsim node tests/browser/cross_origin.mjs
import assert from 'node:assert/strict';
import { createServer } from 'node:http';
import { api, logger, openBrowser, run, startServer } from './common.mjs';

const log = logger('cross-origin');

// A page on its own origin (another port of 127.0.0.1).
async function foreignSite() {
  const server = createServer((req, res) => {
    res.writeHead(200, { 'content-type': 'text/html' });
    res.end('<!doctype html><title>another site</title><p>hello</p>');
  });
  await new Promise((r) => server.listen(0, '127.0.0.1', r));
  return { server, origin: 'http://127.0.0.1:' + server.address().port };
}

// What the page tries: each request's outcome as the page sees it (an opaque or failed
// answer: the browser does not let another origin read it).
async function attempts(page, base) {
  return page.evaluate(async (base) => {
    const out = [];
    const tries = [
      ['/v1/webhooks', 'text/plain', JSON.stringify({ url: 'http://127.0.0.1:9/hook', events: ['job.succeeded'] })],
      ['/v1/jobs', 'text/plain', JSON.stringify({ kind: 'interpret', inputs: { program: { name: 'x.nc', content: 'G0 X1\n' } } })],
      ['/v1/programs?name=evil.nc', 'text/plain', 'G0 X1\n'],
    ];
    for (const [path, type, body] of tries) {
      try {
        const r = await fetch(base + path, { method: 'POST', mode: 'no-cors', headers: { 'content-type': type }, body });
        out.push(path + ': ' + r.type);
      } catch (e) {
        out.push(path + ': ' + e.name);
      }
    }
    return out;
  }, base);
}

async function main() {
  const site = await foreignSite();
  try {
    const base = await startServer('cross-origin', ['--workers', '0']);
    const { browser, page } = await openBrowser(base);
    try {
      await page.goto(site.origin + '/');
      log('page of', site.origin, 'tries', await attempts(page, base));
      // The server saw them and stored nothing.
      assert.equal((await api(base, '/v1/webhooks')).items.length, 0, 'a webhook was registered from another site');
      assert.equal((await api(base, '/v1/jobs')).items.length, 0, 'a job was submitted from another site');
      assert.equal((await api(base, '/v1/programs')).items.length, 0, 'a program was uploaded from another site');
      // Direct: the same request with the page's Origin is a 403 naming the reason.
      const r = await fetch(base + '/v1/jobs', { method: 'POST', headers: { origin: site.origin, 'content-type': 'application/json' }, body: '{}' });
      assert.equal(r.status, 403);
      assert.match(await r.text(), /cross-origin/);

      // Allowed with --cors-origin: the page's JSON request (with its preflight) is answered.
      const allowed = await startServer('cross-origin-allowed', ['--workers', '0', '--cors-origin', site.origin]);
      const status = await page.evaluate(async (base) => {
        const r = await fetch(base + '/v1/programs?name=ok.nc', { method: 'POST', headers: { 'content-type': 'text/plain' }, body: 'G0 X1\n' });
        return r.status;
      }, allowed);
      log('allowed origin, upload status', status);
      assert.equal(status, 201);
      assert.equal((await api(allowed, '/v1/programs')).items.length, 1);
    } finally {
      await browser.close();
    }
  } finally {
    site.server.close();
  }
}

run('cross-origin', main);
