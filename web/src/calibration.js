// SPDX-License-Identifier: Apache-2.0
// The calibration section of the set-up view (docs/http-api.md, "Calibration
// session"): one person with a checkerboard and a plate is taken through a
// session: start it, take checkerboard pairs while the guidance says what the
// views still lack, take plane poses, solve (with its progress from the event
// stream), read the result, install it, and roll back to the calibration an
// install replaced. On the virtual head the session lists the shipped target
// poses: the page offers the next one not yet taken, so that it alone can
// step through them. What is shown is computed in calibration_model.js.
//
// A capture stops the live views (the daemon ends their streams): the page
// closes them itself before it asks for one (setup.js holdLive), so that no
// stream is refused mid-way, and they come back once the head is idle.

import { getJson, isStatus, postJson, request } from './api.js';
import {
  describeCalibration,
  formatMm,
  formatPercent,
  guidanceRows,
  guidanceVerdict,
  mergeSession,
  nextTarget,
  replaceWarning,
  resultCameraRows,
  resultPoseRows,
  resultSummary,
  sessionCounts,
  takenScenes,
  targetLabel,
} from './calibration_model.js';
import { element } from './dom.js';

// While a plane pose is scanned its end comes as a `calibration` event; the
// session is also read this often, in case the event stream is down.
const PLANE_POLL_MS = 3000;

const capitalized = (text) => text.charAt(0).toUpperCase() + text.slice(1);

async function post(path) {
  return (await request(path, { method: 'POST' })).json();
}

// The kinds of capture: the request, the session's list of target poses, the words.
const KINDS = {
  board: { path: 'calibration/session/boards', targets: 'boards', doing: 'taking a board pair' },
  plane: { path: 'calibration/session/planes', targets: 'planes', doing: 'scanning a plane pose' },
};

export class CalibrationView {
  // root: the #calibration section of index.html; holdLive(kind) and
  // releaseLive() pause and resume the live views around a capture;
  // onInstalled() after the installed calibration changed.
  constructor(root, { holdLive = () => {}, releaseLive = () => {}, onInstalled = () => {} } = {}) {
    this.root = root;
    this.holdLive = holdLive;
    this.releaseLive = releaseLive;
    this.onInstalled = onInstalled;
    const $ = (id) => root.querySelector(`#${id}`);
    this.nodes = {
      installed: $('cal-installed'),
      rollback: $('cal-rollback'),
      rollbackMessage: $('cal-rollback-message'),
      start: $('cal-start'),
      sessionLine: $('cal-session'),
      message: $('cal-message'),
      body: $('cal-body'),
      boardCount: $('cal-board-count'),
      boardTargetLabel: $('cal-board-target-label'),
      boardTarget: $('cal-board-target'),
      boardButton: $('cal-board-button'),
      boardMessage: $('cal-board-message'),
      boards: $('cal-boards'),
      guidance: $('cal-guidance'),
      enough: $('cal-enough'),
      guidanceRows: $('cal-guidance-rows'),
      advice: $('cal-advice'),
      planeCount: $('cal-plane-count'),
      planeTargetLabel: $('cal-plane-target-label'),
      planeTarget: $('cal-plane-target'),
      planeButton: $('cal-plane-button'),
      planeMessage: $('cal-plane-message'),
      planes: $('cal-planes'),
      solve: $('cal-solve'),
      solveProgress: $('cal-solve-progress'),
      solveMessage: $('cal-solve-message'),
      solveNotice: $('cal-solve-notice'),
      failed: $('cal-failed'),
      result: $('cal-result'),
      resultCameras: $('cal-result-cameras'),
      resultPoses: $('cal-result-poses'),
      install: $('cal-install'),
      installMessage: $('cal-install-message'),
    };
    this.session = null;
    this.loaded = false;
    this.loading = null;
    this.reload = false;
    this.headBusy = false;
    this.capturing = null; // 'board' | 'plane': a capture this page asked for, not yet over
    this.planeIndex = null; // the plane pose this page is waiting for
    this.planePoll = null;
    this.captureLabel = '';
    this.busy = { start: false, solve: false, install: false, rollback: false };
    this.choice = { board: null, plane: null }; // the target pose chosen; null: the next one
    this.installed = null; // the status' calibration {main, aux}

    const n = this.nodes;
    n.start.addEventListener('click', () => this.start());
    n.boardButton.addEventListener('click', () => this.capture('board'));
    n.planeButton.addEventListener('click', () => this.capture('plane'));
    n.boardTarget.addEventListener('change', () => (this.choice.board = n.boardTarget.value));
    n.planeTarget.addEventListener('change', () => (this.choice.plane = n.planeTarget.value));
    n.solve.addEventListener('click', () => this.solve());
    n.install.addEventListener('click', () => this.install());
    n.rollback.addEventListener('click', () => this.rollback());
    this.render();
  }

