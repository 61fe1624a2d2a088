// SPDX-License-Identifier: Apache-2.0
// The checks against a known artifact, in the set-up view (docs/http-api.md,
// "Checks against a known artifact"): a form that starts one (POST
// /api/v1/checks), the latest check's figures with its verdict, and the
// history (GET /api/v1/checks) as a plot of each check's radius error inside
// its ±tolerance band and as a table, so that a head drifting from its
// calibration shows at a glance. Refreshed by the event stream's `check`
// events; the plot's geometry is checks_plot.js.

import { getJson, isStatus, postJson } from './api.js';
import { checksPlot, formatSigned, radiusError } from './checks_plot.js';
import { element } from './dom.js';

const SVG = 'http://www.w3.org/2000/svg';
const PLOT = { width: 640, height: 200 };

function svg(tag, attributes = {}, children = []) {
  const node = document.createElementNS(SVG, tag);
  for (const [name, value] of Object.entries(attributes)) node.setAttribute(name, String(value));
  for (const child of children) node.append(child);
  return node;
}

const mm = (value, decimals = 3) => (Number.isFinite(value) ? `${value.toFixed(decimals)} mm` : '–');
const signedMm = (value) => (Number.isFinite(value) ? `${formatSigned(value, 3)} mm` : '–');

function formatTime(iso) {
  const date = new Date(iso);
  return iso && !Number.isNaN(date.getTime()) ? date.toLocaleString() : iso || '–';
}

function shortTime(ms) {
  return new Date(ms).toLocaleString(undefined, { dateStyle: 'short', timeStyle: 'short' });
}

// Newest first, as the daemon lists them; ISO 8601 UTC times sort as text.
function byNewest(a, b) {
  if (a.created !== b.created) return a.created < b.created ? 1 : -1;
  return a.id < b.id ? 1 : a.id > b.id ? -1 : 0;
}

// What a check came to: 'pass', 'fail' (measured, out of tolerance),
// 'failed' (nothing measured), 'running' (queued or running).
export function outcomeOf(check) {
  if (check.state === 'done') return check.pass ? 'pass' : 'fail';
  if (check.state === 'failed') return 'failed';
  return 'running';
}

const OUTCOME_TEXT = { pass: 'PASS', fail: 'FAIL', failed: 'no result', running: 'running…' };

export class ChecksView {
  // root: the #checks section of index.html.
  constructor(root) {
    this.root = root;
    const $ = (id) => root.querySelector(`#${id}`);
    this.form = $('check-form');
    this.button = $('check-button');
    this.radius = $('check-radius');
    this.tolerance = $('check-tolerance');
    this.message = $('check-message');
    this.latest = $('check-latest');
    this.plot = $('check-plot');
    this.rows = $('check-rows');
    this.empty = $('no-checks');
    this.fields = {};
    for (const node of root.querySelectorAll('[data-field]')) this.fields[node.dataset.field] = node;

    this.checks = []; // newest first
    this.loaded = false;
    this.loading = null;
    this.reload = false;
    this.busy = false; // the head scans
    this.starting = false; // a POST in flight
    this.started = null; // id of the check this page started
    this.form.addEventListener('submit', (event) => {
      event.preventDefault();
      this.start();
    });
    // With no check measured yet the band drawn is the tolerance typed in.
    this.tolerance.addEventListener('input', () => this.renderPlot());
    this.render();
  }

  say(text, kind = '') {
    this.message.textContent = text;
    this.message.className = `message ${kind}`;
    this.message.hidden = !text;
  }

  show() {
    if (!this.loaded) this.refresh();
  }

  // Reads the history again; a refresh asked for while one is in flight runs after it.
  async refresh() {
    if (this.loading) {
      this.reload = true;
      return this.loading;
    }
    this.loading = (async () => {
      try {
        do {
          this.reload = false;
          const checks = await getJson('checks');
          if (!Array.isArray(checks)) throw new Error('the head did not answer a list of checks');
          this.setChecks(checks);
          this.loaded = true;
          this.root.dataset.loaded = 'true';
        } while (this.reload);
        if (this.message.dataset.from === 'load') this.say('');
      } catch (error) {
        this.message.dataset.from = 'load';
        if (isStatus(error, 401)) this.say('A token is needed to see the checks.', 'muted');
        else if (isStatus(error, 404)) {
          this.say(`This head offers no checks (${error.message}).`, 'error');
        } else this.say(`Checks: ${error.message}`, 'error');
      } finally {
        this.loading = null;
      }
    })();
    return this.loading;
  }

