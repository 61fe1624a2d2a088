// SPDX-License-Identifier: Apache-2.0
// Browser test of the page cylscand serves: starts the daemon on the quick
// fixture board, installs the fixture's calibration, opens the page in
// Debian's chromium (driven by playwright-core, no browser download), clicks
// Scan, waits for live progress and for the 3D viewer to show the cloud,
// drives the Set-up view (the cameras' live views and settings, a fringe
// check of the exposure, then a check against the scene's sphere), and checks
// that nothing failed on the way and that the viewer drew something.
//
// With --flow calibration it takes an uncalibrated head through its whole
// calibration from the page alone instead (runCalibration below): the live
// view and its exposure, a session with every shipped target pose, the solve,
// the install, a scan, a check that passes, and the roll back.
//
//   node browser.test.mjs --daemon PATH --fixture DIR --web-root DIR --out DIR [--token T] [--flow calibration]
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

// The whole of a flow, daemon and browser included. The calibration flow
// waits for every board pair the virtual head ships (96: from ~1.2 s each to
// ~5 s, as the daemon fits its guidance to all the pairs kept after each
// one), 14 plane poses (~1.5 s each) and the solve (~30–60 s): ~5 minutes.
const OVERALL_TIMEOUT_MS = { scan: 120_000, calibration: 540_000 };
const CHROMIUM = '/usr/bin/chromium';
// The viewer's clear colour (web/src/viewer.js BACKGROUND).
const BACKGROUND = [0x14, 0x18, 0x1f];
// Share of the viewer's pixels that must differ from the background: ~20k
// points of 2×2 px in a ~1100×480 canvas cover several percent of it.
const MIN_DRAWN_FRACTION = 0.005;
// Where the page shows that something went wrong: its message lines
// (`.message.error`, `.message.warn`), every other `.error` element (the
// head's last error, the viewer's line, a preview's caption, the set-up
// view's messages), the state of a failed scan and any alert.
const ERROR_SELECTOR = '.error, .message.warn, .state-error, .state-failed, [role=alert]';

const { values: args } = parseArgs({
  options: {
    daemon: { type: 'string' },
    fixture: { type: 'string' },
    'web-root': { type: 'string' },
    out: { type: 'string' },
    token: { type: 'string' },
    flow: { type: 'string', default: 'scan' },
  },
});
if (!(args.flow in OVERALL_TIMEOUT_MS)) {
  console.error(`browser.test: --flow is one of ${Object.keys(OVERALL_TIMEOUT_MS).join(', ')}`);
  process.exit(2);
}
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

