// SPDX-License-Identifier: Apache-2.0
// Unit test of the page's multipart/x-mixed-replace parser (web/src/multipart.js),
// which splits a camera's live view (stream.mjpg, docs/http-api.md) into its
// JPEG parts: every part must come out whole, with its headers, however the
// stream is chunked, and the closing boundary must end it.
//   CYLSCAN_WEB_SRC=web/src node --test tests/web/multipart_parser.test.mjs
import assert from 'node:assert/strict';
import { join } from 'node:path';
import { test } from 'node:test';
import { pathToFileURL } from 'node:url';

const src = process.env.CYLSCAN_WEB_SRC;
assert.ok(src, 'CYLSCAN_WEB_SRC must name web/src');
const { MultipartParser, MultipartError, boundaryOf } = await import(pathToFileURL(join(src, 'multipart.js')).href);

const BOUNDARY = 'cylscanframe';
const ascii = (text) => new TextEncoder().encode(text);
const join8 = (...arrays) => {
  const out = new Uint8Array(arrays.reduce((n, a) => n + a.length, 0));
  let at = 0;
  for (const a of arrays) {
    out.set(a, at);
    at += a.length;
  }
  return out;
};

// A JPEG-like body holding what a naive parser would trip on: CR, LF, the
// boundary itself after a CRLF, and the closing delimiter.
function body(seed, size) {
  const bytes = new Uint8Array(size);
  for (let i = 0; i < size; i++) bytes[i] = (seed * 31 + i * 7) & 0xff;
  const trap = ascii(`\r\n--${BOUNDARY}\r\n\r\n--${BOUNDARY}--\r\n`);
  if (size >= trap.length + 4) {
    bytes.set([0xff, 0xd8], 0);
    bytes.set(trap, Math.floor(size / 3));
    bytes.set([0xff, 0xd9], size - 2);
  }
  return bytes;
}

// A part as the daemon writes it.
function part(jpeg, focus, saturated) {
  return join8(
    ascii(
      `--${BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: ${jpeg.length}\r\n` +
        `X-Cylscan-Focus: ${focus}\r\nX-Cylscan-Saturated: ${saturated}\r\n\r\n`,
    ),
    jpeg,
    ascii('\r\n'),
  );
}

const JPEGS = [body(1, 300), body(2, 1), body(3, 0), body(4, 517)];
const MEASURES = [
  ['412.5', '0'],
  ['1e3', '0.0125'],
  ['0', '1'],
  ['98.25', '0.001'],
];
const STREAM = join8(...JPEGS.map((jpeg, i) => part(jpeg, ...MEASURES[i])), ascii(`--${BOUNDARY}--\r\n`));

function expectParts(parts) {
  assert.equal(parts.length, JPEGS.length, 'number of parts');
  parts.forEach((p, i) => {
    assert.deepEqual(p.body, JPEGS[i], `body of part ${i}`);
    assert.deepEqual(
      p.headers,
      {
        'content-type': 'image/jpeg',
        'content-length': String(JPEGS[i].length),
        'x-cylscan-focus': MEASURES[i][0],
        'x-cylscan-saturated': MEASURES[i][1],
      },
      `headers of part ${i}`,
    );
  });
}

function feed(chunks, boundary = BOUNDARY) {
  const parser = new MultipartParser(boundary);
  const parts = chunks.flatMap((chunk) => parser.push(chunk));
  return { parser, parts };
}

test('the boundary is read from the Content-Type', () => {
  assert.equal(boundaryOf('multipart/x-mixed-replace; boundary=cylscanframe'), 'cylscanframe');
  assert.equal(boundaryOf('multipart/x-mixed-replace;boundary="a b;c"'), 'a b;c');
  assert.equal(boundaryOf('multipart/x-mixed-replace; charset=x; Boundary=f00; q=1'), 'f00');
  assert.equal(boundaryOf('image/jpeg'), null);
  assert.equal(boundaryOf(null), null);
});

test('a whole stream gives every part with its headers, then closes', () => {
  const { parser, parts } = feed([STREAM]);
  expectParts(parts);
  assert.equal(parser.closed, true);
});

test('any split into two chunks gives the same parts', () => {
  for (let at = 0; at <= STREAM.length; at++) {
    const { parser, parts } = feed([STREAM.subarray(0, at), STREAM.subarray(at)]);
    expectParts(parts);
    assert.equal(parser.closed, true, `split at ${at}`);
  }
});

test('one byte at a time gives the same parts', () => {
  const { parser, parts } = feed([...STREAM].map((byte) => Uint8Array.of(byte)));
  expectParts(parts);
  assert.equal(parser.closed, true);
});

