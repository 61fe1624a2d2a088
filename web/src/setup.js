// SPDX-License-Identifier: Apache-2.0
// The set-up view: for each camera of the head (GET /api/v1/cameras) its live
// picture, the saturation overlay, the focus measure and saturated fraction
// of each frame, exposure and gain (PATCH /api/v1/cameras/{name}), whether it
// is calibrated, and a full-resolution snapshot (docs/http-api.md, "Cameras").

import { getBlob, getJson, isStatus, patchJson } from './api.js';
import { LiveView } from './live.js';
import { element } from './dom.js';

// Settings are sent once the slider has rested this long.
const DEBOUNCE_MS = 300;
// Exposure and gain sliders have this many positions.
const SLIDER_STEPS = 1000;
// More saturated pixels than this (a fraction) ask for less light.
const SATURATED_LIMIT = 0.001;

const PAUSED_TEXT = 'Live view paused: a scan is running';
// While the head captures for the calibration session or checks the fringes
// (status `capture`, or a capture this page is about to ask for).
const CAPTURE_PAUSED_TEXT = {
  board: 'Live view paused: taking a calibration board pair',
  plane: 'Live view paused: scanning a calibration plane pose',
  fringe: 'Live view paused: checking the fringes',
};
const CAPTURE_KIND = { 'calibration board': 'board', 'calibration plane': 'plane', 'fringe check': 'fringe' };

// A slider position (0..SLIDER_STEPS) for a control's value and back: on a
// log scale when the range allows (exposure spans decades), else linear.
export function sliderScale(min, max, log) {
  const useLog = log && min > 0 && max > min;
  const span = max > min ? max - min : 1;
  return {
    toPosition(value) {
      const v = Math.min(max, Math.max(min, value));
      const t = useLog ? Math.log(v / min) / Math.log(max / min) : (v - min) / span;
      return Math.round(t * SLIDER_STEPS);
    },
    toValue(position) {
      const t = Math.min(1, Math.max(0, position / SLIDER_STEPS));
      return useLog ? min * (max / min) ** t : min + t * span;
    },
  };
}

// A value the slider gives, rounded as a person would type it (3 significant
// digits; whole numbers when the control's values are), within the range.
export function roundControl(value, { min, max, value: current }) {
  const whole = [min, max, current].every(Number.isInteger);
  let v = Number(value.toPrecision(3));
  if (whole) v = Math.round(v);
  return Math.min(max, Math.max(min, v));
}

export function formatExposure(us) {
  if (!Number.isFinite(us)) return '–';
  if (us < 1000) return `${Number(us.toPrecision(3))} µs`;
  if (us < 1e6) return `${Number((us / 1000).toPrecision(3))} ms`;
  return `${Number((us / 1e6).toPrecision(3))} s`;
}

export function formatGain(gain) {
  return Number.isFinite(gain) ? String(Number(gain.toPrecision(4))) : '–';
}

function formatFocus(focus) {
  if (!Number.isFinite(focus)) return '–';
  return focus >= 1000 ? Math.round(focus).toLocaleString() : String(Number(focus.toPrecision(4)));
}

export function formatFraction(fraction) {
  if (!Number.isFinite(fraction)) return '–';
  const percent = fraction * 100;
  return `${percent === 0 ? '0' : percent < 0.01 ? '< 0.01' : Number(percent.toPrecision(3))} %`;
}

const CONTROLS = [
  { key: 'exposure_us', label: 'Exposure', unit: 'µs', log: true, format: formatExposure },
  { key: 'gain', label: 'Gain', unit: '', log: false, format: formatGain },
];

// One camera: its card and live view, and the settings not yet sent.
class CameraCard {
  constructor(view, camera) {
    this.view = view;
    this.name = camera.name;
    this.data = camera;
    this.pending = {};
    this.timer = null;
    this.inflight = false;
    this.bestFocus = NaN;
    this.build();
    this.live = new LiveView({
      camera: this.name,
      canvas: this.canvas,
      onStatus: (state, detail) => this.showLiveStatus(state, detail),
      onFrame: (frame) => this.showFrame(frame),
    });
  }