  say(node, text, kind = '') {
    node.textContent = text;
    node.className = `message ${kind}`;
    if (node === this.nodes.message) node.hidden = !text;
  }

  show() {
    if (!this.loaded) this.refresh();
  }

  // Reads the session again; a refresh asked for while one is in flight runs after it.
  async refresh() {
    if (this.loading) {
      this.reload = true;
      return this.loading;
    }
    this.loading = (async () => {
      try {
        do {
          this.reload = false;
          let session = null;
          try {
            session = await getJson('calibration/session');
          } catch (error) {
            if (!isStatus(error, 404)) throw error;
          }
          this.setSession(session, { replace: true });
          this.loaded = true;
          this.root.dataset.loaded = 'true';
        } while (this.reload);
        if (this.nodes.message.dataset.from === 'load') this.say(this.nodes.message, '');
      } catch (error) {
        this.nodes.message.dataset.from = 'load';
        if (isStatus(error, 401)) this.say(this.nodes.message, 'A token is needed to calibrate.', 'muted');
        else this.say(this.nodes.message, `Calibration session: ${error.message}`, 'error');
      } finally {
        this.loading = null;
      }
    })();
    return this.loading;
  }

  // A session from the daemon (null: there is none). An event's session
  // lacks the targets, which stay those known; `replace` takes it whole.
  setSession(session, { replace = false } = {}) {
    const previous = this.session;
    if (!session) this.session = null;
    else this.session = replace ? session : mergeSession(previous, session);
    if (!this.session || (previous && previous.created !== this.session.created)) {
      this.choice = { board: null, plane: null };
    }
    this.checkPlane();
    this.render();
  }

  // A `calibration` event: the whole session after a change.
  onSession(session) {
    if (!session || typeof session !== 'object') return;
    // The first event of a session this page has not read yet: its targets come with a GET.
    const fresh = !this.session || this.session.created !== session.created;
    this.setSession(session);
    if (fresh && !session.targets) this.refresh();
  }

  // A `calibration_progress` event during a solve.
  onSolveProgress(event) {
    if (!this.session || typeof event?.progress !== 'number') return;
    if (this.session.state !== 'solving') return;
    this.session = { ...this.session, progress: event.progress };
    this.renderSolve();
  }

  // A `progress` event while the head captures for the session.
  onCaptureProgress(event) {
    const kind = this.capturing;
    if (!kind) return;
    const node = kind === 'board' ? this.nodes.boardMessage : this.nodes.planeMessage;
    const percent = Math.round((event.progress ?? 0) * 100);
    this.say(node, `${capitalized(KINDS[kind].doing)}${this.captureLabel}… ${percent} %`, 'muted');
  }

  // The head's state ('idle', 'scanning', 'error'): no capture while it is busy.
  setHeadState(state) {
    const busy = state === 'scanning';
    if (busy === this.headBusy) return;
    this.headBusy = busy;
    this.renderButtons();
  }

  // The status' calibration: {main: bool, aux: bool}.
  setInstalled(calibration) {
    if (!calibration || typeof calibration !== 'object') return;
    this.installed = calibration;
    this.renderInstalled();
  }

  // --------------------------------------------------------------- actions

  async start() {
    const warning = replaceWarning(this.session);
    if (warning && !window.confirm(warning)) return;
    this.busy.start = true;
    this.renderButtons();
    delete this.nodes.message.dataset.from;
    this.say(this.nodes.message, 'Starting a session…', 'muted');
    for (const node of [this.nodes.boardMessage, this.nodes.planeMessage, this.nodes.solveMessage, this.nodes.installMessage]) {
      this.say(node, '');
    }
    try {
      const session = await postJson('calibration/session', {});
      this.setSession(session, { replace: !this.session });
      this.say(this.nodes.message, 'Session started: take the checkerboard pairs.', 'ok');
      // The answer lacks the virtual head's targets, which only the GET gives.
      if (!session.targets) await this.refresh();
    } catch (error) {
      if (isStatus(error, 401)) this.say(this.nodes.message, 'A token is needed to calibrate.', 'warn');
      else if (isStatus(error, 409)) this.say(this.nodes.message, `No new session now: ${error.message}`, 'warn');
      else this.say(this.nodes.message, `No new session: ${error.message}`, 'error');
    } finally {
      this.busy.start = false;
      this.renderButtons();
    }
  }