test('a part is given as soon as its body is complete, not at the next boundary', () => {
  const parser = new MultipartParser(BOUNDARY);
  const first = part(JPEGS[0], ...MEASURES[0]);
  // Up to the last byte of the body, without the CRLF that follows it.
  assert.deepEqual(parser.push(first.subarray(0, first.length - 3)), []);
  const parts = parser.push(first.subarray(first.length - 3, first.length - 2));
  assert.equal(parts.length, 1);
  assert.deepEqual(parts[0].body, JPEGS[0]);
  assert.equal(parser.closed, false);
});

test('the closing boundary ends the stream; what follows is ignored', () => {
  const parser = new MultipartParser(BOUNDARY);
  assert.equal(parser.push(part(JPEGS[1], '1', '0')).length, 1);
  assert.equal(parser.closed, false);
  assert.deepEqual(parser.push(ascii(`--${BOUNDARY}-`)), []);
  assert.equal(parser.closed, false, 'half a closing delimiter');
  assert.deepEqual(parser.push(ascii(`-\r\n`)), []);
  assert.equal(parser.closed, true);
  assert.deepEqual(parser.push(part(JPEGS[0], '1', '0')), []);
});

test('a stream cut in the middle of a part gives the parts before it only', () => {
  const whole = part(JPEGS[0], '1', '0');
  const { parser, parts } = feed([whole, whole.subarray(0, 100)]);
  assert.equal(parts.length, 1);
  assert.equal(parser.closed, false);
});

test('a preamble, transport padding and bare LFs are accepted', () => {
  const jpeg = body(5, 64);
  const stream = join8(
    ascii(`preamble that mentions --${BOUNDARY} mid-line\r\n`),
    ascii(`--${BOUNDARY}  \t\ncontent-type:image/jpeg\ncontent-length:  ${jpeg.length}\n\n`),
    jpeg,
    ascii(`\n--${BOUNDARY}--`),
  );
  for (let at = 0; at <= stream.length; at++) {
    const { parser, parts } = feed([stream.subarray(0, at), stream.subarray(at)]);
    assert.equal(parts.length, 1, `split at ${at}`);
    assert.deepEqual(parts[0].body, jpeg);
    assert.deepEqual(parts[0].headers, { 'content-type': 'image/jpeg', 'content-length': String(jpeg.length) });
    assert.equal(parser.closed, true);
  }
});

test('a part without Content-Length ends at the next CRLF and boundary', () => {
  const jpeg = ascii('\xff\xd8 no length: --cylscanframe mid-line, \r\n-- not it\xff\xd9');
  const stream = join8(
    ascii(`--${BOUNDARY}\r\nContent-Type: image/jpeg\r\nX-Cylscan-Focus: 7\r\n\r\n`),
    jpeg,
    ascii(`\r\n--${BOUNDARY}\r\nContent-Type: image/jpeg\r\n\r\n\r\n--${BOUNDARY}--\r\n`),
  );
  for (let at = 0; at <= stream.length; at++) {
    const { parser, parts } = feed([stream.subarray(0, at), stream.subarray(at)]);
    assert.equal(parts.length, 2, `split at ${at}`);
    assert.deepEqual(parts[0].body, jpeg);
    assert.equal(parts[0].headers['x-cylscan-focus'], '7');
    assert.equal(parts[1].body.length, 0, 'an empty part');
    assert.equal(parser.closed, true);
  }
});

test('headers or parts too large are refused, not buffered without end', () => {
  const endless = new MultipartParser(BOUNDARY, { maxHeaderBytes: 64 });
  endless.push(ascii(`--${BOUNDARY}\r\n`));
  assert.throws(() => endless.push(ascii(`X-Long: ${'a'.repeat(100)}`)), MultipartError);
  const huge = new MultipartParser(BOUNDARY, { maxPartBytes: 1000 });
  assert.throws(() => huge.push(ascii(`--${BOUNDARY}\r\nContent-Length: 1001\r\n\r\n`)), MultipartError);
  assert.throws(() => new MultipartParser(''), MultipartError);
});

test('a long stream is read in time linear in its length', () => {
  const jpeg = body(6, 100_000);
  const one = part(jpeg, '1', '0');
  const parser = new MultipartParser(BOUNDARY);
  let count = 0;
  const started = Date.now();
  for (let i = 0; i < 50; i++) {
    for (let at = 0; at < one.length; at += 16384) count += parser.push(one.subarray(at, at + 16384)).length;
  }
  assert.equal(count, 50);
  assert.ok(Date.now() - started < 5000, `50 parts of 100 kB took ${Date.now() - started} ms`);
});