  build() {
    const id = `camera-${this.name}`;
    const camera = this.data;
    this.calibrated = element('span', { className: 'calibrated' });
    const title = element('h3', { id: `${id}-title` }, [`${this.name} `, this.calibrated]);
    const bits = Number.isFinite(camera.bit_depth) ? `, ${camera.bit_depth}-bit` : '';
    const size = element('p', { className: 'camera-size muted', textContent: `${camera.width} × ${camera.height} px${bits}` });

    this.canvas = element('canvas', { width: camera.width || 640, height: camera.height || 480 });
    this.canvas.setAttribute('role', 'img');
    this.canvas.setAttribute('aria-label', `Live picture of camera ${this.name}`);
    this.liveStatus = element('figcaption', { className: 'live-status', textContent: 'not started' });
    this.liveStatus.setAttribute('role', 'status');
    this.liveBox = element('figure', { className: 'live' }, [this.canvas, this.liveStatus]);
    this.liveBox.dataset.liveState = 'stopped';
    this.liveBox.dataset.frames = '0';

    this.overlay = element('input', { type: 'checkbox', name: 'overlay', id: `${id}-overlay` });
    this.overlay.addEventListener('change', () => this.live.setOverlay(this.overlay.checked));
    const overlayLabel = element('label', { htmlFor: this.overlay.id }, [this.overlay, ' Show saturated pixels in red']);
    this.snapshotButton = element('button', { type: 'button', className: 'snapshot', textContent: 'Save snapshot' });
    this.snapshotButton.title = 'Download one frame at full resolution';
    this.snapshotButton.addEventListener('click', () => this.snapshot());
    const bar = element('div', { className: 'setup-bar' }, [overlayLabel, this.snapshotButton]);

    this.focus = element('dd', { className: 'focus', textContent: '–' });
    this.saturated = element('dd', { className: 'saturated', textContent: '–' });
    const measures = element('dl', { className: 'measures' }, [
      element('dt', { textContent: 'Focus', title: 'variance of the Laplacian over the central half of the picture' }),
      this.focus,
      element('dt', { textContent: 'Saturated' }),
      this.saturated,
    ]);
    this.saturationHint = element('p', { className: 'hint saturation-hint muted' });
    this.focusHint = element('p', { className: 'hint focus-hint muted' });
    this.saturationHint.setAttribute('aria-live', 'polite');

    this.inputs = {};
    const controls = CONTROLS.map((control) => this.buildControl(control, id));

    this.message = element('p', { className: 'message' });
    this.message.setAttribute('role', 'status');

    this.card = element('article', { className: 'panel camera' }, [
      title,
      size,
      this.liveBox,
      bar,
      measures,
      this.saturationHint,
      this.focusHint,
      ...controls,
      this.message,
    ]);
    this.card.dataset.camera = this.name;
    this.card.setAttribute('aria-labelledby', title.id);
    this.update(camera);
    this.clearMeasures();
  }

  // A slider (log scale for exposure) and a number box for the exact value.
  buildControl({ key, label, unit, log }, id) {
    const slider = element('input', { type: 'range', name: key, id: `${id}-${key}`, min: 0, max: SLIDER_STEPS, step: 1 });
    const exact = element('input', { type: 'number', name: `${key}_entry`, step: 'any' });
    exact.setAttribute('aria-label', `${label}${unit ? ` in ${unit}` : ''}, exact value`);
    const labelNode = element('label', { htmlFor: slider.id, textContent: label });
    this.inputs[key] = { slider, exact, log };

    slider.addEventListener('input', () => {
      const value = this.sliderValue(key);
      this.showValue(key, value, { slider: false });
      this.queue(key, value);
    });
    exact.addEventListener('change', () => {
      const value = Number(exact.value);
      if (exact.value.trim() === '' || !Number.isFinite(value)) {
        this.say(`${label}: "${exact.value}" is not a number.`, 'error');
        this.showValue(key, this.data.controls[key].value);
        return;
      }
      // Sent as typed: the head says when it is out of range.
      this.showValue(key, value, { exact: false });
      this.queue(key, value);
    });
    return element('div', { className: 'control' }, [
      labelNode,
      slider,
      element('span', { className: 'exact' }, [exact, unit ? element('span', { className: 'unit', textContent: unit }) : '']),
    ]);
  }

