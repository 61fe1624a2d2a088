// SPDX-License-Identifier: Apache-2.0
// The page of cylscand, in two views. Scan: head status, the Scan button, live
// progress, the stored scans and, for the selected one, its previews and point
// cloud. Set-up: each camera's live picture and settings (setup.js), the
// fringe check of their exposure (fringe_check.js), the calibration session
// (calibration.js), the checks against a known artifact with their
// history (checks.js), and the system with its A/B updates (system.js).

import './app.css';
import { STALE, getBlob, getBytes, getJson, isStatus, newestOnly, onAuthNeeded, postJson, remove, setToken, token } from './api.js';
import { CalibrationView } from './calibration.js';
import { ChecksView } from './checks.js';
import { connectEvents } from './events.js';
import { FringeCheckView } from './fringe_check.js';
import { SetupView } from './setup.js';
import { SystemView } from './system.js';
import { PointCloudViewer } from './viewer.js';
import { element } from './dom.js';

const $ = (id) => document.getElementById(id);
const DOWNLOADS = ['cloud.ply', 'depth.tiff', 'texture.png'];
const PREVIEWS = { 'img-texture': 'texture.png', 'img-phase': 'phase.png', 'img-depth': 'depth.png' };

const state = {
  scans: [], // newest first, as the daemon lists them
  selected: null, // id of the scan shown below the list
  started: null, // id of the scan this page started, selected when it is done
  previewUrls: [],
  loadAbort: null,
  viewer: null,
  capture: null, // the status' `capture` while the head captures for the calibration session
};

// What the test (and a curious user) can read of the viewer.
window.cylscanViewer = { pointCount: 0, error: null };

// ----------------------------------------------------------------- formatting

function formatBytes(n) {
  if (!Number.isFinite(n)) return '–';
  const units = ['B', 'KiB', 'MiB', 'GiB', 'TiB'];
  let i = 0;
  while (n >= 1024 && i < units.length - 1) {
    n /= 1024;
    i++;
  }
  return `${n.toFixed(i === 0 ? 0 : 1)} ${units[i]}`;
}

function formatTime(iso) {
  if (!iso) return '–';
  const date = new Date(iso);
  return Number.isNaN(date.getTime()) ? iso : date.toLocaleString();
}

const isUnauthorized = (error) => isStatus(error, 401);

function showMessage(text, kind = '') {
  const box = $('scan-message');
  box.textContent = text;
  box.className = `message ${kind}`;
}

// --------------------------------------------------------------------- status

// `capture`: what the head captures for the calibration session, if anything.
function showState(value, capture = null) {
  const node = $('st-state');
  state.capture = value === 'scanning' ? capture ?? null : null;
  node.textContent = value ? `${value}${state.capture ? ` (${state.capture})` : ''}` : '–';
  node.className = `state state-${value}`;
  $('scan-button').disabled = value === 'scanning';
  if (setup && value) setup.setHeadState(value, state.capture);
  if (checks && value) checks.setHeadState(value);
  if (fringeCheck && value) fringeCheck.setHeadState(value);
  if (calibration && value) calibration.setHeadState(value);
}

// Status requests overlap (state events, installs, scans ending), and under
// load their answers can come back out of order: an answer older than the
// one shown would put back what that one replaced (a calibration shown as
// not installed just after its install). Such an answer is dropped.
const getStatus = newestOnly(() => getJson('status'));

async function refreshStatus() {
  try {
    const status = await getStatus();
    if (status === STALE) return;
    showState(status.state, status.capture);
    $('st-board').textContent = status.board ?? '–';
    $('st-version').textContent = status.version ?? '–';
    const calibrated = status.calibration && status.calibration.main;
    const cal = $('st-calibration');
    cal.textContent = calibrated ? 'installed' : 'not installed';
    cal.className = calibrated ? 'ok' : 'warn';
    $('st-disk').textContent = formatBytes(status.disk_free_bytes);
    if (setup) setup.setCalibration(status.cameras);
    if (calibration) calibration.setInstalled(status.calibration);
    const lastError = $('last-error');
    lastError.hidden = !status.last_error;
    lastError.textContent = status.last_error ? `Last error: ${status.last_error}` : '';
  } catch (error) {
    if (!isUnauthorized(error)) showMessage(`Status: ${error.message}`, 'error');
  }
}

function showProgress(event) {
  $('progress-box').hidden = false;
  $('progress-bar').value = event.progress ?? 0;
  const set = event.set ? `, ${event.set} set` : '';
  $('progress-text').textContent =
    `${Math.round((event.progress ?? 0) * 100)} % — frame ${event.frames_done}/${event.frames_total}${set}`;
}

// ---------------------------------------------------------------------- scans

