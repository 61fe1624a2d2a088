// SPDX-License-Identifier: Apache-2.0
// A camera's live view (GET /api/v1/cameras/{name}/stream.mjpg,
// docs/http-api.md): read with fetch() so that the bearer token is sent (an
// <img> cannot send it), split into its JPEG parts by MultipartParser, and
// each part drawn into a canvas; the part headers carry the focus measure and
// the saturated fraction of that frame.
//
// The daemon ends the stream when a scan or a calibration capture starts and
// refuses it (409) while one runs: the view then waits, paused, until the
// head is idle again (state events, setScanning()), rather than knocking. A
// page that starts a capture itself closes the stream first (setScanning(true,
// {close: true})), so that the stream is not cut or refused mid-way. A stream
// that ends or fails while the head is idle is opened again after a growing,
// jittered wait.

import { isStatus, request } from './api.js';
import { MultipartParser, boundaryOf } from './multipart.js';

const MIN_DELAY_MS = 1000;
const MAX_DELAY_MS = 30000;
// A stream that stayed up this long was healthy: the next failure backs off afresh.
const HEALTHY_MS = 10000;
// The daemon sends 5 parts or more a second: this long without a byte is a stalled stream.
const STALL_MS = 15000;
// After the closing boundary the daemon closes the connection; a server that
// does not is left after this long.
const DRAIN_MS = 2000;
// Frames in a row that do not decode before the view says so.
const BAD_FRAMES_SHOWN = 3;

// A header value as a number, NaN when missing or empty.
function headerNumber(headers, name) {
  const value = headers[name];
  return value === undefined || value.trim() === '' ? NaN : Number(value);
}

export class LiveView {
  // camera: its name; canvas: where frames are drawn;
  // onStatus(state, detail): state is 'connecting', 'live', 'paused' (a scan
  //   runs), 'retry' ({wait, reason, error}), 'unauthorized', 'bad-frames' or 'stopped';
  // onFrame({focus, saturated, width, height, frames}) after each frame drawn.
  constructor({ camera, canvas, onStatus = () => {}, onFrame = () => {} }) {
    this.camera = camera;
    this.canvas = canvas;
    this.context = canvas.getContext('2d');
    this.onStatus = onStatus;
    this.onFrame = onFrame;
    this.overlay = false;
    this.active = false;
    this.running = false;
    this.scanning = false;
    this.abort = null;
    this.restarting = false;
    this.wakers = new Set();
    this.latest = null; // the newest part not yet drawn: frames the page cannot keep up with are dropped
    this.drawing = false;
    this.frames = 0;
    this.badFrames = 0;
    this.state = 'stopped';
    this.delay = MIN_DELAY_MS;
  }

  start() {
    this.active = true;
    this.wake();
    if (!this.running) this.run();
  }

  // Closes the stream (the view is no longer shown).
  stop() {
    this.active = false;
    if (this.abort) this.abort.abort();
    this.wake();
  }

  // The saturation overlay on or off: the stream is opened again with it.
  setOverlay(on) {
    if (this.overlay === on) return;
    this.overlay = on;
    this.restart();
  }

  // The head's state from the event stream: no stream while it scans.
  // `close`: the page is about to start a capture, so the open stream is
  // closed now; otherwise it is left for the daemon to end (it does when the
  // scan starts).
  setScanning(scanning, { close = false } = {}) {
    if (this.scanning && !scanning) this.delay = MIN_DELAY_MS; // the end of a scan is no failure
    this.scanning = scanning;
    if (scanning && close && this.abort) this.abort.abort();
    if (scanning && this.active) this.status('paused');
    this.wake();
  }

  // Skips the current wait (e.g. once the user has given a token).
  retryNow() {
    this.delay = MIN_DELAY_MS;
    this.wake();
  }

  // Closes the open stream, if any, and opens it again at once.
  restart() {
    if (this.abort) {
      this.restarting = true;
      this.abort.abort();
    }
    this.wake();
  }

  status(state, detail = {}) {
    this.state = state;
    this.onStatus(state, detail);
  }

  // Waits `ms` (forever when not finite), or until wake().
  wait(ms) {
    return new Promise((resolve) => {
      let timer = null;
      const done = () => {
        clearTimeout(timer);
        this.wakers.delete(done);
        resolve();
      };
      if (Number.isFinite(ms)) timer = setTimeout(done, ms);
      this.wakers.add(done);
    });
  }

  wake() {
    for (const done of [...this.wakers]) done();
  }

