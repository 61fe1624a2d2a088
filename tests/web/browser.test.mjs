// SPDX-License-Identifier: Apache-2.0
// Browser test of the page cylscand serves: starts the daemon on the quick
// fixture board, installs the fixture's calibration, opens the page in
// Debian's chromium (driven by playwright-core, no browser download), clicks
// Scan, waits for live progress and for the 3D viewer to show the cloud, and
// checks that nothing failed on the way and that the viewer drew something.
//
//   node browser.test.mjs --daemon PATH --fixture DIR --web-root DIR --out DIR [--token T]
//
// DIR of --fixture is the `quick_head` CTest fixture (board/, calib.bin,
// ready); --out receives screenshot.png (screenshot-token.png with --token).
// With --token the daemon asks for a bearer token: the page must ask for it,
// and, once it is typed in, send it with every request (event stream,
// previews and the cloud included). Exit status 0 only on success.
import { spawn } from 'node:child_process';
import { once } from 'node:events';
import { existsSync } from 'node:fs';
import { mkdir, mkdtemp, readFile, rm, writeFile } from 'node:fs/promises';
import { tmpdir } from 'node:os';
import { join, resolve } from 'node:path';
import { createInterface } from 'node:readline';
import { parseArgs } from 'node:util';
import { chromium } from 'playwright-core';
import { PNG } from 'pngjs';

const OVERALL_TIMEOUT_MS = 120_000;
const CHROMIUM = '/usr/bin/chromium';
// The viewer's clear colour (web/src/viewer.js BACKGROUND).
const BACKGROUND = [0x14, 0x18, 0x1f];
// Share of the viewer's pixels that must differ from the background: ~20k
// points of 2×2 px in a ~1100×480 canvas cover several percent of it.
const MIN_DRAWN_FRACTION = 0.005;

const { values: args } = parseArgs({
  options: {
    daemon: { type: 'string' },
    fixture: { type: 'string' },
    'web-root': { type: 'string' },
    out: { type: 'string' },
    token: { type: 'string' },
  },
});
for (const name of ['daemon', 'fixture', 'web-root', 'out']) {
  if (!args[name]) {
    console.error(`browser.test: --${name} is required`);
    process.exit(2);
  }
}

const cleanups = []; // run last first
const log = (...text) => console.log('browser.test:', ...text);

function fail(message) {
  throw new Error(message);
}

// Starts cylscand on port 0 and resolves with its base URL from the first line of stdout.
async function startDaemon(dataDir) {
  const argv = [
    '--board', join(args.fixture, 'board'),
    '--listen', '127.0.0.1:0',
    '--data', dataDir,
    '--web-root', resolve(args['web-root']),
  ];
  if (args.token) argv.push('--token', args.token);
  log(`starting ${args.daemon} ${argv.join(' ').replace(args.token || '\0', '***')}`);
  const daemon = spawn(args.daemon, argv, { stdio: ['ignore', 'pipe', 'pipe'] });
  let stderr = '';
  daemon.stderr.on('data', (chunk) => {
    stderr += chunk;
    process.stderr.write(chunk);
  });
  const exited = once(daemon, 'exit');
  cleanups.push(async () => {
    if (daemon.exitCode !== null || daemon.signalCode !== null) return;
    daemon.kill('SIGTERM');
    const timer = setTimeout(() => daemon.kill('SIGKILL'), 10_000);
    const [code, signal] = await exited;
    clearTimeout(timer);
    log(`cylscand stopped (exit ${code}${signal ? `, signal ${signal}` : ''})`);
    if (code !== 0) fail(`cylscand did not exit cleanly on SIGTERM: exit ${code} ${signal ?? ''}`);
  });
  const lines = createInterface({ input: daemon.stdout });
  const first = await Promise.race([
    once(lines, 'line').then(([line]) => line),
    exited.then(([code]) => fail(`cylscand exited (${code}) before listening:\n${stderr}`)),
    new Promise((_, reject) => setTimeout(() => reject(new Error('cylscand said nothing on stdout in 20 s')), 20_000)),
  ]);
  lines.on('line', (line) => log(`cylscand: ${line}`));
  const match = /^cylscand: listening on (http:\/\/127\.0\.0\.1:\d+)/.exec(first);
  if (!match) fail(`unexpected first line from cylscand: "${first}"`);
  return { base: match[1], daemon };
}

async function putCalibration(base) {
  const body = await readFile(join(args.fixture, 'calib.bin'));
  const response = await fetch(`${base}/api/v1/calibration`, {
    method: 'PUT',
    headers: {
      'Content-Type': 'application/octet-stream',
      ...(args.token ? { Authorization: `Bearer ${args.token}` } : {}),
    },
    body,
  });
  const text = await response.text();
  if (response.status !== 200) fail(`PUT /api/v1/calibration: ${response.status} ${text}`);
  log(`calibration installed (${body.length} bytes): ${text}`);
}

