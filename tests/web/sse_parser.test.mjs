// SPDX-License-Identifier: Apache-2.0
// Unit test of the page's text/event-stream parser (web/src/events.js):
// the daemon's events must come out whole however the stream is chunked.
//   CYLSCAN_WEB_SRC=web/src node --test tests/web/sse_parser.test.mjs
import assert from 'node:assert/strict';
import { join } from 'node:path';
import { test } from 'node:test';
import { pathToFileURL } from 'node:url';

const src = process.env.CYLSCAN_WEB_SRC;
assert.ok(src, 'CYLSCAN_WEB_SRC must name web/src');
const { SseParser } = await import(pathToFileURL(join(src, 'events.js')).href);

const STREAM =
  ': keepalive\n\n' +
  'id: 1\nevent: state\ndata: {"state":"idle","scan":null}\n\n' +
  'id: 2\r\nevent: progress\r\ndata: {"id":"a","frames_done":3,"frames_total":50}\r\n\r\n' +
  'event: scan\rdata:{"id":"a",\rdata: "state":"done"}\r\r' +
  'event: ignored-without-data\n\n' +
  'data: plain\n\n';

const EXPECTED = [
  { type: 'state', data: '{"state":"idle","scan":null}', id: '1' },
  { type: 'progress', data: '{"id":"a","frames_done":3,"frames_total":50}', id: '2' },
  { type: 'scan', data: '{"id":"a",\n"state":"done"}', id: '2' },
  { type: 'message', data: 'plain', id: '2' },
];

function feed(chunks) {
  const parser = new SseParser();
  return chunks.flatMap((chunk) => parser.push(chunk));
}

test('a whole stream gives every event with data, in order', () => {
  assert.deepEqual(feed([STREAM]), EXPECTED);
});

test('any split into two chunks gives the same events', () => {
  for (let at = 0; at <= STREAM.length; at++) {
    assert.deepEqual(feed([STREAM.slice(0, at), STREAM.slice(at)]), EXPECTED, `split at ${at}`);
  }
});

test('one character at a time gives the same events', () => {
  assert.deepEqual(feed([...STREAM]), EXPECTED);
});

test('an event is not dispatched before its blank line', () => {
  const parser = new SseParser();
  assert.deepEqual(parser.push('event: state\ndata: {}\n'), []);
  assert.deepEqual(parser.push('\n'), [{ type: 'state', data: '{}', id: '' }]);
});