  control(key) {
    return this.data.controls && this.data.controls[key];
  }

  sliderValue(key) {
    const control = this.control(key);
    const { slider, log } = this.inputs[key];
    const scale = sliderScale(control.min, control.max, log);
    return roundControl(scale.toValue(Number(slider.value)), control);
  }

  // Shows `value` on the control's slider and number box (unless told not to
  // touch the one being used).
  showValue(key, value, { slider = true, exact = true } = {}) {
    const control = this.control(key);
    if (!control) return;
    const inputs = this.inputs[key];
    const spec = CONTROLS.find((c) => c.key === key);
    if (slider) inputs.slider.value = String(sliderScale(control.min, control.max, inputs.log).toPosition(value));
    inputs.slider.dataset.value = String(value);
    inputs.slider.setAttribute('aria-valuetext', spec.format(value));
    if (exact) inputs.exact.value = String(value);
  }

  // The camera object from the daemon: range and value of each control, calibration.
  update(camera) {
    this.data = camera;
    for (const { key } of CONTROLS) {
      const control = this.control(key);
      const { slider, exact } = this.inputs[key];
      const usable = control && [control.min, control.max, control.value].every(Number.isFinite);
      slider.disabled = !usable;
      exact.disabled = !usable;
      if (!usable) continue;
      exact.min = String(control.min);
      exact.max = String(control.max);
      // A value the user is still changing is not overwritten.
      if (!(key in this.pending)) this.showValue(key, control.value);
    }
    this.setCalibrated(camera.calibrated);
  }

  setCalibrated(calibrated) {
    this.calibrated.textContent = calibrated ? 'calibrated' : 'not calibrated';
    this.calibrated.className = `calibrated ${calibrated ? 'ok' : 'warn'}`;
    this.calibrated.dataset.calibrated = String(Boolean(calibrated));
  }

  say(text, kind = '') {
    this.message.textContent = text;
    this.message.className = `message ${kind}`;
  }

  queue(key, value) {
    this.pending[key] = value;
    clearTimeout(this.timer);
    this.timer = setTimeout(() => this.flush(), DEBOUNCE_MS);
  }

  // Sends the pending settings, one request at a time.
  async flush() {
    this.timer = null;
    if (this.inflight) {
      this.timer = setTimeout(() => this.flush(), DEBOUNCE_MS);
      return;
    }
    const body = this.pending;
    if (Object.keys(body).length === 0) return;
    this.pending = {};
    this.inflight = true;
    this.card.dataset.saving = 'true';
    const said = CONTROLS.filter((c) => c.key in body)
      .map((c) => `${c.label.toLowerCase()} ${c.format(body[c.key])}`)
      .join(', ');
    try {
      const camera = await patchJson(`cameras/${encodeURIComponent(this.name)}`, body);
      if (camera && camera.controls) this.update(camera);
      this.say(`Set ${said}.`, 'ok');
    } catch (error) {
      if (isStatus(error, 401)) this.say('A token is needed to change the settings.', 'warn');
      else if (isStatus(error, 409)) this.say(`Not set (the head is busy): ${error.message}`, 'error');
      else this.say(`Not set: ${error.message}`, 'error');
      // Back to what the head has.
      for (const key of Object.keys(body)) {
        if (!(key in this.pending) && this.control(key)) this.showValue(key, this.control(key).value);
      }
    } finally {
      this.inflight = false;
      delete this.card.dataset.saving;
    }
  }

  async snapshot() {
    const query = this.overlay.checked ? '?overlay=saturation' : '';
    this.snapshotButton.disabled = true;
    try {
      const blob = await getBlob(`cameras/${encodeURIComponent(this.name)}/snapshot.jpg${query}`);
      const url = URL.createObjectURL(blob);
      const stamp = new Date().toISOString().replace(/[:.]/g, '-').replace(/-\d+Z$/, 'Z');
      const a = element('a', { href: url, download: `${this.name}-${stamp}.jpg` });
      document.body.append(a);
      a.click();
      a.remove();
      setTimeout(() => URL.revokeObjectURL(url), 60000);
    } catch (error) {
      if (isStatus(error, 401)) this.say('A token is needed for a snapshot.', 'warn');
      else this.say(`Snapshot: ${error.message}`, 'error');
    } finally {
      this.snapshotButton.disabled = false;
    }
  }