// Pixels inside `box` (CSS px of a full-page screenshot at scale 1) that differ from BACKGROUND.
function drawnFraction(png, box) {
  const x0 = Math.max(0, Math.round(box.x));
  const y0 = Math.max(0, Math.round(box.y));
  const x1 = Math.min(png.width, Math.round(box.x + box.width));
  const y1 = Math.min(png.height, Math.round(box.y + box.height));
  let drawn = 0;
  let total = 0;
  for (let y = y0; y < y1; y++) {
    for (let x = x0; x < x1; x++) {
      const i = (y * png.width + x) * 4;
      const d =
        Math.abs(png.data[i] - BACKGROUND[0]) +
        Math.abs(png.data[i + 1] - BACKGROUND[1]) +
        Math.abs(png.data[i + 2] - BACKGROUND[2]);
      if (d > 24) drawn++;
      total++;
    }
  }
  if (total === 0) fail(`the viewer's box ${JSON.stringify(box)} is outside the screenshot`);
  return drawn / total;
}

// Share of the pixels that differ between two same-sized images.
function changedFraction(a, b) {
  if (a.width !== b.width || a.height !== b.height) fail('viewer screenshots of different sizes');
  let changed = 0;
  for (let i = 0; i < a.data.length; i += 4) {
    const d = Math.abs(a.data[i] - b.data[i]) + Math.abs(a.data[i + 1] - b.data[i + 1]) + Math.abs(a.data[i + 2] - b.data[i + 2]);
    if (d > 24) changed++;
  }
  return changed / (a.width * a.height);
}