async function startScan() {
  const button = $('scan-button');
  button.disabled = true;
  showMessage('Starting…');
  try {
    const { id } = await postJson('scans', {});
    state.started = id;
    showMessage(`Scan ${id} started.`, 'ok');
    $('progress-box').hidden = false;
    $('progress-bar').value = 0;
    $('progress-text').textContent = 'waiting for the first frame…';
    refreshStatus();
  } catch (error) {
    button.disabled = false;
    if (isStatus(error, 409)) {
      showMessage('The head is busy with another scan; try again when it is done.', 'warn');
      refreshStatus();
    } else if (isStatus(error, 507)) {
      showMessage('No room on the disk for another scan: delete some scans.', 'error');
    } else if (isStatus(error, 401)) {
      showMessage('A token is needed to scan.', 'warn');
    } else {
      showMessage(`Scan refused: ${error.message}`, 'error');
    }
  }
}

async function refreshScans() {
  try {
    state.scans = await getJson('scans');
    renderScans();
    if (!state.selected) {
      const newestDone = state.scans.find((s) => s.state === 'done');
      if (newestDone) select(newestDone.id);
    }
  } catch (error) {
    // A 401 has shown the token box, which says what to do.
    if (!isUnauthorized(error)) showMessage(`Scans: ${error.message}`, 'error');
  }
}

function upsertScan(scan) {
  const at = state.scans.findIndex((s) => s.id === scan.id);
  if (at >= 0) state.scans[at] = scan;
  else state.scans.unshift(scan);
  state.scans.sort((a, b) => (a.created < b.created ? 1 : a.created > b.created ? -1 : 0));
  renderScans();
}

// A link that downloads with the token when there is one (a plain link can't send headers).
function downloadLink(id, file) {
  const path = `scans/${encodeURIComponent(id)}/${file}`;
  const link = element('a', { href: `api/v1/${path}`, textContent: file, download: `${id}-${file}` });
  link.addEventListener('click', async (event) => {
    if (!token()) return;
    event.preventDefault();
    try {
      const url = URL.createObjectURL(await getBlob(path));
      const a = element('a', { href: url, download: link.download });
      document.body.append(a);
      a.click();
      a.remove();
      setTimeout(() => URL.revokeObjectURL(url), 60000);
    } catch (error) {
      showMessage(`Download of ${file}: ${error.message}`, 'error');
    }
  });
  return link;
}

function renderScans() {
  const rows = $('scan-rows');
  rows.replaceChildren();
  $('no-scans').hidden = state.scans.length > 0;
  for (const scan of state.scans) {
    const row = element('tr', { className: scan.id === state.selected ? 'selected' : '' });
    row.dataset.id = scan.id;
    const files = element('td', { className: 'files' });
    if (scan.state === 'done') {
      for (const file of DOWNLOADS) {
        if (!scan.files || scan.files.includes(file)) files.append(downloadLink(scan.id, file), ' ');
      }
    }
    let stateText = scan.state;
    if (scan.state === 'running') stateText += ` ${Math.round((scan.progress ?? 0) * 100)} %`;
    const stateCell = element('td', { className: `state state-${scan.state}`, textContent: stateText });
    if (scan.error) stateCell.title = scan.error;
    const del = element('button', { type: 'button', className: 'delete', textContent: 'Delete' });
    del.disabled = scan.state === 'running' || scan.state === 'queued';
    del.addEventListener('click', (event) => {
      event.stopPropagation();
      deleteScan(scan.id);
    });
    row.append(
      element('td', { className: 'id', textContent: scan.id }),
      stateCell,
      element('td', {
        textContent: formatTime(scan.created) + (Number.isFinite(scan.duration_s) ? ` (${scan.duration_s.toFixed(1)} s)` : ''),
      }),
      element('td', { className: 'num', textContent: Number.isFinite(scan.points) ? scan.points.toLocaleString() : '–' }),
      files,
      element('td', {}, [del]),
    );
    if (scan.state === 'done') row.addEventListener('click', () => select(scan.id));
    rows.append(row);
  }
}

async function deleteScan(id) {
  if (!window.confirm(`Delete scan ${id} and its files?`)) return;
  try {
    await remove(`scans/${encodeURIComponent(id)}`);
    state.scans = state.scans.filter((s) => s.id !== id);
    if (state.selected === id) unselect();
    renderScans();
    refreshStatus();
  } catch (error) {
    showMessage(`Delete ${id}: ${error.message}`, 'error');
  }
}

// ------------------------------------------------------------- selected scan