  clearMeasures() {
    this.focus.textContent = '–';
    this.saturated.textContent = '–';
    delete this.focus.dataset.value;
    delete this.saturated.dataset.value;
    this.saturationHint.textContent = '';
    this.focusHint.textContent = 'Focus: higher is sharper; turn the lens to the highest value.';
  }

  showFrame({ focus, saturated, frames }) {
    this.liveBox.dataset.frames = String(frames);
    this.focus.textContent = formatFocus(focus);
    this.saturated.textContent = formatFraction(saturated);
    this.focus.dataset.value = String(focus);
    this.saturated.dataset.value = String(saturated);
    if (Number.isFinite(focus) && !(focus <= this.bestFocus)) this.bestFocus = focus;
    if (Number.isFinite(this.bestFocus)) {
      this.focusHint.textContent =
        `Focus: higher is sharper; turn the lens to the highest value (best seen: ${formatFocus(this.bestFocus)}).`;
    }
    let hint = '';
    let kind = 'muted';
    if (saturated > SATURATED_LIMIT) {
      hint = `More than ${SATURATED_LIMIT * 100} % of the pixels are saturated: lower the exposure or the gain.`;
      kind = 'warn';
    } else if (saturated > 0) {
      hint = `A few saturated pixels (under ${SATURATED_LIMIT * 100} %): fine.`;
    } else if (saturated === 0) {
      hint = 'No saturated pixels.';
    }
    if (this.saturationHint.textContent !== hint) this.saturationHint.textContent = hint;
    this.saturationHint.className = `hint saturation-hint ${kind}`;
  }

  showLiveStatus(state, detail) {
    this.liveBox.dataset.liveState = state;
    let text;
    let kind = '';
    if (state === 'connecting') text = 'connecting…';
    else if (state === 'live') text = 'live';
    else if (state === 'paused') text = this.view.pausedText();
    else if (state === 'unauthorized') text = 'a token is needed for the live view';
    else if (state === 'bad-frames') {
      text = 'the frames received cannot be decoded';
      kind = 'error';
    } else if (state === 'retry') {
      text = `${detail.reason}: trying again in ${Math.max(1, Math.round(detail.wait / 1000))} s`;
      if (detail.error) kind = 'error';
    } else text = 'stopped';
    this.liveStatus.textContent = text;
    this.liveStatus.className = `live-status ${kind}`;
    this.view.liveStateChanged();
  }
}

export class SetupView {
  // root: the set-up view's element, holding #setup-message, #live-paused and #camera-cards.
  constructor(root) {
    this.root = root;
    this.message = root.querySelector('#setup-message');
    this.paused = root.querySelector('#live-paused');
    this.list = root.querySelector('#camera-cards');
    this.cards = new Map();
    this.shown = false;
    this.loaded = false;
    this.loading = null;
    this.scanning = false; // the head scans or captures (state events)
    this.capture = null; // 'board' | 'plane' while the head captures for the calibration
    this.held = null; // 'board' | 'plane' while this page captures
    this.calibration = null; // the status' cameras, newer than the list when a calibration is installed
    document.addEventListener('visibilitychange', () => this.streamAsNeeded());
    // What a test (and a curious user) can read of the view.
    window.cylscanSetup = { cameras: [] };
  }

  say(text, kind = '') {
    this.message.textContent = text;
    this.message.className = `message ${kind}`;
    this.message.hidden = !text;
  }

  show() {
    this.shown = true;
    if (!this.loaded) this.load();
    this.streamAsNeeded();
  }

  hide() {
    this.shown = false;
    this.streamAsNeeded();
  }

  // Streams only while the view is on screen: each stream costs the head a
  // JPEG encoder and the network a few megabits.
  streamAsNeeded() {
    const wanted = this.shown && !document.hidden;
    for (const card of this.cards.values()) {
      if (wanted) card.live.start();
      else card.live.stop();
    }
  }