  async run() {
    this.running = true;
    try {
      while (this.active) {
        if (this.scanning) {
          this.status('paused');
          await this.wait(Infinity);
          continue;
        }
        const opened = Date.now();
        let outcome;
        try {
          outcome = await this.readOnce();
        } catch (error) {
          outcome = error;
        }
        if (!this.active) break;
        if (this.restarting) {
          this.restarting = false;
          this.delay = MIN_DELAY_MS;
          continue;
        }
        if (Date.now() - opened > HEALTHY_MS) this.delay = MIN_DELAY_MS;
        if (isStatus(outcome, 401)) {
          this.status('unauthorized');
          await this.wait(Infinity);
          continue;
        }
        if (this.scanning) continue;
        const wait = this.delay * (0.75 + Math.random() * 0.5);
        this.delay = Math.min(this.delay * 2, MAX_DELAY_MS);
        if (isStatus(outcome, 409)) {
          // A scan runs that the event stream has not told of yet (or it is
          // down): paused, and asked again after the wait unless an idle
          // state event comes first.
          this.status('paused', { wait });
        } else {
          const ended = outcome === 'ended' || outcome === 'closed';
          this.status('retry', {
            wait,
            reason: ended ? 'the stream ended' : outcome.message || String(outcome),
            error: !ended,
          });
        }
        await this.wait(wait);
      }
    } finally {
      this.running = false;
      if (!this.active) this.status('stopped');
    }
  }

  // One stream from request to end: 'ended' (the connection closed),
  // 'closed' (the closing boundary); throws on a refusal or a failure.
  async readOnce() {
    const abort = new AbortController();
    this.abort = abort;
    try {
      return await this.readStream(abort);
    } finally {
      if (this.abort === abort) this.abort = null;
    }
  }

  async readStream(abort) {
    this.status('connecting');
    const query = this.overlay ? '?overlay=saturation' : '';
    const response = await request(`cameras/${encodeURIComponent(this.camera)}/stream.mjpg${query}`, {
      signal: abort.signal,
      cache: 'no-store',
      headers: { Accept: 'multipart/x-mixed-replace, image/jpeg' },
    });
    const type = response.headers.get('Content-Type');
    const boundary = boundaryOf(type);
    if (!boundary || !response.body) {
      abort.abort();
      throw new Error(`the live view is not a multipart stream (${type})`);
    }
    const parser = new MultipartParser(boundary);
    const reader = response.body.getReader();
    let stalled = false;
    let stall = null;
    const watch = () => {
      clearTimeout(stall);
      stall = setTimeout(() => {
        stalled = true;
        abort.abort();
      }, STALL_MS);
    };
    this.badFrames = 0;
    let shownLive = false;
    try {
      watch();
      for (;;) {
        const { value, done } = await reader.read();
        if (done) return 'ended';
        watch();
        for (const part of parser.push(value)) {
          this.show(part);
          if (!shownLive) {
            shownLive = true;
            this.status('live');
          }
        }
        if (parser.closed) break;
      }
      // Read on to the end of the connection, which follows the closing boundary.
      let timer = null;
      const drained = new Promise((resolve) => {
        timer = setTimeout(() => resolve('late'), DRAIN_MS);
      });
      for (;;) {
        const next = await Promise.race([reader.read(), drained]);
        if (next === 'late') {
          abort.abort();
          break;
        }
        if (next.done) break;
      }
      clearTimeout(timer);
      return 'closed';
    } catch (error) {
      if (stalled) throw new Error(`no frame for ${STALL_MS / 1000} s`);
      throw error;
    } finally {
      clearTimeout(stall);
    }
  }

  show(part) {
    this.latest = {
      body: part.body,
      focus: headerNumber(part.headers, 'x-cylscan-focus'),
      saturated: headerNumber(part.headers, 'x-cylscan-saturated'),
    };
    if (!this.drawing) this.drawLatest();
  }

  async drawLatest() {
    this.drawing = true;
    try {
      while (this.latest) {
        const { body, focus, saturated } = this.latest;
        this.latest = null;
        let bitmap;
        try {
          bitmap = await createImageBitmap(new Blob([body], { type: 'image/jpeg' }));
        } catch {
          this.badFrames++;
          if (this.badFrames === BAD_FRAMES_SHOWN) this.status('bad-frames');
          continue;
        }
        if (this.canvas.width !== bitmap.width) this.canvas.width = bitmap.width;
        if (this.canvas.height !== bitmap.height) this.canvas.height = bitmap.height;
        this.context.drawImage(bitmap, 0, 0);
        bitmap.close();
        if (this.badFrames >= BAD_FRAMES_SHOWN && this.state === 'bad-frames') this.status('live');
        this.badFrames = 0;
        this.frames++;
        this.onFrame({ focus, saturated, width: this.canvas.width, height: this.canvas.height, frames: this.frames });
      }
    } finally {
      this.drawing = false;
    }
  }
}
