// What the browser tests share: the real `millsim serve` on 127.0.0.1:0 with a temporary
// SQLite database, the API from node, Debian's chromium through playwright-core (never a
// downloaded browser) with every console error and every request leaving the origin
// recorded, and pixel counts of drawn canvases.
import { spawn } from 'node:child_process';
import { mkdtempSync, mkdirSync, rmSync, readFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, dirname } from 'node:path';
import { fileURLToPath } from 'node:url';
import { createInterface } from 'node:readline';
import assert from 'node:assert/strict';
import { chromium } from 'playwright-core';

const here = dirname(fileURLToPath(import.meta.url));
export const root = join(here, '..', '..');
export const BIN = process.env.MILLSIM_BIN || join(root, 'target', 'debug', 'millsim');
const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';
export const ARTIFACTS = join(here, 'artifacts');
mkdirSync(ARTIFACTS, { recursive: true });
export const work = mkdtempSync(join(tmpdir(), 'millsim-dash-'));
const children = [];

export function logger(tag) { return (...a) => console.log('[' + tag + ']', ...a); }

export function spawnMillsim(args) {
  const child = spawn(BIN, args, { stdio: ['ignore', 'pipe', 'inherit'], env: { ...process.env, RUST_LOG: 'warn' } });
  children.push(child);
  return child;
}

export const dbUrl = (name) => `sqlite://${join(work, name + '.db')}`;

export async function startServer(name, extra) {
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

export async function api(base, path, body, headers) {
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

export async function waitJob(base, id, seconds) {
  const t0 = Date.now();
  for (;;) {
    const j = await api(base, '/v1/jobs/' + id);
    if (!['queued', 'running'].includes(j.status)) return j;
    assert.ok(Date.now() - t0 < seconds * 1000, `job ${id} still ${j.status} after ${seconds} s`);
    await new Promise((r) => setTimeout(r, 200));
  }
}

// The example job's inputs (examples/adaptive: the Fusion 360 adaptive roughing program).
export async function exampleInputs(base) {
  const ex = join(root, 'examples', 'adaptive');
  return {
    program: await api(base, '/v1/programs?name=1055_utab_265bit.nc', readFileSync(join(ex, '1055_utab_265bit.nc')), { 'content-type': 'text/plain' }),
    stock: await api(base, '/v1/stocks', readFileSync(join(ex, 'stock.json'), 'utf8')),
    tool: await api(base, '/v1/tools', readFileSync(join(ex, 'tool.json'), 'utf8')),
    machine: await api(base, '/v1/machines', readFileSync(join(ex, 'machine.json'), 'utf8')),
  };
}

// A browser context that records console errors and requests to other origins.
export async function openBrowser(base) {
  const browser = await chromium.launch({ executablePath: CHROMIUM, args: ['--no-sandbox', '--disable-background-networking'] });
  const context = await browser.newContext({ viewport: { width: 1300, height: 900 } });
  const page = await context.newPage();
  const consoleErrors = [];
  const foreign = [];
  page.on('console', (m) => { if (m.type() === 'error') consoleErrors.push(m.text() + ' at ' + (m.location().url || '?')); });
  page.on('pageerror', (e) => consoleErrors.push(String(e)));
  context.on('request', (r) => { const u = r.url(); if (!u.startsWith(base + '/') && !u.startsWith('blob:') && !u.startsWith('data:')) foreign.push(u); });
  return { browser, context, page, consoleErrors, foreign };
}

// Pixels drawn on 2-D canvases (uPlot), one count per canvas.
export async function canvasInk(page, selector) {
  return page.$$eval(selector, (canvases) => canvases.map((c) => {
    const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    let ink = 0;
    for (let i = 3; i < d.length; i += 4) if (d[i] > 0) ink++;
    return ink;
  }));
}

// Pixels of a series' colour (hex, within 40 per channel) on each 2-D canvas matching
// selector: a plot whose grid and axes are drawn but whose line is not has none.
export async function colourInk(page, selector, hex) {
  const rgb = [1, 3, 5].map((i) => parseInt(hex.slice(i, i + 2), 16));
  return page.$$eval(selector, (canvases, rgb) => canvases.map((c) => {
    const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    let n = 0;
    for (let i = 0; i < d.length; i += 4) if (d[i + 3] > 200 && Math.abs(d[i] - rgb[0]) < 40 && Math.abs(d[i + 1] - rgb[1]) < 40 && Math.abs(d[i + 2] - rgb[2]) < 40) n++;
    return n;
  }), rgb);
}

// A WebGL canvas (drawn with preserveDrawingBuffer): pixels off the clear colour, pixels
// of a given colour (within 40 per channel), and a checksum to see the picture change.
export async function glPixels(page, selector, rgb) {
  return page.$eval(selector, (c, rgb) => {
    const t = document.createElement('canvas'); t.width = c.width; t.height = c.height;
    const g = t.getContext('2d'); g.drawImage(c, 0, 0);
    const d = g.getImageData(0, 0, t.width, t.height).data;
    let shape = 0; let sum = 0; let coloured = 0;
    for (let i = 0; i < d.length; i += 4) {
      if (Math.abs(d[i] - 0xf4) + Math.abs(d[i + 1] - 0xf6) + Math.abs(d[i + 2] - 0xf9) > 24) shape++;
      if (rgb && Math.abs(d[i] - rgb[0]) < 40 && Math.abs(d[i + 1] - rgb[1]) < 40 && Math.abs(d[i + 2] - rgb[2]) < 40) coloured++;
      sum = (sum + d[i] * 7 + d[i + 1] * 13 + d[i + 2] * 17 + i) % 1000000007;
    }
    return { shape, total: d.length / 4, sum, coloured };
  }, rgb || null);
}

// A box from a to b as an ASCII STL (faces wound outwards).
export function boxStl(a, b) {
  const p = (i, j, k) => [i ? b[0] : a[0], j ? b[1] : a[1], k ? b[2] : a[2]];
  const faces = [
    [[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]], [[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    [[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], [[0, 1, 0], [0, 1, 1], [1, 1, 1], [1, 1, 0]],
    [[0, 0, 0], [0, 0, 1], [0, 1, 1], [0, 1, 0]], [[1, 0, 0], [1, 1, 0], [1, 1, 1], [1, 0, 1]],
  ];
  const tri = (q) => ' facet normal 0 0 0\n  outer loop\n' + q.map((v) => '   vertex ' + p(...v).join(' ') + '\n').join('') + '  endloop\n endfacet\n';
  return 'solid part\n' + faces.map((f) => tri([f[0], f[1], f[2]]) + tri([f[0], f[2], f[3]])).join('') + 'endsolid part\n';
}

export const fmt = (x, d) => Number(x).toLocaleString('en-US', { minimumFractionDigits: d, maximumFractionDigits: d });
export const esc = (s) => s.replace(/[.,]/g, '\\$&');

// Runs main, then stops every process it started and removes the temporary folder.
export async function run(tag, main) {
  let code = 0;
  try {
    await main();
  } catch (e) {
    console.error('[' + tag + '] FAILED:', e);
    code = 1;
  } finally {
    for (const c of children) c.kill('SIGTERM');
    rmSync(work, { recursive: true, force: true });
  }
  process.exit(code);
}