  // The list from the daemon: the running check may also be in the history
  // for a moment as it finishes, so one record per id (the first, newest).
  setChecks(checks) {
    const seen = new Set();
    this.checks = checks.filter((check) => check && typeof check.id === 'string' && !seen.has(check.id) && seen.add(check.id));
    this.checks.sort(byNewest);
    this.render();
  }

  // A `check` event: the record as it is now (queued, running, done, failed).
  onCheck(check) {
    if (!check || typeof check.id !== 'string') return;
    const at = this.checks.findIndex((c) => c.id === check.id);
    if (at >= 0) this.checks[at] = check;
    else this.checks.push(check);
    this.checks.sort(byNewest);
    // The latest check's box now says how it ended (a failure with its reason).
    if (check.id === this.started && (check.state === 'done' || check.state === 'failed')) {
      this.started = null;
      this.say('');
    }
    this.render();
    // The history as the head keeps it, once a check is in it.
    if (check.state === 'done' || check.state === 'failed') this.refresh();
  }

  // A `progress` event: the scan of the check this page started.
  onProgress(event) {
    if (!this.started || event.id !== this.started) return;
    const percent = Math.round((event.progress ?? 0) * 100);
    this.say(percent >= 100 ? `Check ${event.id}: measuring the sphere…` : `Check ${event.id}: scanning the sphere, ${percent} %`, 'muted');
  }

  // The head's state ('idle', 'scanning', 'error'): no check while it scans.
  setHeadState(state) {
    this.busy = state === 'scanning';
    this.updateButton();
  }

  updateButton() {
    this.button.disabled = this.busy || this.starting;
    this.button.title = this.busy ? 'The head is busy: a check can start once it is idle' : '';
  }

  async start() {
    const body = {
      artifact: this.form.elements.artifact.value,
      radius_mm: Number(this.radius.value),
      tolerance_mm: Number(this.tolerance.value),
    };
    this.starting = true;
    this.updateButton();
    delete this.message.dataset.from;
    this.say('Starting the check…', 'muted');
    try {
      const { id } = await postJson('checks', body);
      // On a quick head the check's final event may come before this answer.
      const known = this.checks.find((check) => check.id === id);
      if (known && (known.state === 'done' || known.state === 'failed')) this.say('');
      else {
        this.started = id;
        this.say(`Check ${id}: scanning the ${body.artifact}…`, 'muted');
      }
      this.refresh();
    } catch (error) {
      // The daemon's words: not calibrated, busy, a value out of range.
      if (isStatus(error, 401)) this.say('A token is needed to run a check.', 'warn');
      else this.say(`Check refused: ${error.message}`, 'error');
    } finally {
      this.starting = false;
      this.updateButton();
    }
  }

  render() {
    this.renderLatest();
    this.renderPlot();
    this.renderTable();
  }

  renderLatest() {
    const check = this.checks[0];
    this.latest.hidden = !check;
    if (!check) return;
    const outcome = outcomeOf(check);
    this.latest.dataset.id = check.id;
    this.latest.dataset.outcome = outcome;
    const f = this.fields;
    f.verdict.textContent = OUTCOME_TEXT[outcome];
    f.verdict.className = `verdict verdict-${outcome}`;
    f.verdict.dataset.pass = String(outcome === 'pass');
    f.id.textContent = check.id;
    f.created.textContent = formatTime(check.created);
    f.nominal.textContent = `${check.artifact ?? 'sphere'}, radius ${mm(check.radius_mm)} ± ${mm(check.tolerance_mm)}`;
    f.measured.textContent = mm(check.measured_radius_mm, 4);
    f.measured.dataset.value = String(check.measured_radius_mm ?? '');
    const error = radiusError(check);
    f.error.textContent = signedMm(error);
    f.error.className = error === null ? '' : Math.abs(error) <= check.tolerance_mm ? 'within' : 'beyond';
    f.rmse.textContent = mm(check.rmse_mm);
    f.pf.textContent = mm(check.probing_error_form_mm);
    f.ps.textContent = signedMm(check.probing_error_size_mm);
    f.points.textContent = Number.isFinite(check.points) && check.state === 'done' ? check.points.toLocaleString() : '–';
    f.reason.hidden = !check.error;
    f.reason.textContent = check.error ? `The check measured nothing: ${check.error}` : '';
  }