  // The target pose to send for a capture: the selector's, on the virtual head.
  chosenScene(kind) {
    const targets = this.targets(kind);
    if (!targets) return '';
    return (kind === 'board' ? this.nodes.boardTarget : this.nodes.planeTarget).value;
  }

  targets(kind) {
    const list = this.session?.targets?.[KINDS[kind].targets];
    return Array.isArray(list) && list.length > 0 ? list : null;
  }

  taken(kind) {
    return kind === 'board' ? takenScenes(this.session?.boards) : takenScenes(this.session?.planes, { planes: true });
  }

  // After a capture of `scene`: the next target not yet taken.
  advance(kind, scene) {
    const targets = this.targets(kind);
    if (!targets || !scene) return;
    const taken = this.taken(kind);
    taken.add(scene);
    this.choice[kind] = nextTarget(targets, taken, scene) ?? '';
  }

  async capture(kind) {
    const node = kind === 'board' ? this.nodes.boardMessage : this.nodes.planeMessage;
    const scene = this.chosenScene(kind);
    const label = scene ? ` (${targetLabel(scene)})` : '';
    this.capturing = kind;
    this.captureLabel = label;
    this.holdLive(kind);
    // What the session's start said is done with.
    if (this.nodes.message.dataset.from !== 'load') this.say(this.nodes.message, '');
    this.renderButtons();
    this.say(node, `${capitalized(KINDS[kind].doing)}${label}…`, 'muted');
    let held = true;
    try {
      const answer = await postJson(KINDS[kind].path, scene ? { scene } : {});
      this.advance(kind, scene);
      if (kind === 'board') {
        this.noteBoard(answer, scene);
        const { main, aux } = answer.found ?? {};
        const missing = [main ? null : 'main', aux ? null : 'aux'].filter(Boolean);
        if (missing.length === 0) this.say(node, `Pair ${answer.index}${label}: board found in both cameras.`, 'ok');
        else {
          this.say(
            node,
            `Pair ${answer.index}${label}: no board found in ${missing.join(' and ')}, so it does not count; ` +
              'make sure both cameras see the whole board.',
            'warn',
          );
        }
      } else {
        // The pose is scanned now; its end comes with the session.
        this.planeIndex = answer.index;
        this.say(node, `Pose ${answer.index}${label}: scanning…`, 'muted');
        held = false; // released once the pose is over (checkPlane)
        this.pollPlane();
        this.checkPlane();
      }
    } catch (error) {
      if (isStatus(error, 401)) this.say(node, 'A token is needed to calibrate.', 'warn');
      else if (isStatus(error, 409)) this.say(node, `Not now: ${error.message}`, 'warn');
      else if (isStatus(error, 404)) {
        this.say(node, `No session: ${error.message}`, 'warn');
        this.refresh();
      } else this.say(node, `The capture failed: ${error.message}`, 'error');
      this.planeIndex = null;
    } finally {
      if (held) {
        this.capturing = null;
        this.releaseLive();
      }
      this.render();
    }
  }

  // A pair the answer names that no event has brought yet.
  noteBoard({ index, found }, scene) {
    if (!this.session || !Number.isInteger(index)) return;
    const boards = Array.isArray(this.session.boards) ? this.session.boards : [];
    if (boards.some((b) => b.index === index)) return;
    const board = { index, found: found ?? { main: false, aux: false } };
    if (scene) board.scene = scene;
    this.session = { ...this.session, boards: [...boards, board] };
  }

  // Reads the session now and then while a plane pose is scanned.
  pollPlane() {
    clearTimeout(this.planePoll);
    this.planePoll = setTimeout(async () => {
      if (this.planeIndex === null) return;
      await this.refresh();
      if (this.planeIndex !== null) this.pollPlane();
    }, PLANE_POLL_MS);
  }

