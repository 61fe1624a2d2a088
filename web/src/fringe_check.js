// SPDX-License-Identifier: Apache-2.0
// The fringe check of the set-up view (docs/http-api.md, "Fringe check"):
// answers "is this exposure right for scanning" with a short scan of every
// camera at its settings (POST /api/v1/fringe-check), shown per camera as the
// advice, the figures behind it in plain words, and the picture of the
// fringes' modulation (GET /api/v1/fringe-check/{camera}.jpg, read with
// fetch() so that the bearer token is sent; an <img> cannot send it).
//
// The check stops the live views as a scan does: the page closes them itself
// before it asks (setup.js holdLive), so that no stream is cut or refused
// mid-way, and they come back once the head is idle.

import { ApiError, getBlob, isStatus, postJson } from './api.js';
import { formatExposure, formatFraction, formatGain } from './setup.js';
import { element } from './dom.js';

const ADVICE_TEXT = {
  right: 'Exposure right for scanning',
  raise: 'Too dark: raise the exposure',
  lower: 'Saturated: lower the exposure',
};


function formatCounts(counts) {
  return Number.isFinite(counts) ? `${Number(counts.toPrecision(3))} counts` : '–';
}

export class FringeCheckView {
  // root: the #fringe-check section of index.html; holdLive(kind) and
  // releaseLive() pause and resume the live views around the check.
  constructor(root, { holdLive = () => {}, releaseLive = () => {} } = {}) {
    this.root = root;
    this.holdLive = holdLive;
    this.releaseLive = releaseLive;
    this.button = root.querySelector('#fringe-check-button');
    this.message = root.querySelector('#fringe-check-message');
    this.results = root.querySelector('#fringe-results');
    this.running = false;
    this.headBusy = false;
    this.urls = []; // blob URLs of the pictures shown
    this.abort = null; // the pictures' requests of the check shown
    this.button.addEventListener('click', () => this.run());
    this.updateButton();
  }

  say(text, kind = '') {
    this.message.textContent = text;
    this.message.className = `message ${kind}`;
  }

  // The head's state ('idle', 'scanning', 'error'): no check while it is busy.
  setHeadState(state) {
    this.headBusy = state === 'scanning';
    this.updateButton();
  }

  updateButton() {
    this.button.disabled = this.running || this.headBusy;
    this.button.title = this.headBusy && !this.running ? 'The head is busy: a check can start once it is idle' : '';
  }

  async run() {
    this.running = true;
    this.root.dataset.state = 'checking';
    this.updateButton();
    this.say('checking…', 'muted');
    this.holdLive('fringe');
    try {
      const answer = await postJson('fringe-check', {});
      if (!answer || !Array.isArray(answer.cameras)) throw new Error('the head did not answer a list of cameras');
      this.show(answer.cameras);
      this.say('');
      this.root.dataset.state = 'done';
    } catch (error) {
      this.root.dataset.state = 'failed';
      if (isStatus(error, 401)) this.say('A token is needed to check the fringes.', 'warn');
      else if (isStatus(error, 409)) this.say(`Not now (HTTP 409): ${error.message}`, 'warn');
      else if (error instanceof ApiError) this.say(`The check did not run (HTTP ${error.status}): ${error.message}`, 'error');
      else this.say(`The check did not run: ${error.message}`, 'error');
    } finally {
      this.running = false;
      this.releaseLive();
      this.updateButton();
    }
  }

  // The answer's cameras, each with its picture, in place of the last check's.
  show(cameras) {
    if (this.abort) this.abort.abort();
    const abort = new AbortController();
    this.abort = abort;
    const old = this.urls;
    this.urls = [];
    this.results.replaceChildren(...cameras.map((camera) => this.card(camera, abort.signal)));
    this.results.hidden = cameras.length === 0;
    for (const url of old) URL.revokeObjectURL(url);
  }

  card(camera, signal) {
    const advice = element('p', {
      className: `fringe-advice advice-${camera.advice}`,
      textContent: ADVICE_TEXT[camera.advice] ?? `The head advises: ${camera.advice}`,
    });
    const picture = element('img', { alt: `Fringe modulation seen by camera ${camera.name}` });
    const caption = element('figcaption', {
      className: 'muted',
      textContent: 'Brighter: stronger fringes; red: saturated.',
    });
    const figure = (key, label, value, text, title = '') => {
      const dd = element('dd', { textContent: text });
      dd.dataset.figure = key;
      dd.dataset.value = String(value);
      return [element('dt', { textContent: label, title }), dd];
    };
    const figures = element('dl', { className: 'measures fringe-figures' }, [
      ...figure('usable', 'Usable', camera.usable, `${formatFraction(camera.usable)} of the picture`,
        'share of the pixels whose phase a scan keeps'),
      ...figure('lit', 'Reached by the fringes', camera.lit, `${formatFraction(camera.lit)} of the picture`),
      ...figure('saturated', 'Saturated', camera.saturated, formatFraction(camera.saturated),
        'share of the pixels saturated in some frame'),
      ...figure('peak', 'Brightest crests', camera.peak, `${formatFraction(camera.peak)} of full scale`,
        'the brightest fringe crests; above 100 % they clip'),
      ...figure('modulation', 'Fringe modulation', camera.modulation_median, `${formatCounts(camera.modulation_median)} (median)`,
        'median modulation of the fringes over the pixels they reach'),
      ...figure('settings', 'Checked at', camera.exposure_us,
        `exposure ${formatExposure(camera.exposure_us)}, gain ${formatGain(camera.gain)}`),
    ]);
    const problem = element('p', { className: 'message' });
    const title = element('h3', { textContent: camera.name });
    const node = element('article', { className: 'fringe-camera' }, [
      title,
      advice,
      element('figure', { className: 'fringe-picture' }, [picture, caption]),
      figures,
      problem,
    ]);
    node.dataset.fringeCamera = camera.name;
    node.dataset.advice = camera.advice;

    getBlob(`fringe-check/${encodeURIComponent(camera.name)}.jpg`, signal)
      .then((blob) => {
        // A newer check's pictures have replaced this one's.
        if (signal.aborted) return;
        const url = URL.createObjectURL(blob);
        this.urls.push(url);
        picture.src = url;
      })
      .catch((error) => {
        if (signal.aborted) return;
        picture.hidden = true;
        caption.hidden = true;
        const status = error instanceof ApiError ? ` (HTTP ${error.status})` : '';
        problem.textContent = `No picture${status}: ${error.message}`;
        problem.className = 'message error';
      });
    return node;
  }
}