function unselect() {
  state.selected = null;
  $('selected').hidden = true;
  if (state.loadAbort) state.loadAbort.abort();
  for (const url of state.previewUrls) URL.revokeObjectURL(url);
  state.previewUrls = [];
  if (state.viewer) state.viewer.clear();
  window.cylscanViewer.pointCount = 0;
  window.cylscanViewer.error = null;
  for (const img of Object.keys(PREVIEWS)) {
    $(img).removeAttribute('src');
    $(img).hidden = false;
    const caption = $(img).parentElement.querySelector('figcaption');
    caption.textContent = caption.dataset.name;
    caption.className = '';
  }
}

async function select(id) {
  if (state.selected === id) return;
  unselect();
  state.selected = id;
  renderScans();
  $('selected').hidden = false;
  $('selected-id').textContent = id;
  const abort = new AbortController();
  state.loadAbort = abort;
  const base = `scans/${encodeURIComponent(id)}`;

  // A scan lists the files it made (a scan without a calibration has no
  // cloud and no depth): those it lacks are said so, not fetched.
  const scan = state.scans.find((s) => s.id === id);
  const has = (file) => !scan || !Array.isArray(scan.files) || scan.files.includes(file);
  for (const [img, file] of Object.entries(PREVIEWS)) {
    const caption = $(img).parentElement.querySelector('figcaption');
    if (!has(file)) {
      $(img).hidden = true;
      caption.textContent = `${caption.dataset.name}: not made by this scan`;
      caption.className = 'muted';
      continue;
    }
    getBlob(`${base}/${file}`, abort.signal)
      .then((blob) => {
        const url = URL.createObjectURL(blob);
        state.previewUrls.push(url);
        $(img).src = url;
      })
      .catch((error) => {
        if (abort.signal.aborted) return;
        caption.textContent = `${caption.dataset.name}: ${error.message}`;
        caption.className = 'error';
      });
  }

  const info = $('viewer-info');
  info.className = 'muted';
  if (!has('cloud.ply')) {
    info.textContent = 'No point cloud: the scan was made without a calibration.';
    showCameraLegend([]);
    return;
  }
  info.textContent = 'loading the point cloud…';
  try {
    if (!state.viewer) state.viewer = new PointCloudViewer($('viewer'));
    const bytes = await getBytes(`${base}/cloud.ply`, abort.signal);
    if (abort.signal.aborted) return;
    const count = state.viewer.load(bytes);
    window.cylscanViewer.pointCount = count;
    showCameraLegend(state.viewer.cameras);
    info.textContent = `${count.toLocaleString()} points (${formatBytes(bytes.byteLength)}) — drag to orbit, wheel to zoom`;
  } catch (error) {
    if (abort.signal.aborted) return;
    window.cylscanViewer.error = error.message;
    info.textContent = `Point cloud: ${error.message}`;
    info.className = 'error';
  }
}

// A merged 360° cloud: the viewer coloured by camera, and the legend of the
// cameras (name, colour, point count). A cloud whose points all come from one
// camera (no camera property, or a ring scan with main alone) has nothing to
// tell apart: no legend, coloured by intensity.
function showCameraLegend(cameras) {
  const legend = $('camera-legend');
  legend.replaceChildren();
  window.cylscanViewer.cameras = cameras.map(({ name, points }) => ({ name, points }));
  if (cameras.filter((camera) => camera.points > 0).length < 2) {
    legend.hidden = true;
    if ($('colour-mode').value === 'camera') {
      $('colour-mode').value = 'intensity';
      if (state.viewer) state.viewer.colour('intensity');
    }
    return;
  }
  for (const camera of cameras) {
    const item = document.createElement('li');
    const swatch = document.createElement('span');
    swatch.className = 'swatch';
    swatch.style.background = `#${camera.colour.toString(16).padStart(6, '0')}`;
    item.append(swatch, `${camera.name}: ${camera.points.toLocaleString()} points`);
    legend.append(item);
  }
  legend.hidden = false;
  $('colour-mode').value = 'camera';
  state.viewer.colour('camera');
}

// --------------------------------------------------------------------- events

function onEvent(type, data) {
  if (type === 'state') {
    showState(data.state, data.capture);
    if (data.state !== 'scanning') refreshStatus();
  } else if (type === 'progress' && state.capture) {
    // A capture of the calibration session: no scan of the list.
    calibration.onCaptureProgress(data);
  } else if (type === 'progress') {
    showProgress(data);
    checks.onProgress(data);
    const scan = state.scans.find((s) => s.id === data.id);
    if (scan) {
      scan.progress = data.progress;
      scan.frames_done = data.frames_done;
      scan.state = 'running';
      renderScans();
    }
  } else if (type === 'scan') {
    upsertScan(data);
    if (data.state === 'done' || data.state === 'failed') {
      $('progress-box').hidden = true;
      refreshStatus();
    }
    if (data.state === 'done' && (data.id === state.started || !state.selected)) {
      state.started = null;
      select(data.id);
    }
    if (data.state === 'failed') showMessage(`Scan ${data.id} failed: ${data.error ?? 'unknown error'}`, 'error');
  } else if (type === 'error') {
    showMessage(`Scan ${data.id ?? ''} failed: ${data.error}`, 'error');
  } else if (type === 'check') {
    checks.onCheck(data);
  } else if (type === 'calibration') {
    calibration.onSession(data);
  } else if (type === 'calibration_progress') {
    calibration.onSolveProgress(data);
  } else if (type === 'update') {
    system.onUpdate(data);
  }
}