  renderPlot() {
    const tolerance = Number(this.tolerance.value);
    const model = checksPlot(this.checks, { ...PLOT, tolerance: tolerance > 0 ? tolerance : 0.1 });
    const { area } = model;
    const nodes = [];
    nodes.push(svg('path', { class: 'band', d: model.band }));
    for (const tick of model.yTicks) {
      nodes.push(svg('line', { class: tick.value === 0 ? 'zero' : 'grid', x1: area.left, x2: area.right, y1: tick.y, y2: tick.y }));
      nodes.push(svg('text', { class: 'tick', x: area.left - 6, y: tick.y, 'text-anchor': 'end', 'dominant-baseline': 'middle' }, [tick.label]));
    }
    nodes.push(svg('rect', { class: 'frame', x: area.left, y: area.top, width: area.right - area.left, height: area.bottom - area.top }));
    const midY = (area.top + area.bottom) / 2;
    nodes.push(
      svg('text', { class: 'axis', transform: `translate(12 ${midY}) rotate(-90)`, 'text-anchor': 'middle', 'dominant-baseline': 'middle' }, [
        'radius error, mm',
      ]),
    );
    model.xLabels.forEach((label, i) => {
      const anchor = model.xLabels.length === 1 ? 'middle' : i === 0 ? 'start' : 'end';
      nodes.push(svg('text', { class: 'tick', x: label.x, y: PLOT.height - 6, 'text-anchor': anchor }, [shortTime(label.time)]));
    });
    if (model.dots.length === 0) {
      nodes.push(svg('text', { class: 'axis', x: (area.left + area.right) / 2, y: area.top + 16, 'text-anchor': 'middle' }, ['no measured check yet']));
    }
    for (const dot of model.dots) {
      const when = dot.time === null ? '' : `${shortTime(dot.time)}: `;
      const title = `${when}${formatSigned(dot.error, 3)} mm (± ${dot.tolerance} mm) ${dot.pass ? 'PASS' : 'FAIL'}${dot.clipped ? ', beyond the plot' : ''}`;
      const circle = svg('circle', { class: `check-dot ${dot.pass ? 'pass' : 'fail'}${dot.clipped ? ' clipped' : ''}`, cx: dot.x, cy: dot.y, r: 4.5 }, [
        svg('title', {}, [title]),
      ]);
      circle.dataset.id = dot.id;
      nodes.push(circle);
    }
    this.plot.replaceChildren(...nodes);
    this.plot.dataset.dots = String(model.dots.length);
  }

  renderTable() {
    this.empty.hidden = this.checks.length > 0;
    this.rows.replaceChildren(
      ...this.checks.map((check) => {
        const outcome = outcomeOf(check);
        const result = element('td', { className: `result result-${outcome}${outcome === 'failed' ? ' state-failed' : ''}`, textContent: OUTCOME_TEXT[outcome] });
        if (check.error) result.title = check.error;
        const row = element('tr', {}, [
          element('td', { textContent: formatTime(check.created) }),
          element('td', { className: 'num', textContent: mm(check.radius_mm, 2) }),
          element('td', { className: 'num', textContent: mm(check.measured_radius_mm, 4) }),
          element('td', { className: 'num', textContent: signedMm(radiusError(check)) }),
          element('td', { className: 'num', textContent: mm(check.probing_error_form_mm) }),
          element('td', { className: 'num', textContent: signedMm(check.probing_error_size_mm) }),
          result,
        ]);
        row.dataset.check = check.id;
        return row;
      }),
    );
  }
}
