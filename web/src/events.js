// SPDX-License-Identifier: Apache-2.0
// The daemon's live events (GET /api/v1/events) read with fetch() and a
// stream parser rather than EventSource, so that the Authorization header
// can be sent. Reconnects with exponential backoff and Last-Event-ID.

import { apiUrl, authHeaders } from './api.js';

// Incremental text/event-stream parser (the WHATWG rules: `field: value`
// lines, `:` comments, a blank line dispatches, data lines joined by \n).
export class SseParser {
  constructor() {
    this.buffer = '';
    this.reset();
    this.lastId = '';
  }

  reset() {
    this.type = '';
    this.data = [];
  }

  // Feeds a chunk of text; returns the events it completes: {type, data, id}.
  push(chunk) {
    this.buffer += chunk;
    const events = [];
    for (;;) {
      const match = /\r\n|\r|\n/.exec(this.buffer);
      if (!match) break;
      // A lone \r at the very end may be the first half of \r\n: wait.
      if (match[0] === '\r' && match.index === this.buffer.length - 1) break;
      const line = this.buffer.slice(0, match.index);
      this.buffer = this.buffer.slice(match.index + match[0].length);
      const event = this.line(line);
      if (event) events.push(event);
    }
    return events;
  }

  line(line) {
    if (line === '') {
      if (this.data.length === 0) {
        this.reset();
        return null;
      }
      const event = { type: this.type || 'message', data: this.data.join('\n'), id: this.lastId };
      this.reset();
      return event;
    }
    if (line.startsWith(':')) return null;
    const colon = line.indexOf(':');
    const field = colon < 0 ? line : line.slice(0, colon);
    let value = colon < 0 ? '' : line.slice(colon + 1);
    if (value.startsWith(' ')) value = value.slice(1);
    if (field === 'event') this.type = value;
    else if (field === 'data') this.data.push(value);
    else if (field === 'id' && !value.includes('\0')) this.lastId = value;
    return null;
  }
}

const MIN_DELAY_MS = 1000;
const MAX_DELAY_MS = 30000;

// Waits `ms`, or less when one of `signals` aborts.
const sleep = (ms, signals) =>
  new Promise((resolve) => {
    const timer = setTimeout(resolve, ms);
    for (const signal of signals) {
      signal.addEventListener('abort', () => {
        clearTimeout(timer);
        resolve();
      });
    }
  });

// Calls onEvent(type, data) for each event (data parsed as JSON) and
// onConnection('open' | 'retry' | 'unauthorized', detail) as the link changes.
// Returns {close(), retryNow()}: retryNow() skips the current backoff wait
// (e.g. once the user has given a token).
export function connectEvents({ onEvent, onConnection }) {
  const stop = new AbortController();
  let wake = new AbortController();
  let lastId = '';

  async function readOnce() {
    const headers = authHeaders({ Accept: 'text/event-stream' });
    if (lastId) headers['Last-Event-ID'] = lastId;
    const response = await fetch(apiUrl('events'), { headers, signal: stop.signal, cache: 'no-store' });
    if (response.status === 401) return 'unauthorized';
    if (!response.ok || !response.body) throw new Error(`events: ${response.status} ${response.statusText}`);
    onConnection('open');
    const parser = new SseParser();
    const reader = response.body.pipeThrough(new TextDecoderStream()).getReader();
    for (;;) {
      const { value, done } = await reader.read();
      if (done) return 'closed';
      for (const event of parser.push(value)) {
        if (event.id) lastId = event.id;
        let data;
        try {
          data = JSON.parse(event.data);
        } catch {
          console.warn(`events: "${event.type}" data is not JSON`, event.data);
          continue;
        }
        onEvent(event.type, data);
      }
    }
  }

  (async () => {
    let delay = MIN_DELAY_MS;
    while (!stop.signal.aborted) {
      const opened = Date.now();
      let outcome;
      try {
        outcome = await readOnce();
      } catch (error) {
        if (stop.signal.aborted) return;
        outcome = error.message || 'failed';
      }
      // A stream that stayed up for a while was healthy: start backing off afresh.
      if (Date.now() - opened > MAX_DELAY_MS) delay = MIN_DELAY_MS;
      const wait = delay * (0.75 + Math.random() * 0.5);
      onConnection(outcome === 'unauthorized' ? 'unauthorized' : 'retry', { outcome, wait });
      wake = new AbortController();
      await sleep(wait, [stop.signal, wake.signal]);
      delay = Math.min(delay * 2, MAX_DELAY_MS);
    }
  })();

  return { close: () => stop.abort(), retryNow: () => wake.abort() };
}