function onConnection(what, detail) {
  const badge = $('connection');
  if (what === 'open') {
    badge.textContent = 'live';
    badge.className = 'badge ok';
    // Whatever happened while the stream was down.
    refreshStatus();
    refreshScans();
    if (checks.loaded) checks.refresh();
    if (calibration.loaded) calibration.refresh();
    if (system.loaded) system.refresh();
  } else if (what === 'unauthorized') {
    badge.textContent = 'token needed';
    badge.className = 'badge warn';
    askForToken();
  } else {
    badge.textContent = `reconnecting in ${Math.round(detail.wait / 1000)} s`;
    badge.className = 'badge warn';
  }
}

// ---------------------------------------------------------------------- views

let setup = null;
let checks = null;
let fringeCheck = null;
let calibration = null;
let system = null;
const VIEWS = { scan: { tab: 'scan-tab', panel: 'scan-view' }, setup: { tab: 'setup-tab', panel: 'setup-view' } };

// Shows one view; the URL's fragment (#setup) keeps it across a reload.
function showView(name) {
  for (const [view, { tab, panel }] of Object.entries(VIEWS)) {
    const selected = view === name;
    $(tab).setAttribute('aria-selected', String(selected));
    $(tab).tabIndex = selected ? 0 : -1;
    $(panel).hidden = !selected;
  }
  if (name === 'setup') {
    setup.show();
    calibration.show();
    checks.show();
    system.refresh();
  } else setup.hide();
  const url = name === 'scan' ? location.pathname + location.search : '#setup';
  if ((location.hash === '#setup') !== (name === 'setup')) history.replaceState(null, '', url);
}

// The tabs as WAI-ARIA tabs: arrows, Home and End move between them.
function setupTabs() {
  const names = Object.keys(VIEWS);
  for (const name of names) $(VIEWS[name].tab).addEventListener('click', () => showView(name));
  $('scan-tab').parentElement.addEventListener('keydown', (event) => {
    const at = names.findIndex((name) => $(VIEWS[name].tab) === document.activeElement);
    if (at < 0) return;
    let next = null;
    if (event.key === 'ArrowRight') next = (at + 1) % names.length;
    else if (event.key === 'ArrowLeft') next = (at - 1 + names.length) % names.length;
    else if (event.key === 'Home') next = 0;
    else if (event.key === 'End') next = names.length - 1;
    if (next === null) return;
    event.preventDefault();
    showView(names[next]);
    $(VIEWS[names[next]].tab).focus();
  });
  window.addEventListener('hashchange', () => showView(location.hash === '#setup' ? 'setup' : 'scan'));
  showView(location.hash === '#setup' ? 'setup' : 'scan');
}

// ---------------------------------------------------------------------- token

let events = null;

function askForToken() {
  $('token-box').hidden = false;
}

function setupToken() {
  onAuthNeeded(askForToken);
  $('token-form').addEventListener('submit', (event) => {
    event.preventDefault();
    setToken($('token-input').value.trim());
    $('token-input').value = '';
    $('token-box').hidden = true;
    refreshStatus();
    refreshScans();
    if (events) events.retryNow();
    setup.retryNow();
    if (!$('setup-view').hidden) {
      checks.refresh();
      calibration.refresh();
    }
  });
}

// ----------------------------------------------------------------------- main

function main() {
  setup = new SetupView($('setup-view'));
  checks = new ChecksView($('checks'));
  system = new SystemView($('system'));
  fringeCheck = new FringeCheckView($('fringe-check'), {
    holdLive: (kind) => setup.holdLive(kind),
    releaseLive: () => setup.releaseLive(),
  });
  calibration = new CalibrationView($('calibration'), {
    holdLive: (kind) => setup.holdLive(kind),
    releaseLive: () => setup.releaseLive(),
    onInstalled: refreshStatus,
  });
  setupToken();
  setupTabs();
  $('scan-button').addEventListener('click', startScan);
  $('colour-mode').addEventListener('change', (event) => state.viewer && state.viewer.colour(event.target.value));
  $('reset-view').addEventListener('click', () => state.viewer && state.viewer.frame());
  refreshStatus();
  refreshScans();
  events = connectEvents({ onEvent, onConnection });
}

main();