// Runs in the page before its own scripts (context.addInitScript): keeps in
// window.cylscanShownErrors every error text the page shows, however briefly
// (a message replaced a moment later is still one the user saw). The
// viewer's line is checked by its text as well, so that an error shown there
// without the error class still counts.
function recordShownErrors(selector) {
  const shown = [];
  const seen = new Set();
  window.cylscanShownErrors = shown;
  const note = (node, text) => {
    const key = `${node.id ? `#${node.id}` : `${node.localName}.${[...node.classList].join('.')}`}: ${text}`;
    if (seen.has(key)) return;
    seen.add(key);
    shown.push(key);
  };
  const look = () => {
    for (const node of document.querySelectorAll(selector)) {
      const text = node.textContent.trim();
      if (text && node.checkVisibility()) note(node, text);
    }
    const info = document.getElementById('viewer-info');
    if (info && /^Point cloud:/.test(info.textContent) && info.checkVisibility()) note(info, info.textContent.trim());
  };
  new MutationObserver(look).observe(document, {
    subtree: true,
    childList: true,
    characterData: true,
    attributes: true,
    attributeFilter: ['class', 'hidden', 'role'],
  });
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

// The checks every flow starts with: the fixture, the page, chromium.
function checkInputs() {
  if (!existsSync(join(args.fixture, 'ready'))) {
    fail(`the quick_head fixture is not ready: ${join(args.fixture, 'ready')} is missing (run the fixture.quick_head test)`);
  }
  if (!existsSync(join(args['web-root'], 'index.html'))) fail(`no page in ${args['web-root']} (build the "web" target)`);
  if (!existsSync(CHROMIUM)) fail(`${CHROMIUM} is missing (apt-get install chromium)`);
}

// A fresh data directory, removed at the end.
async function freshDataDir() {
  const dataDir = await mkdtemp(join(tmpdir(), 'cylscan-web-data-'));
  cleanups.push(() => rm(dataDir, { recursive: true, force: true }));
  return dataDir;
}

// Chromium on a fresh profile with the page's error recorder, and the
// watchers that turn whatever goes wrong into `problems`: page errors,
// console errors (with the URL of a refused request), requests outside the
// head or failed, and HTTP errors. `expected` takes RegExps of problems a
// step provokes on purpose. With --token, 401s are judged as described below.
async function openBrowser(base) {
  const profileDir = await mkdtemp(join(tmpdir(), 'cylscan-web-chromium-'));
  cleanups.push(() => rm(profileDir, { recursive: true, force: true }));

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
  await context.addInitScript(recordShownErrors, ERROR_SELECTOR);
  const page = context.pages()[0] ?? (await context.newPage());

  const problems = [];
  // Problems a step provokes on purpose (a refused setting), each a RegExp.
  const expected = [];
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
    const url = message.location()?.url;
    const text = `${message.text()}${url ? ` (${url})` : ''}`;
    if (message.type() === 'error' && args.token && /status of 401\b/.test(message.text())) log(`console error: ${text}`);
    else if (message.type() === 'error') problems.push(`console error: ${text}`);
    else log(`console ${message.type()}: ${text}`);
  });
  page.on('request', (request) => {
    if (!tokenSubmitted) sentBeforeToken.add(request);
    if (!request.url().startsWith(`${base}/`) && !request.url().startsWith('blob:')) {
      problems.push(`request outside the head: ${request.url()}`);
    }
  });
  page.on('requestfailed', (request) => {
    // The page closes a camera's live stream itself when its view is left or
    // the overlay changes: that stream alone may end aborted.
    const errorText = request.failure()?.errorText;
    if (errorText === 'net::ERR_ABORTED' && /\/stream\.mjpg(\?|$)/.test(request.url())) return;
    problems.push(`request failed: ${request.method()} ${request.url()} (${errorText})`);
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
  // The Set-up view asks for the calibration session; a head without one
  // answers 404, which is how it says so.
  expected.push(
    /^HTTP 404: GET .*\/api\/v1\/calibration\/session$/,
    /^console error: .*status of 404.*\(http:\/\/127\.0\.0\.1:\d+\/api\/v1\/calibration\/session\)$/,
  );
  return { page, problems, expected, tokenGiven: () => (tokenSubmitted = true), unauthorized };
}

// The problems the flow met, less those expected, and the error texts the
// page showed: the test fails on any.
async function judge(page, problems, expected) {
  const shown = await page.evaluate(() => ({ errors: window.cylscanShownErrors ?? null, viewer: window.cylscanViewer?.error ?? null }));
  if (shown.errors === null) problems.push('the error recorder did not run in the page');
  for (const text of shown.errors ?? []) problems.push(`error shown in the page: ${text}`);
  if (shown.viewer) problems.push(`viewer error: ${shown.viewer}`);
  const unexpected = problems.filter((problem) => !expected.some((pattern) => pattern.test(problem)));
  if (unexpected.length > 0) fail(`${unexpected.length} problem(s):\n  ${unexpected.join('\n  ')}`);
}

// The scan flow: the fixture's calibration installed, a scan from the page,
// the viewer, the set-up view and a check.
async function run() {
  checkInputs();
  const { base } = await startDaemon(await freshDataDir());
  await putCalibration(base);
  const { page, problems, expected, tokenGiven, unauthorized } = await openBrowser(base);

  await page.goto(`${base}/`, { waitUntil: 'load' });
  if (args.token) {
    await page.waitForSelector('#token-box:not([hidden])', { timeout: 15_000 });
    await page.waitForFunction(() => document.getElementById('connection').textContent === 'token needed', null, { timeout: 15_000 });
    log(`the page asks for a token (${unauthorized.length} requests refused with 401 so far)`);
    if (unauthorized.length === 0) problems.push('the token box is shown but no request was refused');
    await page.fill('#token-input', args.token);
    await page.click('#token-form button[type=submit]');
    tokenGiven();
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
  // The viewer's line says how many points once the cloud is in, or why not;
  // the quick head's cloud is main's alone, with no camera property: no legend.
  await page.waitForFunction(() => /points|^Point cloud:/.test(document.getElementById('viewer-info').textContent), null, { timeout: 15_000 });
  const viewerLine = await page.textContent('#viewer-info');
  log(`viewer line: "${viewerLine}"`);
  if (!viewerLine.includes(points.toLocaleString('en-US')) && !viewerLine.includes(String(points))) {
    problems.push(`the viewer's line does not give the point count ${points}: "${viewerLine}"`);
  }
  if (await page.isVisible('#camera-legend')) problems.push('a camera legend is shown for a one-camera cloud');

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

  await checkSetupView(page, base, { problems, expected });
  await checkChecks(page, base, { problems, expected });
  await checkStaleStatus(page, { problems });
  await judge(page, problems, expected);
}

// Answers that come back out of order, as they can from a busy head: the
// answer to the status request the page makes as a scan starts (the head
// scanning) is held back until the scan has ended and a newer answer has
// come, then delivered. The page must go on showing the head idle: the older
// answer shown would leave the Scan button (and the set-up's captures)
// disabled until the next event. A held answer that already says idle proves
// nothing: the scan is tried again, three times at most.
async function checkStaleStatus(page, { problems }) {
  await page.click('#scan-tab');
  const isStatus = (url) => /\/api\/v1\/status$/.test(url);
  for (let attempt = 1; attempt <= 3; attempt++) {
    await page.waitForSelector('#scan-button:not([disabled])', { timeout: 15_000 });
    let held = null;
    let release;
    const released = new Promise((resolve) => {
      release = resolve;
    });
    const hold = async (route) => {
      if (held) return route.continue();
      held = { request: route.request(), said: null };
      const response = await route.fetch();
      const body = await response.text();
      held.said = JSON.parse(body).state;
      await released;
      await route.fulfill({ response, body });
    };
    await page.route('**/api/v1/status', hold);
    // The first status answer to arrive after the click is a newer one: the
    // first asked is held.
    const newer = page.waitForResponse((r) => isStatus(r.url()), { timeout: 60_000 });
    await page.click('#scan-button');
    await newer;
    await page.waitForFunction(
      () => document.getElementById('st-state').textContent === 'idle' && !document.getElementById('scan-button').disabled,
      null,
      { timeout: 60_000 },
    );
    const delivered = page.waitForResponse((r) => r.request() === held.request, { timeout: 15_000 });
    release();
    await delivered;
    await page.unroute('**/api/v1/status', hold);
    if (held.said !== 'scanning') {
      log(`stale status, attempt ${attempt}: the held answer said "${held.said}", not scanning; again`);
      continue;
    }
    // The page takes the delivered answer within a few milliseconds; two
    // seconds of watching leave a loaded machine a wide margin.
    let shown = 'idle';
    for (let i = 0; i < 20 && shown === 'idle'; i++) {
      await page.waitForTimeout(100);
      shown = await page.evaluate(() => (document.getElementById('scan-button').disabled ? 'scan button disabled' : document.getElementById('st-state').textContent));
    }
    log(`stale status: an answer saying scanning, delivered after the scan's end, left the page showing "${shown}"`);
    if (shown !== 'idle') problems.push(`a status answer older than the one shown was taken: the page shows "${shown}" after the scan's end`);
    return;
  }
  problems.push('three scans ended before their first status answer was made: no answer saying scanning to hold back');
}

// The set-up view (docs/http-api.md, "Cameras"), driven as a user would:
// each camera's live picture drawn at 5 frames a second or more with its
// focus and saturated fraction, the saturation overlay, exposure set with the
// keyboard and sent, an out-of-range value refused with the daemon's words,
// the live view paused while a scan runs and back once the head is idle, the
// tabs by keyboard, and no stream left open once the view is left.
// `expected` takes the patterns of the problems it provokes.
async function checkSetupView(page, base, { problems, expected }) {
  const api = async (path, init = {}) => {
    const headers = { ...(init.headers ?? {}), ...(args.token ? { Authorization: `Bearer ${args.token}` } : {}) };
    const response = await fetch(`${base}/api/v1/${path}`, { ...init, headers });
    const body = await response.text();
    return { status: response.status, body, json: () => JSON.parse(body) };
  };
  const listed = await api('cameras');
  if (listed.status !== 200) fail(`GET /api/v1/cameras: ${listed.status} ${listed.body}`);
  const cameras = listed.json();
  const main = cameras.find((camera) => camera.name === 'main');
  if (!main) fail(`no camera "main" in ${listed.body}`);
  const card = '[data-camera="main"]';
  const frames = () => page.$eval(`${card} .live`, (live) => Number(live.dataset.frames));
  const streams = new Set(); // stream.mjpg requests not yet finished
  const streamUrls = [];
  page.on('request', (request) => {
    if (/\/stream\.mjpg(\?|$)/.test(request.url())) {
      streams.add(request);
      streamUrls.push(request.url());
    }
  });
  const finished = (request) => streams.delete(request);
  page.on('requestfinished', finished);
  page.on('requestfailed', finished);

  // The tabs by keyboard: from Scan to Set-up with the arrow key.
  await page.focus('#scan-tab');
  await page.keyboard.press('ArrowRight');
  await page.waitForSelector('#setup-view:not([hidden])', { timeout: 5_000 });
  if ((await page.getAttribute('#setup-tab', 'aria-selected')) !== 'true') problems.push('the Set-up tab is not selected after ArrowRight');
  if (await page.isVisible('#scan-view')) problems.push('the scan view is still shown beside the set-up view');
  await page.waitForSelector(card, { timeout: 15_000 });
  const cards = await page.$$eval('[data-camera]', (nodes) => nodes.map((node) => node.dataset.camera));
  if (cards.join() !== cameras.map((camera) => camera.name).join()) problems.push(`cards ${cards} for cameras ${cameras.map((c) => c.name)}`);
  const calibrated = await page.getAttribute(`${card} .calibrated`, 'data-calibrated');
  if (calibrated !== String(main.calibrated)) problems.push(`main's card says calibrated=${calibrated}, the daemon ${main.calibrated}`);

  // Frames, at the daemon's rate, drawn into the canvas.
  await page.waitForFunction((s) => Number(document.querySelector(`${s} .live`).dataset.frames) >= 3, card, { timeout: 15_000 });
  const before = await frames();
  await page.waitForTimeout(2000);
  const rate = ((await frames()) - before) / 2;
  log(`live view of main: ${rate} frames/s`);
  if (!(rate >= 4)) problems.push(`the live view of main draws ${rate} frames/s (the daemon sends 5 or more)`);
  const picture = await page.$eval(`${card} .live canvas`, (canvas) => {
    const data = canvas.getContext('2d').getImageData(0, 0, canvas.width, canvas.height).data;
    let lo = 255;
    let hi = 0;
    for (let i = 0; i < data.length; i += 4 * 97) {
      lo = Math.min(lo, data[i + 1]);
      hi = Math.max(hi, data[i + 1]);
    }
    return { width: canvas.width, height: canvas.height, lo, hi };
  });
  if (!(picture.hi - picture.lo > 16)) problems.push(`main's live picture looks blank: ${JSON.stringify(picture)}`);
  const measures = await page.evaluate((s) => ({
    focus: Number(document.querySelector(`${s} .focus`).dataset.value),
    saturated: Number(document.querySelector(`${s} .saturated`).dataset.value),
    text: `${document.querySelector(`${s} .focus`).textContent} / ${document.querySelector(`${s} .saturated`).textContent}`,
  }), card);
  log(`main: focus / saturated ${measures.text}`);
  if (!(measures.focus >= 0)) problems.push(`main's focus measure is ${measures.focus}`);
  if (!(measures.saturated >= 0 && measures.saturated <= 1)) problems.push(`main's saturated fraction is ${measures.saturated}`);

  // The overlay opens the stream again with ?overlay=saturation, and frames go on.
  await page.check(`${card} input[name=overlay]`);
  const overlaid = await frames();
  await page.waitForFunction(([s, n]) => Number(document.querySelector(`${s} .live`).dataset.frames) > n + 2, [card, overlaid], { timeout: 10_000 });
  if (!streamUrls.some((url) => url.endsWith('/cameras/main/stream.mjpg?overlay=saturation'))) {
    problems.push(`no stream with the overlay was opened: ${streamUrls.join(', ')}`);
  }

  // Exposure by keyboard: 20 steps of the (log) slider, sent once, debounced.
  const original = main.controls.exposure_us;
  const down = original.value > original.min;
  const patches = [];
  const onPatch = (request) => {
    if (request.method() === 'PATCH') patches.push(request);
  };
  page.on('request', onPatch);
  const slider = `${card} input[type=range][name=exposure_us]`;
  await page.focus(slider);
  for (let i = 0; i < 20; i++) await page.keyboard.press(down ? 'ArrowLeft' : 'ArrowRight');
  await page.waitForFunction((s) => /^Set exposure/.test(document.querySelector(`${s} .message`).textContent), card, { timeout: 10_000 });
  const wanted = Number(await page.getAttribute(slider, 'data-value'));
  const now = (await api('cameras')).json().find((camera) => camera.name === 'main').controls.exposure_us;
  log(`exposure set to ${now.value} µs in ${patches.length} request(s) (range ${now.min}..${now.max})`);
  if (patches.length < 1 || patches.length > 3) problems.push(`${patches.length} PATCH requests for one slider movement (debounced: 1)`);
  if (patches.length > 0 && patches.at(-1).headers()['content-type'] !== 'application/json') problems.push('PATCH without Content-Type: application/json');
  if (!(Math.abs(now.value - wanted) <= 1e-6 * wanted + 1)) problems.push(`the daemon's exposure is ${now.value} µs, the slider's ${wanted}`);
  if (!(down ? now.value < original.value : now.value > original.value)) {
    problems.push(`the exposure did not go ${down ? 'down' : 'up'} from ${original.value} µs: ${now.value}`);
  }

  // An out-of-range value, typed in: refused, in the daemon's words, and the inputs back to its value.
  expected.push(/^HTTP 400: PATCH .*\/api\/v1\/cameras\/main$/, /^console error: .*status of 400/, /^error shown in the page: .*exposure_us/);
  await page.fill(`${card} input[name=exposure_us_entry]`, String(now.max * 10));
  await page.press(`${card} input[name=exposure_us_entry]`, 'Enter');
  await page.waitForSelector(`${card} .message.error`, { timeout: 10_000 });
  const refusal = await page.textContent(`${card} .message.error`);
  log(`out of range: "${refusal}"`);
  if (!refusal.includes('exposure_us')) problems.push(`the refusal does not name exposure_us: "${refusal}"`);
  const shownValue = Number(await page.inputValue(`${card} input[name=exposure_us_entry]`));
  if (shownValue !== now.value) problems.push(`after the refusal the exposure box shows ${shownValue}, the daemon has ${now.value}`);
  page.off('request', onPatch);
  // The rest of the test, and the scans after it, at the exposure the head had.
  const restored = await api('cameras/main', {
    method: 'PATCH',
    headers: { 'Content-Type': 'application/json' },
    body: JSON.stringify({ exposure_us: original.value }),
  });
  if (restored.status !== 200) fail(`PATCH /api/v1/cameras/main back to ${original.value} µs: ${restored.status} ${restored.body}`);

  await checkFringeCheck(page, { api, cameras, original: original.value, problems });

  // A scan pauses the live view, plainly; the head idle again, it comes back.
  // The quick head scans in under a second: what the page showed meanwhile is
  // recorded in the page rather than polled.
  await page.evaluate(() => {
    const seen = (window.cylscanPausedSeen = []);
    const notice = document.getElementById('live-paused');
    const look = () => {
      if (!notice.hidden) seen.push(notice.textContent.trim());
      const live = document.querySelector('[data-camera="main"] .live');
      if (live.dataset.liveState === 'paused') seen.push(`main: ${live.querySelector('.live-status').textContent}`);
    };
    new MutationObserver(look).observe(document.getElementById('setup-view'), { subtree: true, childList: true, characterData: true, attributes: true });
  });
  const scan = await api('scans', { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: '{}' });
  if (scan.status !== 202) fail(`POST /api/v1/scans: ${scan.status} ${scan.body}`);
  const { id } = scan.json();
  for (;;) {
    const state = (await api(`scans/${id}`)).json().state;
    if (state === 'done' || state === 'failed') break;
    await page.waitForTimeout(100);
  }
  await page.waitForSelector('#live-paused', { state: 'hidden', timeout: 15_000 });
  const pausedSeen = new Set(await page.evaluate(() => window.cylscanPausedSeen));
  for (const text of ['Live view paused: a scan is running', 'main: Live view paused: a scan is running']) {
    if (!pausedSeen.has(text)) problems.push(`"${text}" was not shown during the scan (shown: ${[...pausedSeen].join(' | ')})`);
  }
  const resumed = await frames();
  await page.waitForFunction(([s, n]) => Number(document.querySelector(`${s} .live`).dataset.frames) > n + 2, [card, resumed], { timeout: 15_000 });
  log('the live view paused during the scan and came back');

  // Back to the scan view: no stream left open.
  await page.click('#scan-tab');
  await page.waitForTimeout(500);
  if (streams.size > 0) problems.push(`${streams.size} live stream(s) still open once the set-up view was left`);
}

// The fringe check (docs/http-api.md, "Fringe check"), clicked in the set-up
// view: at the fixture's exposure every camera's advice is "right", shown in
// words with its picture (at the camera's resolution) and a plausible usable
// share; main at 2 ms, typed into its card, is "raise". The button is
// disabled and says "checking…" while the check runs, the live views say
// they are paused meanwhile and come back. Main's exposure is set back to
// `original` µs for the steps that follow.
async function checkFringeCheck(page, { api, cameras, original, problems }) {
  const card = '[data-camera="main"]';
  const entry = `${card} input[name=exposure_us_entry]`;
  await page.evaluate(() => {
    const button = document.getElementById('fringe-check-button');
    const message = document.getElementById('fringe-check-message');
    const paused = document.getElementById('live-paused');
    const seen = (window.cylscanFringeSeen = new Set());
    new MutationObserver(() => {
      if (button.disabled) seen.add('disabled');
      if (message.textContent) seen.add(message.textContent);
      if (!paused.hidden) seen.add(paused.textContent.trim());
    }).observe(document.getElementById('setup-view'), { subtree: true, childList: true, characterData: true, attributes: true });
  });
  // One check from the page: the daemon's answer and what the page shows of it.
  const check = async () => {
    await page.waitForSelector('#fringe-check-button:not([disabled])', { timeout: 15_000 });
    const posted = page.waitForResponse((r) => r.request().method() === 'POST' && /\/api\/v1\/fringe-check$/.test(r.url()), { timeout: 30_000 });
    const clicked = Date.now();
    await page.click('#fringe-check-button');
    const response = await posted;
    if (response.status() !== 200) fail(`POST /api/v1/fringe-check from the page: ${response.status()} ${await response.text()}`);
    const answer = await response.json();
    await page.waitForSelector('#fringe-check:is([data-state="done"], [data-state="failed"])', { timeout: 15_000 });
    if ((await page.getAttribute('#fringe-check', 'data-state')) !== 'done') fail(`the fringe check failed: ${await page.textContent('#fringe-check-message')}`);
    const names = answer.cameras.map((camera) => camera.name);
    await page.waitForFunction(
      (n) => n.every((name) => document.querySelector(`[data-fringe-camera="${name}"] img`)?.naturalWidth > 0),
      names,
      { timeout: 15_000 },
    );
    const shown = await page.evaluate((n) => Object.fromEntries(n.map((name) => {
      const node = document.querySelector(`[data-fringe-camera="${name}"]`);
      const figures = Object.fromEntries([...node.querySelectorAll('[data-figure]')].map((dd) => [dd.dataset.figure, dd.textContent]));
      const img = node.querySelector('img');
      return [name, {
        advice: node.dataset.advice,
        text: node.querySelector('.fringe-advice').textContent,
        visible: node.querySelector('.fringe-advice').checkVisibility() && img.checkVisibility(),
        width: img.naturalWidth,
        height: img.naturalHeight,
        figures,
      }];
    })), names);
    log(`fringe check shown after ${Date.now() - clicked} ms: ${JSON.stringify(shown)}`);
    return { answer, shown };
  };

  const { answer, shown } = await check();
  const names = answer.cameras.map((camera) => camera.name);
  if (names.join() !== cameras.map((camera) => camera.name).join()) problems.push(`the fringe check's cameras ${names} for cameras ${cameras.map((c) => c.name)}`);
  for (const camera of cameras) {
    const measured = answer.cameras.find((c) => c.name === camera.name);
    const onPage = shown[camera.name];
    if (!measured || !onPage) {
      problems.push(`no fringe check of ${camera.name} shown (daemon: ${JSON.stringify(measured)})`);
      continue;
    }
    if (measured.advice !== 'right') problems.push(`the daemon advises "${measured.advice}" for ${camera.name} at the fixture's exposure: ${JSON.stringify(measured)}`);
    if (onPage.advice !== measured.advice || onPage.text !== 'Exposure right for scanning' || !onPage.visible) {
      problems.push(`${camera.name}'s fringe advice shown: "${onPage.text}" (${onPage.advice}, visible: ${onPage.visible}), the daemon's "${measured.advice}"`);
    }
    if (onPage.width !== camera.width || onPage.height !== camera.height) {
      problems.push(`${camera.name}'s fringe picture is ${onPage.width} × ${onPage.height}, the camera ${camera.width} × ${camera.height}`);
    }
    const usable = Number.parseFloat(onPage.figures.usable);
    if (!(usable > 50)) problems.push(`${camera.name}'s usable share shown is "${onPage.figures.usable}" (want > 50 %)`);
    if (!(Math.abs(usable - measured.usable * 100) < 0.1)) problems.push(`${camera.name}'s usable share shown is "${onPage.figures.usable}", the daemon's ${measured.usable}`);
    for (const key of ['saturated', 'peak', 'modulation']) {
      if (!onPage.figures[key] || onPage.figures[key].startsWith('–')) problems.push(`${camera.name}'s fringe figure ${key} is not shown`);
    }
  }
  const seen = await page.evaluate(() => [...window.cylscanFringeSeen]);
  if (!seen.includes('disabled') || !seen.includes('checking…')) problems.push(`the fringe check button was not disabled with "checking…" while it ran (seen: ${seen.join(' | ')})`);
  if (!seen.includes('Live view paused: checking the fringes')) problems.push(`the live view's pause was not shown during the fringe check (seen: ${seen.join(' | ')})`);

  // Main too dark, as typed into its card: the advice turns to "raise".
  const setExposure = async (us) => {
    await page.fill(entry, String(us));
    await page.press(entry, 'Enter');
    for (let i = 0; ; i++) {
      const value = (await api('cameras')).json().find((camera) => camera.name === 'main').controls.exposure_us.value;
      if (value === us) break;
      if (i === 50) fail(`main's exposure typed in as ${us} µs is ${value} µs at the daemon`);
      await page.waitForTimeout(100);
    }
  };
  await setExposure(2000);
  const dark = await check();
  const darkMain = dark.answer.cameras.find((camera) => camera.name === 'main');
  log(`fringe check of main at 2 ms: ${JSON.stringify(darkMain)}`);
  if (darkMain?.exposure_us !== 2000) problems.push(`the fringe check was taken at ${darkMain?.exposure_us} µs, not the 2000 µs typed in`);
  if (darkMain?.advice !== 'raise' || dark.shown.main?.advice !== 'raise' || dark.shown.main?.text !== 'Too dark: raise the exposure') {
    problems.push(`main at 2 ms: the daemon advises "${darkMain?.advice}", the page shows "${dark.shown.main?.text}"`);
  }
  await setExposure(original);

  // The live view paused during the checks and is back.
  await page.waitForSelector('#live-paused', { state: 'hidden', timeout: 15_000 });
  const resumed = await page.$eval(`${card} .live`, (live) => Number(live.dataset.frames));
  await page.waitForFunction(([s, n]) => Number(document.querySelector(`${s} .live`).dataset.frames) > n + 2, [card, resumed], { timeout: 15_000 });
  log('the live view paused during the fringe checks and came back');
}

// The checks against a known artifact (docs/http-api.md), from the page
// alone: a check the daemon refuses shows its words; then a check of the
// quick head's default scene (sphere_on_plane: a sphere of 50 mm radius) with
// the form's defaults, clicked, must come out PASS with the radius measured
// within 0.1 mm, one dot more in the history plot, a row in the table, and
// the figures the daemon keeps. The Run check button is disabled meanwhile.
async function checkChecks(page, base, { problems, expected }) {
  const api = async (path) => {
    const response = await fetch(`${base}/api/v1/${path}`, { headers: args.token ? { Authorization: `Bearer ${args.token}` } : {} });
    const body = await response.text();
    if (response.status !== 200) fail(`GET /api/v1/${path}: ${response.status} ${body}`);
    return JSON.parse(body);
  };
  await page.click('#setup-tab');
  await page.waitForSelector('#checks[data-loaded="true"]', { timeout: 15_000 });
  await page.waitForSelector('#check-button:not([disabled])', { timeout: 15_000 });
  const dots = () => page.$$eval('#check-plot circle.check-dot', (nodes) => nodes.length);
  const history = await api('checks');
  const dotsBefore = await dots();
  const measuredBefore = history.filter((check) => Number.isFinite(check.measured_radius_mm)).length;
  if (dotsBefore !== measuredBefore) problems.push(`the plot has ${dotsBefore} dots for ${measuredBefore} measured checks`);
  const defaults = { radius: await page.inputValue('#check-radius'), tolerance: await page.inputValue('#check-tolerance') };
  if (Number(defaults.radius) !== 50 || Number(defaults.tolerance) !== 0.1) problems.push(`the form's defaults are ${JSON.stringify(defaults)}`);

  // A tolerance the daemon refuses (the browser's own validation of the form
  // set aside, so that the request is sent): its error, naming the key, shown.
  expected.push(/^HTTP 400: POST .*\/api\/v1\/checks$/, /^console error: .*status of 400/, /^error shown in the page: #check-message: .*tolerance_mm/);
  await page.$eval('#check-form', (form) => {
    form.noValidate = true;
  });
  await page.fill('#check-tolerance', '1000');
  const refused = page.waitForResponse((r) => r.request().method() === 'POST' && /\/api\/v1\/checks$/.test(r.url()));
  await page.click('#check-button');
  if ((await refused).status() !== 400) problems.push(`a tolerance of 1000 mm was answered ${(await refused).status()}, not 400`);
  await page.waitForSelector('#check-message.error', { timeout: 10_000 });
  const refusal = await page.textContent('#check-message');
  log(`check refused: "${refusal}"`);
  if (!refusal.includes('tolerance_mm')) problems.push(`the refusal does not give the daemon's words naming tolerance_mm: "${refusal}"`);
  await page.$eval('#check-form', (form) => {
    form.noValidate = false;
  });
  await page.fill('#check-tolerance', defaults.tolerance);
  await page.waitForSelector('#check-button:not([disabled])', { timeout: 5_000 });

  // The check itself.
  await page.evaluate(() => {
    const button = document.getElementById('check-button');
    window.cylscanCheckButtonDisabled = false;
    new MutationObserver(() => {
      if (button.disabled) window.cylscanCheckButtonDisabled = true;
    }).observe(button, { attributes: true, attributeFilter: ['disabled'] });
  });
  const posted = page.waitForResponse((r) => r.request().method() === 'POST' && /\/api\/v1\/checks$/.test(r.url()));
  const clicked = Date.now();
  await page.click('#check-button');
  const response = await posted;
  if (response.status() !== 202) fail(`POST /api/v1/checks from the page: ${response.status()} ${await response.text()}`);
  const { id } = await response.json();
  const sent = JSON.parse(response.request().postData() ?? 'null');
  if (!sent || sent.artifact !== 'sphere' || sent.radius_mm !== 50 || sent.tolerance_mm !== 0.1) {
    problems.push(`the page asked for the check ${JSON.stringify(sent)}`);
  }
  log(`check ${id} started from the page`);
  const latest = `#check-latest[data-id="${id}"]`;
  await page
    .waitForSelector(`${latest}:is([data-outcome="pass"], [data-outcome="fail"], [data-outcome="failed"])`, { timeout: 60_000 })
    .catch(async () => {
      const now = await page.$eval('#check-latest', (box) => `${box.dataset.id}: ${box.querySelector('[data-field="verdict"]').textContent}`);
      fail(`check ${id}: no outcome shown in 60 s (the latest check shown: ${now})`);
    });
  const shown = await page.evaluate((s) => {
    const field = (name) => document.querySelector(`${s} [data-field="${name}"]`).textContent.trim();
    return {
      verdict: field('verdict'),
      visible: document.querySelector(s).checkVisibility(),
      measured: field('measured'),
      error: field('error'),
      rmse: field('rmse'),
      pf: field('pf'),
      ps: field('ps'),
      points: field('points'),
    };
  }, latest);
  log(`check ${id} shown after ${Date.now() - clicked} ms: ${JSON.stringify(shown)}`);
  if (shown.verdict !== 'PASS' || !shown.visible) fail(`check ${id}: the page shows "${shown.verdict}" (visible: ${shown.visible}), not PASS`);
  const measured = Number.parseFloat(shown.measured);
  if (!(Math.abs(measured - 50) <= 0.1)) problems.push(`the measured radius shown is "${shown.measured}", not within 0.1 mm of 50 mm`);
  for (const [name, text] of Object.entries(shown)) {
    if (name !== 'visible' && (text === '' || text === '–')) problems.push(`the latest check's ${name} is not shown`);
  }
  await page.waitForFunction((n) => document.querySelectorAll('#check-plot circle.check-dot').length === n, dotsBefore + 1, { timeout: 10_000 })
    .catch(async () => problems.push(`the history plot has ${await dots()} dots, not ${dotsBefore + 1}, after the check`));
  if (!(await page.$(`#check-plot circle.check-dot.pass[data-id="${id}"]`))) problems.push(`no passing dot for check ${id} in the plot`);
  const row = await page.$eval(`#check-rows tr[data-check="${id}"] .result`, (cell) => cell.textContent).catch(() => null);
  if (row !== 'PASS') problems.push(`check ${id}'s row in the table says ${row === null ? 'nothing (no row)' : `"${row}"`}`);
  if (!(await page.evaluate(() => window.cylscanCheckButtonDisabled))) problems.push('the Run check button was never disabled while the check ran');

  // What the daemon keeps is what the page showed.
  const kept = (await api('checks')).find((check) => check.id === id);
  if (!kept) fail(`check ${id} is not in GET /api/v1/checks`);
  if (kept.state !== 'done' || kept.pass !== true) problems.push(`the daemon's check ${id}: ${JSON.stringify(kept)}`);
  if (shown.measured !== `${kept.measured_radius_mm.toFixed(4)} mm`) {
    problems.push(`the page shows a measured radius of "${shown.measured}", the daemon ${kept.measured_radius_mm}`);
  }
  log(`check ${id}: radius ${kept.measured_radius_mm} mm, RMSE ${kept.rmse_mm}, PF ${kept.probing_error_form_mm}, PS ${kept.probing_error_size_mm}, ${kept.points} points`);
  await page.waitForSelector('#check-button:not([disabled])', { timeout: 15_000 });
}

// Requests to the daemon beside the page, to compare what it shows with
// what the daemon says: {status, body, json()}.
function daemonApi(base) {
  return async (path, init = {}) => {
    const headers = { ...(init.headers ?? {}), ...(args.token ? { Authorization: `Bearer ${args.token}` } : {}) };
    const response = await fetch(`${base}/api/v1/${path}`, { ...init, headers });
    const body = await response.text();
    return { status: response.status, body, json: () => JSON.parse(body) };
  };
}

// Mean of the green channel of main's live picture, over a grid of its pixels.
async function liveBrightness(page) {
  return page.$eval('[data-camera="main"] .live canvas', (canvas) => {
    const data = canvas.getContext('2d').getImageData(0, 0, canvas.width, canvas.height).data;
    let sum = 0;
    let count = 0;
    for (let i = 0; i < data.length; i += 4 * 7) {
      sum += data[i + 1];
      count++;
    }
    return sum / count;
  });
}

// Main's live view is drawn, and an exposure typed into its box shows in the
// picture: a quarter of it darkens the picture, and back to what it was
// brightens it again (the captures that follow use the head's exposure).
async function checkExposureSeen(page, { problems }) {
  const card = '[data-camera="main"]';
  const frames = () => page.$eval(`${card} .live`, (live) => Number(live.dataset.frames));
  const newFrames = async (n) => {
    const from = await frames();
    await page.waitForFunction(([s, f]) => Number(document.querySelector(`${s} .live`).dataset.frames) >= f, [card, from + n], { timeout: 15_000 });
  };
  await page.waitForSelector(`${card} .live[data-live-state="live"]`, { timeout: 15_000 });
  await newFrames(3);
  if (!(await page.isVisible(`${card} .live canvas`))) problems.push("main's live picture is not visible");
  const entry = `${card} input[name=exposure_us_entry]`;
  const original = Number(await page.inputValue(entry));
  const min = Number(await page.getAttribute(entry, 'min'));
  // Frames already on their way were exposed before the change, and how
  // many are on their way depends on how busy the machine is: the picture
  // is read after each new frame until it shows the change (`shows`), for
  // at most 40 frames.
  const setExposure = async (value, shows) => {
    const patched = page.waitForResponse((r) => r.request().method() === 'PATCH' && /\/cameras\/main$/.test(r.url()));
    await page.fill(entry, String(value));
    await page.press(entry, 'Enter');
    const response = await patched;
    if (response.status() !== 200) fail(`PATCH of main's exposure to ${value} µs: ${response.status()}`);
    let brightness = NaN;
    for (let frame = 0; frame < 40; frame++) {
      await newFrames(1);
      brightness = await liveBrightness(page);
      if (shows(brightness)) break;
    }
    return brightness;
  };
  const before = await liveBrightness(page);
  const darker = Math.max(min, Math.round(original / 4));
  const darkened = (b) => b < before * 0.8 && before - b > 8;
  const dimmed = await setExposure(darker, darkened);
  const cameBack = (b) => b > dimmed * 1.2 && Math.abs(b - before) < 0.1 * before + 4;
  const restored = await setExposure(original, cameBack);
  log(`main's live picture: mean ${before.toFixed(1)} at ${original} µs, ${dimmed.toFixed(1)} at ${darker} µs, ${restored.toFixed(1)} back at ${original} µs`);
  if (!darkened(dimmed)) problems.push(`the picture did not darken with the exposure in 40 frames: ${before.toFixed(1)} → ${dimmed.toFixed(1)}`);
  if (!cameBack(restored)) {
    problems.push(`the picture did not come back with the exposure in 40 frames: ${dimmed.toFixed(1)} → ${restored.toFixed(1)} (first ${before.toFixed(1)})`);
  }
}

// Clicks a capture button of the calibration section once it is enabled,
// with the target pose the page offers, which must be `target` (the next one
// not yet taken), and waits until the capture is in the session and the
// button is enabled again.
async function takeCapture(page, { button, select, target, counter, count }) {
  await page.waitForSelector(`${button}:not([disabled])`, { timeout: 30_000 });
  const offered = await page.inputValue(select);
  if (offered !== target) fail(`the page offers the target pose "${offered}", not "${target}", the next one not taken`);
  await page.click(button);
  await page.waitForFunction(
    ([c, n]) => Number(document.getElementById('calibration').dataset[c]) >= n,
    [counter, count],
    { timeout: 60_000, polling: 50 },
  );
}

// The calibration flow, on a head of its own with no calibration: the page
// alone (clicks and typing) goes through everything a person with a board
// would: main's live view and its exposure, a session with every target pose
// the virtual head ships (the page offering the next one each time), the
// guidance, the plane poses, a solve refused while it has too few views (the
// daemon's words shown) and then done with its progress, the result, the
// install, a scan that gives a cloud, a check that passes, a roll back with
// nothing kept (the daemon's 404 said as a plain message), and once more
// installed, a roll back that is done. The live views pause during each
// capture, in words, and come back; nothing shows an error.
async function runCalibration() {
  checkInputs();
  const { base } = await startDaemon(await freshDataDir());
  const { page, problems, expected } = await openBrowser(base);
  const api = daemonApi(base);
  const started = Date.now();
  const elapsed = () => `${((Date.now() - started) / 1000).toFixed(1)} s`;
  // The one dialog expected (a RegExp of its text), answered No; any other is a problem.
  let expectedDialog = null;
  const dialogsSeen = [];
  page.on('dialog', (dialog) => {
    if (expectedDialog && expectedDialog.test(dialog.message())) dialogsSeen.push(dialog.message());
    else problems.push(`unexpected dialog: ${dialog.message()}`);
    dialog.dismiss().catch(() => {});
  });

  await page.goto(`${base}/`, { waitUntil: 'load' });
  await page.waitForFunction(() => document.getElementById('connection').textContent === 'live', null, { timeout: 15_000 });
  await page.waitForFunction(() => document.getElementById('st-calibration').textContent === 'not installed', null, { timeout: 15_000 });
  await page.click('#setup-tab');
  await checkExposureSeen(page, { problems });

  // What the live views showed during the captures, recorded in the page.
  await page.evaluate(() => {
    const seen = (window.cylscanPausedSeen = new Set());
    const notice = document.getElementById('live-paused');
    new MutationObserver(() => {
      if (!notice.hidden) seen.add(notice.textContent.trim());
      for (const live of document.querySelectorAll('[data-camera] .live')) {
        if (live.dataset.liveState === 'paused') seen.add(`card: ${live.querySelector('.live-status').textContent}`);
      }
    }).observe(document.getElementById('setup-view'), { subtree: true, childList: true, characterData: true, attributes: true });
  });

  await page.waitForSelector('#calibration[data-loaded="true"][data-state="none"]', { timeout: 15_000 });
  const installedText = await page.textContent('#cal-installed');
  if (!/^main ✗/.test(installedText)) problems.push(`the section says the installed calibration is "${installedText}" on an uncalibrated head`);
  await page.click('#cal-start');
  await page.waitForSelector('#calibration[data-state="capturing"]', { timeout: 15_000 });
  const session = (await api('calibration/session')).json();
  const targets = session.targets;
  if (!targets || targets.boards.length === 0 || targets.planes.length === 0) fail(`the virtual head's session has no targets: ${JSON.stringify(targets)}`);
  await page.waitForFunction((n) => document.querySelectorAll('#cal-board-target option').length === n + 1, targets.boards.length, { timeout: 10_000 });
  log(`session started (${elapsed()}): ${targets.boards.length} board and ${targets.planes.length} plane targets`);

  // A solve with nothing taken: refused, in the daemon's words.
  expected.push(
    /^HTTP 409: POST .*\/api\/v1\/calibration\/session\/solve$/,
    /^console error: .*status of 409.*\/api\/v1\/calibration\/session\/solve\)$/,
    /^error shown in the page: #cal-solve-message: Not solved: too few checkerboard pairs: 0 found in both cameras/,
  );
  await page.click('#cal-solve');
  await page.waitForFunction(() => /too few checkerboard pairs/.test(document.getElementById('cal-solve-message').textContent), null, { timeout: 10_000 });
  log(`solve refused: "${await page.textContent('#cal-solve-message')}"`);

  // Every board target, each the one the page offers next.
  const boardsStarted = Date.now();
  for (const [i, target] of targets.boards.entries()) {
    await takeCapture(page, { button: '#cal-board-button', select: '#cal-board-target', target, counter: 'boards', count: i + 1 });
    if (i === 0 || (i + 1) % 16 === 0) log(`board pair ${i + 1}/${targets.boards.length} taken (${elapsed()}): ${await page.textContent('#cal-board-message')}`);
  }
  const boardsSeconds = (Date.now() - boardsStarted) / 1000;
  log(`${targets.boards.length} board pairs in ${boardsSeconds.toFixed(1)} s (${(boardsSeconds / targets.boards.length).toFixed(2)} s each)`);
  if ((await page.inputValue('#cal-board-target')) !== '') problems.push('with every board target taken the page still offers one');

  // The pairs as the daemon has them, listed; the guidance as it says.
  const afterBoards = (await api('calibration/session')).json();
  const kept = afterBoards.boards.filter((b) => b.found.main && b.found.aux).length;
  const listed = await page.$$eval('#cal-boards li', (items) => items.map((li) => `${li.dataset.index}:${li.dataset.main}:${li.dataset.aux}`));
  const wantListed = afterBoards.boards.map((b) => `${b.index}:${b.found.main}:${b.found.aux}`);
  if (listed.join() !== wantListed.join()) problems.push(`the pairs listed (${listed.length}) are not the session's (${wantListed.length})`);
  if (kept !== afterBoards.boards.length) log(`note: ${afterBoards.boards.length - kept} pair(s) not found in both cameras`);
  const guidance = afterBoards.guidance;
  const shownGuidance = await page.evaluate(() => ({
    verdict: document.getElementById('cal-guidance').dataset.verdict,
    enough: document.getElementById('cal-enough').textContent,
    advice: document.getElementById('cal-advice').textContent,
    rows: [...document.querySelectorAll('#cal-guidance-rows tr')].map((tr) => ({
      camera: tr.dataset.camera,
      cells: Object.fromEntries([...tr.querySelectorAll('td[data-key]')].map((td) => [td.dataset.key, td.textContent])),
    })),
    notice: document.getElementById('cal-solve-notice').checkVisibility() ? document.getElementById('cal-solve-notice').textContent : null,
  }));
  log(`guidance shown: ${shownGuidance.enough} ${JSON.stringify(shownGuidance.rows)} ${shownGuidance.advice}`);
  if (shownGuidance.verdict !== (guidance.enough ? 'enough' : 'not-enough')) problems.push(`the guidance shown is "${shownGuidance.verdict}", the daemon's enough is ${guidance.enough}`);
  for (const camera of ['main', 'aux']) {
    const row = shownGuidance.rows.find((r) => r.camera === camera);
    const sigma = guidance.cameras[camera]?.sigma_px;
    if (!row || !sigma) {
      problems.push(`no guidance row for ${camera} (daemon: ${JSON.stringify(guidance.cameras[camera])})`);
      continue;
    }
    for (const key of ['fx', 'fy', 'cx', 'cy']) {
      if (row.cells[key] !== `${sigma[key].toFixed(3)} px`) problems.push(`${camera}'s σ ${key} shown is "${row.cells[key]}", the daemon's ${sigma[key]}`);
    }
    for (const key of ['coverage', 'tilt']) if (!row.cells[key] || row.cells[key] === '–') problems.push(`${camera}'s ${key} is not shown`);
  }
  if (!guidance.enough) {
    if (!shownGuidance.advice.includes(guidance.advice)) problems.push(`the advice shown is "${shownGuidance.advice}", the daemon's "${guidance.advice}"`);
    if (!shownGuidance.notice) problems.push('no warning by the Solve button while the guidance says the views are not enough');
  }

  // Every plane target.
  const planesStarted = Date.now();
  for (const [i, target] of targets.planes.entries()) {
    await takeCapture(page, { button: '#cal-plane-button', select: '#cal-plane-target', target, counter: 'planesDone', count: i + 1 });
  }
  const planesSeconds = (Date.now() - planesStarted) / 1000;
  log(`${targets.planes.length} plane poses in ${planesSeconds.toFixed(1)} s (${(planesSeconds / targets.planes.length).toFixed(2)} s each), ${elapsed()}`);
  const planeRows = await page.$$eval('#cal-planes tr', (rows) => rows.map((tr) => tr.dataset.state));
  if (planeRows.length !== targets.planes.length || planeRows.some((state) => state !== 'done')) problems.push(`the plane poses listed: ${planeRows.join(', ')}`);

  // The live views paused during the captures, saying why, and are back.
  const pausedSeen = await page.evaluate(() => [...window.cylscanPausedSeen]);
  for (const text of ['Live view paused: taking a calibration board pair', 'Live view paused: scanning a calibration plane pose']) {
    if (!pausedSeen.includes(text) || !pausedSeen.includes(`card: ${text}`)) problems.push(`"${text}" was not shown (shown: ${pausedSeen.join(' | ')})`);
  }
  await page.waitForSelector('#live-paused', { state: 'hidden', timeout: 15_000 });
  const resumedAt = await page.$eval('[data-camera="main"] .live', (live) => Number(live.dataset.frames));
  await page.waitForFunction((n) => Number(document.querySelector('[data-camera="main"] .live').dataset.frames) > n + 2, resumedAt, { timeout: 15_000 });
  log('the live views paused during the captures and came back');

  // The solve, its progress from the event stream, and the result.
  await page.evaluate(() => {
    const bar = document.getElementById('cal-solve-progress');
    const seen = (window.cylscanSolveProgress = []);
    new MutationObserver(() => {
      if (!bar.hidden) seen.push(Number(bar.value));
    }).observe(bar, { attributes: true, attributeFilter: ['value', 'hidden'] });
    // <progress>.value is a property: its changes are watched on the line beside it.
    new MutationObserver(() => {
      if (!bar.hidden) seen.push(Number(bar.value));
    }).observe(document.getElementById('cal-solve-message'), { childList: true, characterData: true, subtree: true });
  });
  const solveStarted = Date.now();
  await page.waitForSelector('#cal-solve:not([disabled])', { timeout: 15_000 });
  await page.click('#cal-solve');
  await page.waitForSelector('#calibration:is([data-state="solved"], [data-state="failed"])', { timeout: 240_000 });
  const solveSeconds = (Date.now() - solveStarted) / 1000;
  const progressSeen = await page.evaluate(() => window.cylscanSolveProgress);
  log(`solve ended after ${solveSeconds.toFixed(1)} s (${elapsed()}): ${progressSeen.length} progress values shown, ${progressSeen.slice(0, 3).join(', ')} … ${progressSeen.at(-1)}`);
  if ((await page.getAttribute('#calibration', 'data-state')) !== 'solved') fail(`the solve failed: ${await page.textContent('#cal-failed')}`);
  if (!(new Set(progressSeen).size >= 3 && progressSeen.some((v) => v > 0 && v < 1))) problems.push(`the solve's progress was not shown as it went: ${progressSeen.join(', ')}`);
  const solved = (await api('calibration/session')).json();
  const result = await page.evaluate(() => ({
    visible: document.getElementById('cal-result').checkVisibility(),
    fields: Object.fromEntries([...document.querySelectorAll('#cal-result [data-result]')].map((n) => [n.dataset.result, n.textContent])),
    cameras: [...document.querySelectorAll('#cal-result-cameras tr')].map((tr) => [...tr.children].map((c) => c.textContent)),
    poses: [...document.querySelectorAll('#cal-result-poses tr')].map((tr) => [...tr.children].map((c) => c.textContent)),
  }));
  log(`result shown: ${JSON.stringify(result.fields)}; ${JSON.stringify(result.cameras)}`);
  if (!result.visible) problems.push('the result is not shown');
  if (result.fields.stereoRms !== `${solved.result.stereo_rms_px.toFixed(3)} px`) problems.push(`stereo RMS shown "${result.fields.stereoRms}", the daemon's ${solved.result.stereo_rms_px}`);
  if (result.fields.boardsUsed !== String(solved.result.boards_used)) problems.push(`boards used shown "${result.fields.boardsUsed}", the daemon's ${solved.result.boards_used}`);
  if (result.fields.pooledRmse !== `${solved.result.pooled_rmse_mm.toFixed(4)} mm`) problems.push(`pooled RMSE shown "${result.fields.pooledRmse}", the daemon's ${solved.result.pooled_rmse_mm}`);
  if (result.cameras.map((row) => row[0]).join() !== 'main,aux') problems.push(`the result's cameras: ${result.cameras.map((row) => row[0])}`);
  const mainRow = result.cameras.find((row) => row[0] === 'main');
  const mainFx = solved.result.cameras.main;
  if (!mainRow || mainRow[1] !== `${mainFx.fx.toFixed(2)} ± ${mainFx.sigma_px.fx.toFixed(3)}`) problems.push(`main's fx shown "${mainRow?.[1]}", the daemon's ${mainFx.fx} ± ${mainFx.sigma_px.fx}`);
  if (result.poses.length !== solved.result.poses.length) problems.push(`${result.poses.length} poses in the result's table, ${solved.result.poses.length} in the daemon's`);
  for (const [i, pose] of solved.result.poses.entries()) {
    const row = result.poses[i];
    if (!row || row[2] !== `${pose.rmse_mm.toFixed(4)} mm`) problems.push(`pose ${pose.index}'s RMSE shown "${row?.[2]}", the daemon's ${pose.rmse_mm}`);
  }

  // Install: the head is calibrated, on the page too.
  await page.click('#cal-install');
  await page.waitForFunction(() => /^Installed/.test(document.getElementById('cal-install-message').textContent), null, { timeout: 15_000 });
  log(`install: "${await page.textContent('#cal-install-message')}"`);
  await page.waitForFunction(() => /^main ✓/.test(document.getElementById('cal-installed').textContent), null, { timeout: 15_000 });
  await page.waitForSelector('[data-camera="main"] .calibrated[data-calibrated="true"]', { timeout: 15_000 });
  if ((await page.textContent('#st-calibration')) !== 'installed') problems.push(`the Scan view says the calibration is "${await page.textContent('#st-calibration')}" after the install`);

  // A scan with the new calibration gives a cloud.
  await page.click('#scan-tab');
  await page.waitForSelector('#scan-button:not([disabled])', { timeout: 15_000 });
  await page.click('#scan-button');
  await page.waitForFunction(() => window.cylscanViewer && window.cylscanViewer.pointCount > 1000, null, { timeout: 60_000 });
  log(`scan with the new calibration: ${await page.evaluate(() => window.cylscanViewer.pointCount)} points in the viewer (${elapsed()})`);

  // The check of the sphere passes with it.
  await checkChecks(page, base, { problems, expected });

  // Roll back with nothing kept before this install: the daemon's 404 is an
  // answer, said as a plain message; the calibration stays.
  expected.push(
    /^HTTP 404: POST .*\/api\/v1\/calibration\/rollback$/,
    /^console error: .*status of 404.*\/api\/v1\/calibration\/rollback\)$/,
  );
  await page.click('#cal-rollback');
  await page.waitForFunction(() => /^Nothing to roll back to/.test(document.getElementById('cal-rollback-message').textContent), null, { timeout: 15_000 });
  const nothing = await page.evaluate(() => {
    const node = document.getElementById('cal-rollback-message');
    return { text: node.textContent, className: node.className };
  });
  log(`roll back with nothing kept: "${nothing.text}" (${nothing.className})`);
  if (!nothing.text.includes('no previous calibration is kept')) problems.push(`the roll back's message does not give the daemon's words: "${nothing.text}"`);
  if (/\b(error|warn)\b/.test(nothing.className)) problems.push(`the roll back's 404 is shown as a problem: ${nothing.className}`);
  if (!/^main ✓/.test(await page.textContent('#cal-installed'))) problems.push('the calibration is gone after a roll back with nothing kept');

  // Installed once more, the first install is kept: the roll back is done.
  await page.click('#cal-install');
  await page.waitForFunction(() => /^Installed/.test(document.getElementById('cal-install-message').textContent), null, { timeout: 15_000 });
  const rolled = page.waitForResponse((r) => r.request().method() === 'POST' && /\/calibration\/rollback$/.test(r.url()));
  await page.click('#cal-rollback');
  if ((await rolled).status() !== 200) problems.push(`the second roll back was answered ${(await rolled).status()}`);
  await page.waitForFunction(() => /^Rolled back/.test(document.getElementById('cal-rollback-message').textContent), null, { timeout: 15_000 });
  log(`roll back after a second install: "${await page.textContent('#cal-rollback-message')}"`);
  const status = (await api('status')).json();
  if (!status.calibration?.main) problems.push(`after the roll back the daemon has no calibration of main: ${JSON.stringify(status.calibration)}`);
  if (!/^main ✓/.test(await page.textContent('#cal-installed'))) problems.push(`after the roll back the page says "${await page.textContent('#cal-installed')}"`);

  // A new session would throw the solved one away: the page asks first, and
  // answered No, the session stays.
  const taken = `${targets.boards.length} board pairs and ${targets.planes.length} plane poses`;
  expectedDialog = new RegExp(`^Start a new calibration session\\? The current one \\(${taken}\\) is solved`);
  await page.click('#cal-start');
  for (let i = 0; i < 50 && dialogsSeen.length === 0; i++) await page.waitForTimeout(100);
  if (dialogsSeen.length !== 1) problems.push(`${dialogsSeen.length} question(s) before a new session replaced the solved one`);
  const stayed = (await api('calibration/session')).json();
  if (stayed.state !== 'solved' || stayed.created !== solved.created) problems.push(`the session after No: ${stayed.state}, created ${stayed.created}`);
  if ((await page.getAttribute('#calibration', 'data-state')) !== 'solved') problems.push('the page no longer shows the solved session after No');

  await mkdir(args.out, { recursive: true });
  const shotPath = join(args.out, 'screenshot-calibration.png');
  await page.click('#setup-tab');
  await writeFile(shotPath, await page.screenshot({ fullPage: true }));
  log(`screenshot ${shotPath}; the calibration flow took ${elapsed()}`);
  await judge(page, problems, expected);
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
  console.error(`browser.test: FAILED: not done in ${OVERALL_TIMEOUT_MS[args.flow] / 1000} s`);
  await cleanup().catch(() => {});
  process.exit(1);
}, OVERALL_TIMEOUT_MS[args.flow]);

try {
  await (args.flow === 'calibration' ? runCalibration() : run());
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
