// SPDX-License-Identifier: Apache-2.0
// Unit test of newestOnly() (web/src/api.js): overlapping requests whose
// answers come back out of order never put an older answer in place of a
// newer one.
//   CYLSCAN_WEB_SRC=web/src node --test tests/web/api_newest.test.mjs
import assert from 'node:assert/strict';
import { join } from 'node:path';
import { test } from 'node:test';
import { pathToFileURL } from 'node:url';

const src = process.env.CYLSCAN_WEB_SRC;
assert.ok(src, 'CYLSCAN_WEB_SRC must name web/src');
const { STALE, newestOnly } = await import(pathToFileURL(join(src, 'api.js')).href);

// A request that answers `value` when the test says so.
function deferred() {
  let resolve;
  let reject;
  const promise = new Promise((res, rej) => {
    resolve = res;
    reject = rej;
  });
  return { promise, resolve, reject };
}

test('answers in order are all taken', async () => {
  const get = newestOnly(async (value) => value);
  assert.equal(await get('first'), 'first');
  assert.equal(await get('second'), 'second');
});

test('an answer that comes after a later call\'s is stale', async () => {
  const pending = [deferred(), deferred()];
  let n = 0;
  const get = newestOnly(() => pending[n++].promise);
  const older = get();
  const newer = get();
  pending[1].resolve('installed');
  assert.equal(await newer, 'installed');
  pending[0].resolve('not installed');
  assert.equal(await older, STALE);
});

test('a later call still answers after an older one was taken', async () => {
  const pending = [deferred(), deferred(), deferred()];
  let n = 0;
  const get = newestOnly(() => pending[n++].promise);
  const a = get();
  const b = get();
  const c = get();
  pending[0].resolve('a');
  assert.equal(await a, 'a');
  pending[2].resolve('c');
  assert.equal(await c, 'c');
  pending[1].resolve('b');
  assert.equal(await b, STALE);
});

test('a failed call is an error, and does not make the others stale', async () => {
  const pending = [deferred(), deferred()];
  let n = 0;
  const get = newestOnly(() => pending[n++].promise);
  const older = get();
  const newer = get();
  pending[1].reject(new Error('HTTP 503'));
  await assert.rejects(newer, /HTTP 503/);
  pending[0].resolve('idle');
  assert.equal(await older, 'idle');
});