async function run() {
  if (!existsSync(join(args.fixture, 'ready'))) {
    fail(`the quick_head fixture is not ready: ${join(args.fixture, 'ready')} is missing (run the fixture.quick_head test)`);
  }
  if (!existsSync(join(args['web-root'], 'index.html'))) fail(`no page in ${args['web-root']} (build the "web" target)`);
  if (!existsSync(CHROMIUM)) fail(`${CHROMIUM} is missing (apt-get install chromium)`);

  const dataDir = await mkdtemp(join(tmpdir(), 'cylscan-web-data-'));
  const profileDir = await mkdtemp(join(tmpdir(), 'cylscan-web-chromium-'));
  cleanups.push(() => rm(dataDir, { recursive: true, force: true }));
  cleanups.push(() => rm(profileDir, { recursive: true, force: true }));

  const { base } = await startDaemon(dataDir);
  await putCalibration(base);

  // launchPersistentContext passes --user-data-dir=profileDir: a fresh profile.
  const context = await chromium.launchPersistentContext(profileDir, {
    executablePath: CHROMIUM,
    headless: true,
    args: [
      '--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync',
      // WebGL on the CPU (SwiftShader): --disable-gpu leaves no other way.
      '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    ],
    viewport: { width: 1280, height: 1400 },
    deviceScaleFactor: 1,
  });
  cleanups.push(() => context.close());
  const page = context.pages()[0] ?? (await context.newPage());

  const problems = [];
  // With --token, a 401 is expected for a request the page sent before the
  // token was submitted, and only for those: the page may still have such a
  // request in flight (the event stream's retry) when the token is typed in.
  // A 401 for a request that carried a token, or for one sent without it after
  // the token was given, is a problem.
  let tokenSubmitted = !args.token;
  const sentBeforeToken = new WeakSet();
  const unauthorized = [];
  page.on('pageerror', (error) => problems.push(`page error: ${error.message}`));
  page.on('console', (message) => {
    // The browser logs every refused request; the response handler below judges each one.
    if (message.type() === 'error' && args.token && /status of 401\b/.test(message.text())) log(`console error: ${message.text()}`);
    else if (message.type() === 'error') problems.push(`console error: ${message.text()}`);
    else log(`console ${message.type()}: ${message.text()}`);
  });
  page.on('request', (request) => {
    if (!tokenSubmitted) sentBeforeToken.add(request);
    if (!request.url().startsWith(`${base}/`) && !request.url().startsWith('blob:')) {
      problems.push(`request outside the head: ${request.url()}`);
    }
  });
  page.on('requestfailed', (request) => {
    problems.push(`request failed: ${request.method()} ${request.url()} (${request.failure()?.errorText})`);
  });
  page.on('response', (response) => {
    const request = response.request();
    const what = `HTTP ${response.status()}: ${request.method()} ${response.url()}`;
    const carriedToken = 'authorization' in request.headers();
    if (response.status() === 401 && args.token && !carriedToken && sentBeforeToken.has(request)) unauthorized.push(what);
    else if (response.status() === 401 && carriedToken) problems.push(`${what} (the request carried a token)`);
    else if (response.status() === 401 && args.token) problems.push(`${what} (sent without the token after it was given)`);
    else if (response.status() >= 400) problems.push(what);
  });

  await page.goto(`${base}/`, { waitUntil: 'load' });
  if (args.token) {
    await page.waitForSelector('#token-box:not([hidden])', { timeout: 15_000 });
    await page.waitForFunction(() => document.getElementById('connection').textContent === 'token needed', null, { timeout: 15_000 });
    log(`the page asks for a token (${unauthorized.length} requests refused with 401 so far)`);
    if (unauthorized.length === 0) problems.push('the token box is shown but no request was refused');
    await page.fill('#token-input', args.token);
    await page.click('#token-form button[type=submit]');
    tokenSubmitted = true;
    const stored = await page.evaluate(() => sessionStorage.getItem('cylscan.token'));
    if (stored !== args.token) problems.push('the token is not kept in sessionStorage');
    if (await page.isVisible('#token-box')) problems.push('the token box is still shown after the token was given');
  }
  await page.waitForFunction(() => document.getElementById('connection').textContent === 'live', null, { timeout: 15_000 });
  await page.waitForFunction(() => document.getElementById('st-calibration').textContent === 'installed', null, { timeout: 15_000 });
  const board = await page.textContent('#st-board');
  log(`page loaded, event stream live, board "${board}", calibration installed`);

  const clicked = Date.now();
  await page.click('#scan-button');
  await page.waitForFunction(() => Number(document.getElementById('progress-bar').value) > 0, null, { timeout: 60_000, polling: 50 });
  log(`progress shown after ${Date.now() - clicked} ms: ${await page.textContent('#progress-text')}`);

  await page.waitForFunction(() => window.cylscanViewer && window.cylscanViewer.pointCount > 1000, null, { timeout: 90_000 });
  const points = await page.evaluate(() => window.cylscanViewer.pointCount);
  log(`viewer shows ${points} points, ${Date.now() - clicked} ms after the click`);

  // The scan's row, its downloads and its previews.
  const row = await page.$eval('#scan-rows tr', (tr) => ({
    state: tr.querySelector('.state').textContent,
    links: [...tr.querySelectorAll('a')].map((a) => a.textContent),
  }));
  if (row.state !== 'done') problems.push(`the newest scan's row says "${row.state}", not done`);
  for (const file of ['cloud.ply', 'depth.tiff', 'texture.png']) {
    if (!row.links.includes(file)) problems.push(`no download link for ${file} (links: ${row.links.join(', ')})`);
  }
  await page.waitForFunction(
    () => ['img-texture', 'img-phase', 'img-depth'].every((id) => document.getElementById(id).naturalWidth > 0),
    null,
    { timeout: 15_000 },
  );

  // Let the renderer present its frame, then look at the pixels.
  await page.evaluate(() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done))));
  await mkdir(args.out, { recursive: true });
  const shotPath = join(args.out, args.token ? 'screenshot-token.png' : 'screenshot.png');
  const shot = await page.screenshot({ fullPage: true });
  await writeFile(shotPath, shot);
  const box = await (await page.$('#viewer')).boundingBox();
  const fraction = drawnFraction(PNG.sync.read(shot), box);
  log(`screenshot ${shotPath}: ${(fraction * 100).toFixed(2)} % of the viewer drawn`);
  if (!(fraction > MIN_DRAWN_FRACTION)) {
    problems.push(`the viewer looks blank: ${(fraction * 100).toFixed(3)} % of its pixels drawn (want > ${MIN_DRAWN_FRACTION * 100} %)`);
  }

  // The viewer reacts: colour by depth, then orbit with the mouse; each
  // changes a good share of the viewer's pixels.
  const viewerPixels = async () => PNG.sync.read(await page.locator('#viewer').screenshot());
  const before = await viewerPixels();
  await page.selectOption('#colour-mode', 'depth');
  const depthColoured = await viewerPixels();
  const centre = { x: box.x + box.width / 2, y: box.y + box.height / 2 };
  await page.mouse.move(centre.x, centre.y);
  await page.mouse.down();
  await page.mouse.move(centre.x + box.width / 4, centre.y + box.height / 8, { steps: 8 });
  await page.mouse.up();
  const orbited = await viewerPixels();
  const colourChange = changedFraction(before, depthColoured);
  const orbitChange = changedFraction(depthColoured, orbited);
  log(`colour by depth changed ${(colourChange * 100).toFixed(2)} %, orbiting ${(orbitChange * 100).toFixed(2)} % of the viewer`);
  if (!(colourChange > fraction / 4)) problems.push(`colouring by depth changed only ${(colourChange * 100).toFixed(3)} % of the viewer`);
  if (!(orbitChange > fraction / 4)) problems.push(`orbiting changed only ${(orbitChange * 100).toFixed(3)} % of the viewer`);

  if (problems.length > 0) fail(`${problems.length} problem(s):\n  ${problems.join('\n  ')}`);
}

async function cleanup() {
  let error = null;
  for (const step of cleanups.splice(0).reverse()) {
    try {
      await step();
    } catch (e) {
      error ??= e;
    }
  }
  if (error) throw error;
}

const deadline = setTimeout(async () => {
  console.error(`browser.test: FAILED: not done in ${OVERALL_TIMEOUT_MS / 1000} s`);
  await cleanup().catch(() => {});
  process.exit(1);
}, OVERALL_TIMEOUT_MS);

try {
  await run();
  await cleanup();
  clearTimeout(deadline);
  log('passed');
  process.exit(0);
} catch (error) {
  console.error(`browser.test: FAILED: ${error.message}`);
  await cleanup().catch((e) => console.error(`browser.test: cleanup: ${e.message}`));
  clearTimeout(deadline);
  process.exit(1);
}