  // The plane pose this page waits for, once the session says it is over.
  checkPlane() {
    if (this.planeIndex === null || !this.session) return;
    const plane = (this.session.planes ?? []).find((p) => p.index === this.planeIndex);
    if (!plane || plane.state === 'capturing') return;
    const label = plane.scene ? ` (${targetLabel(plane.scene)})` : '';
    if (plane.state === 'done') this.say(this.nodes.planeMessage, `Pose ${plane.index}${label}: scanned.`, 'ok');
    else this.say(this.nodes.planeMessage, `Pose ${plane.index}${label} failed: ${plane.error ?? 'no reason given'}`, 'error');
    this.planeIndex = null;
    clearTimeout(this.planePoll);
    if (this.capturing === 'plane') {
      this.capturing = null;
      this.releaseLive();
    }
  }

  async solve() {
    const n = this.nodes;
    this.busy.solve = true;
    this.renderButtons();
    this.say(n.solveMessage, 'Starting the solve…', 'muted');
    try {
      await post('calibration/session/solve');
      if (this.session && this.session.state !== 'solving' && this.session.state !== 'solved') {
        this.session = { ...this.session, state: 'solving', progress: 0 };
      }
      this.say(n.solveMessage, '');
    } catch (error) {
      // Too few pairs or poses, a capture running: the daemon says which.
      if (isStatus(error, 401)) this.say(n.solveMessage, 'A token is needed to calibrate.', 'warn');
      else if (isStatus(error, 409)) this.say(n.solveMessage, `Not solved: ${error.message}`, 'warn');
      else this.say(n.solveMessage, `Not solved: ${error.message}`, 'error');
    } finally {
      this.busy.solve = false;
      this.render();
    }
  }

  async install() {
    const n = this.nodes;
    this.busy.install = true;
    this.renderButtons();
    this.say(n.installMessage, 'Installing…', 'muted');
    try {
      const info = await post('calibration/session/install');
      this.say(n.installMessage, `Installed ${describeCalibration(info)} for camera main; the one it replaced is kept for a roll back.`, 'ok');
      this.say(n.rollbackMessage, '');
      this.onInstalled();
    } catch (error) {
      if (isStatus(error, 401)) this.say(n.installMessage, 'A token is needed to install a calibration.', 'warn');
      else if (isStatus(error, 409)) this.say(n.installMessage, `Not installed: ${error.message}`, 'warn');
      else this.say(n.installMessage, `Not installed: ${error.message}`, 'error');
    } finally {
      this.busy.install = false;
      this.renderButtons();
    }
  }

  async rollback() {
    const n = this.nodes;
    this.busy.rollback = true;
    this.renderButtons();
    this.say(n.rollbackMessage, 'Rolling back…', 'muted');
    try {
      const info = await post('calibration/rollback');
      this.say(n.rollbackMessage, `Rolled back: camera main has ${describeCalibration(info)} again.`, 'ok');
      this.say(n.installMessage, '');
      this.onInstalled();
    } catch (error) {
      // Nothing kept to go back to is an answer, not a failure.
      if (isStatus(error, 404)) this.say(n.rollbackMessage, `Nothing to roll back to: ${error.message}.`, 'muted');
      else if (isStatus(error, 401)) this.say(n.rollbackMessage, 'A token is needed to roll back.', 'warn');
      else this.say(n.rollbackMessage, `Not rolled back: ${error.message}`, 'error');
    } finally {
      this.busy.rollback = false;
      this.renderButtons();
    }
  }

  // ---------------------------------------------------------------- render

  render() {
    const n = this.nodes;
    const s = this.session;
    this.root.dataset.state = s ? s.state : 'none';
    n.body.hidden = !s;
    n.start.textContent = s ? 'Start a new session' : 'Start session';
    n.start.title = s ? 'Throws the current session away' : '';
    if (!s) n.sessionLine.textContent = this.loaded ? 'No session: start one to calibrate the head.' : '–';
    else {
      const created = new Date(s.created);
      const when = Number.isNaN(created.getTime()) ? s.created : created.toLocaleString();
      n.sessionLine.textContent = `Session started ${when}: ${s.state}. A new session replaces it.`;
    }
    if (s) {
      this.renderBoards();
      this.renderGuidance();
      this.renderPlanes();
      this.renderSolve();
    }
    this.renderInstalled();
    this.renderButtons();
  }