  async load() {
    if (this.loading) return this.loading;
    this.say('Loading the cameras…', 'muted');
    this.loading = (async () => {
      try {
        const cameras = await getJson('cameras');
        if (!Array.isArray(cameras)) throw new Error('the head did not answer a list of cameras');
        this.build(cameras);
        this.loaded = true;
        this.say(cameras.length === 0 ? 'The head reports no camera.' : '');
        this.streamAsNeeded();
      } catch (error) {
        if (isStatus(error, 401)) this.say('A token is needed to set up the cameras.', 'muted');
        else if (isStatus(error, 404)) {
          this.say(`This head offers no camera set-up (${error.message}).`, 'error');
        } else this.say(`Cameras: ${error.message}`, 'error');
      } finally {
        this.loading = null;
      }
    })();
    return this.loading;
  }

  build(cameras) {
    for (const card of this.cards.values()) card.live.stop();
    this.cards.clear();
    this.list.replaceChildren();
    for (const camera of cameras) {
      const card = new CameraCard(this, camera);
      card.live.setScanning(this.livePaused());
      this.cards.set(camera.name, card);
      this.list.append(card.card);
    }
    if (this.calibration) this.setCalibration(this.calibration);
    window.cylscanSetup.cameras = cameras.map((c) => c.name);
    this.liveStateChanged();
  }

  // The head's state ('idle', 'scanning', 'error') and, while it captures for
  // the calibration session or checks the fringes, the status' `capture`: no
  // live view meanwhile.
  setHeadState(state, capture = null) {
    const scanning = state === 'scanning';
    const kind = scanning ? CAPTURE_KIND[capture] ?? null : null;
    const was = this.livePaused();
    const text = this.pausedText();
    this.scanning = scanning;
    this.capture = kind;
    this.applyPause(was, text);
  }

  // A capture this page is about to ask for ('board', 'plane', 'fringe'): the
  // live views close their streams now rather than have the daemon cut them.
  holdLive(kind) {
    const was = this.livePaused();
    const text = this.pausedText();
    this.held = kind;
    if (!was) {
      for (const card of this.cards.values()) card.live.setScanning(true, { close: true });
    }
    this.applyPause(true, text);
  }

  // The capture is over: the live views come back once the head is idle.
  releaseLive() {
    const was = this.livePaused();
    const text = this.pausedText();
    this.held = null;
    this.applyPause(was, text);
  }

  livePaused() {
    return this.scanning || this.held !== null;
  }

  pausedText() {
    const kind = this.held ?? this.capture;
    return kind ? CAPTURE_PAUSED_TEXT[kind] : PAUSED_TEXT;
  }

  // After a change of what pauses the live views: each is told only when
  // paused turns to not or back (telling it again would cut short its wait
  // before a retry), and its words follow the reason.
  applyPause(wasPaused, wasText) {
    const paused = this.livePaused();
    for (const card of this.cards.values()) {
      if (paused !== wasPaused) card.live.setScanning(paused);
      else if (paused && card.live.state === 'paused' && this.pausedText() !== wasText) card.showLiveStatus('paused');
    }
    this.paused.textContent = this.pausedText();
    this.liveStateChanged();
  }

  // The status' cameras ([{name, calibrated}]): a calibration installed since the list was read.
  setCalibration(cameras) {
    if (!Array.isArray(cameras)) return;
    this.calibration = cameras;
    for (const camera of cameras) {
      const card = this.cards.get(camera.name);
      if (card && typeof camera.calibrated === 'boolean') card.setCalibrated(camera.calibrated);
    }
  }

  liveStateChanged() {
    const paused = [...this.cards.values()].some((card) => card.live.state === 'paused');
    this.paused.hidden = !(this.livePaused() || paused) || this.cards.size === 0;
  }

  // After the user has given a token.
  retryNow() {
    if (!this.loaded && this.shown) this.load();
    for (const card of this.cards.values()) card.live.retryNow();
  }
}

export { PAUSED_TEXT };