  renderTargets(kind) {
    const select = kind === 'board' ? this.nodes.boardTarget : this.nodes.planeTarget;
    const label = kind === 'board' ? this.nodes.boardTargetLabel : this.nodes.planeTargetLabel;
    const targets = this.targets(kind);
    label.hidden = !targets;
    if (!targets) {
      select.replaceChildren();
      return;
    }
    const taken = this.taken(kind);
    if (this.choice[kind] === null) this.choice[kind] = nextTarget(targets, taken) ?? '';
    const options = targets.map((scene) => {
      const option = element('option', { value: scene, textContent: `${targetLabel(scene)}${taken.has(scene) ? ' (taken)' : ''}` });
      option.dataset.taken = String(taken.has(scene));
      return option;
    });
    const remaining = targets.filter((scene) => !taken.has(scene)).length;
    const none = remaining === 0 ? 'the scene as it is (every target pose taken)' : 'the scene as it is (no target)';
    options.push(element('option', { value: '', textContent: none }));
    select.replaceChildren(...options);
    select.value = this.choice[kind];
    select.dataset.remaining = String(remaining);
  }

  renderBoards() {
    const n = this.nodes;
    const s = this.session;
    const counts = sessionCounts(s);
    n.boardCount.textContent = `— ${counts.kept} of ${counts.boards} found in both cameras`;
    this.root.dataset.boards = String(counts.boards);
    this.root.dataset.kept = String(counts.kept);
    this.renderTargets('board');
    const mark = (found) => (found ? '✓' : '✗');
    n.boards.replaceChildren(
      ...(s.boards ?? []).map((board) => {
        const main = Boolean(board.found?.main);
        const aux = Boolean(board.found?.aux);
        const item = element('li', { className: `cal-board ${main && aux ? 'kept' : 'missed'}` }, [
          element('span', { className: 'cal-board-index', textContent: `#${board.index}` }),
          ` main ${mark(main)} aux ${mark(aux)}`,
        ]);
        item.title = `${board.scene ? `${targetLabel(board.scene)}: ` : ''}` +
          `board ${main ? 'found' : 'not found'} in main, ${aux ? 'found' : 'not found'} in aux`;
        item.dataset.index = String(board.index);
        item.dataset.main = String(main);
        item.dataset.aux = String(aux);
        if (board.scene) item.dataset.scene = board.scene;
        return item;
      }),
    );
  }

  renderGuidance() {
    const n = this.nodes;
    const guidance = this.session.guidance;
    const verdict = guidanceVerdict(guidance);
    n.guidance.dataset.verdict = verdict;
    this.root.dataset.enough = verdict;
    if (verdict === 'enough') n.enough.textContent = 'Enough views: the guidance is satisfied. More views still help.';
    else if (verdict === 'not-enough') {
      n.enough.textContent = 'Not enough views yet: the calibration may be poor. You can go on all the same.';
    } else n.enough.textContent = 'The head gives no guidance.';
    n.enough.className = `cal-enough ${verdict}`;
    n.advice.textContent = guidance?.advice ? `Advice: ${guidance.advice}` : '';
    n.guidanceRows.replaceChildren(
      ...guidanceRows(guidance).map(({ camera, ready, cells }) => {
        const row = element('tr', {}, [element('th', { scope: 'row', textContent: camera })]);
        row.dataset.camera = camera;
        if (!ready) {
          row.append(element('td', { colSpan: 7, className: 'muted', textContent: 'no estimate yet (4 pairs found in both cameras are needed)' }));
          return row;
        }
        for (const key of ['fx', 'fy', 'cx', 'cy', 'rms', 'coverage', 'tilt']) {
          const cell = element('td', { className: 'num', textContent: cells[key] });
          cell.dataset.key = key;
          row.append(cell);
        }
        return row;
      }),
    );
  }

  renderPlanes() {
    const n = this.nodes;
    const s = this.session;
    const counts = sessionCounts(s);
    n.planeCount.textContent = `— ${counts.planesDone} of ${counts.planes} done`;
    this.root.dataset.planesDone = String(counts.planesDone);
    this.renderTargets('plane');
    const STATE_TEXT = { capturing: 'scanning…', done: 'done', failed: 'failed' };
    n.planes.replaceChildren(
      ...(s.planes ?? []).map((plane) => {
        const stateClass = plane.state === 'failed' ? 'state-failed' : plane.state === 'capturing' ? 'state-running' : 'state-done';
        const state = element('td', { className: stateClass, textContent: STATE_TEXT[plane.state] ?? plane.state });
        if (plane.error) state.title = plane.error;
        const row = element('tr', {}, [
          element('td', { textContent: `#${plane.index}` }),
          element('td', { textContent: targetLabel(plane.scene) || '–' }),
          state,
          element('td', { className: 'num', textContent: formatPercent(plane.valid_fraction) }),
          element('td', { className: 'num', textContent: formatMm(plane.rmse_mm) }),
        ]);
        row.dataset.index = String(plane.index);
        row.dataset.state = plane.state;
        return row;
      }),
    );
  }

  renderSolve() {
    const n = this.nodes;
    const s = this.session;
    const solving = s.state === 'solving';
    n.solveProgress.hidden = !solving;
    if (solving) {
      const progress = Math.min(1, Math.max(0, s.progress ?? 0));
      n.solveProgress.value = progress;
      this.say(n.solveMessage, `Solving… ${Math.round(progress * 100)} %`, 'muted');
    } else if (/^Solving/.test(n.solveMessage.textContent)) {
      this.say(n.solveMessage, s.state === 'solved' ? 'Solved.' : '');
    }
    const verdict = guidanceVerdict(s.guidance);
    n.solveNotice.hidden = verdict !== 'not-enough' || s.state === 'solved';
    n.solveNotice.textContent =
      'The guidance says the views are not enough yet: a solve now may give a poor calibration. ' +
      'Compare the result (RMS, σ, RMSE) before you install it.';
    n.failed.hidden = s.state !== 'failed';
    n.failed.textContent = s.state === 'failed' ? `The solve failed: ${s.error ?? 'no reason given'}` : '';
    const summary = resultSummary(s.state === 'solved' ? s.result : null);
    n.result.hidden = !summary;
    if (!summary) return;
    for (const node of n.result.querySelectorAll('[data-result]')) node.textContent = summary[node.dataset.result];
    n.resultCameras.replaceChildren(
      ...resultCameraRows(s.result).map((row) => {
        const tr = element('tr', {}, [element('th', { scope: 'row', textContent: row.camera })]);
        for (const key of ['fx', 'fy', 'cx', 'cy', 'rms']) tr.append(element('td', { className: 'num', textContent: row[key] }));
        tr.dataset.camera = row.camera;
        return tr;
      }),
    );
    n.resultPoses.replaceChildren(
      ...resultPoseRows(s.result, s.planes).map((row) => {
        const tr = element('tr', {}, [
          element('td', { textContent: `#${row.index}` }),
          element('td', { textContent: row.scene || '–' }),
          ...['rmse', 'planeFit', 'mainValid', 'auxValid'].map((key) => element('td', { className: 'num', textContent: row[key] })),
        ]);
        tr.dataset.index = String(row.index);
        return tr;
      }),
    );
  }

  renderInstalled() {
    const n = this.nodes;
    const c = this.installed;
    if (!c) {
      n.installed.textContent = '–';
      return;
    }
    const names = Object.keys(c).sort((a, b) => (a === 'main' ? -1 : b === 'main' ? 1 : a.localeCompare(b)));
    n.installed.textContent = names.map((name) => `${name} ${c[name] ? '✓' : '✗'}`).join(', ');
    n.installed.title = names.map((name) => `${name}: ${c[name] ? 'calibrated' : 'not calibrated'}`).join('; ');
    n.installed.dataset.main = String(Boolean(c.main));
  }

  renderButtons() {
    const n = this.nodes;
    const s = this.session;
    const solving = s?.state === 'solving';
    const capturing = Boolean(this.capturing);
    n.start.disabled = this.busy.start || capturing || solving;
    const canCapture = s && !solving && !this.headBusy && !capturing && !this.busy.start;
    n.boardButton.disabled = !canCapture;
    n.planeButton.disabled = !canCapture;
    const why = !s ? '' : solving ? 'The session is solving' : this.headBusy || capturing ? 'The head is busy: wait until it is idle' : '';
    n.boardButton.title = why;
    n.planeButton.title = why;
    n.boardTarget.disabled = !canCapture;
    n.planeTarget.disabled = !canCapture;
    n.solve.disabled = !s || solving || this.headBusy || capturing || this.busy.solve;
    n.solve.textContent = s?.state === 'solved' || s?.state === 'failed' ? 'Solve again' : 'Solve';
    n.install.disabled = s?.state !== 'solved' || this.busy.install;
    n.install.title = s?.state === 'solved' ? '' : 'Solve the session first';
    n.rollback.disabled = this.busy.rollback;
  }
}
