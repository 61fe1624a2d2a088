// SPDX-License-Identifier: Apache-2.0
// Unit test of what the page's System panel says of the slots and updates
// (web/src/system_model.js).
//   CYLSCAN_WEB_SRC=web/src node --test tests/web/system_model.test.mjs
import assert from 'node:assert/strict';
import { join } from 'node:path';
import { test } from 'node:test';
import { pathToFileURL } from 'node:url';

const src = process.env.CYLSCAN_WEB_SRC;
assert.ok(src, 'CYLSCAN_WEB_SRC must name web/src');
const { describeImage, describeLastUpdate, describeSlot, describeUpdateState, uploadRefusal } = await import(
  pathToFileURL(join(src, 'system_model.js')).href
);

test('the last update in words', () => {
  assert.equal(describeLastUpdate(null), 'No update installed through the page yet.');
  assert.equal(
    describeLastUpdate({ version: '1.2.3', target_slot: 'b', result: 'installed' }),
    'Installed 1.2.3 into slot b; waiting for the reboot.',
  );
  assert.equal(
    describeLastUpdate({ version: '1.2.3', target_slot: 'b', result: 'rolled back',
      message: 'the new slot did not come up; the head went back to slot a' }),
    'Update 1.2.3 rolled back: the new slot did not come up; the head went back to slot a',
  );
  assert.equal(
    describeLastUpdate({ version: '', target_slot: null, result: 'failed', message: 'truncated upload' }),
    'Update failed: truncated upload',
  );
  assert.equal(describeLastUpdate({ version: '2', target_slot: 'a', result: 'booted' }), 'Update 2 running from slot a.');
});

test('a slot in one line', () => {
  assert.equal(
    describeSlot({ name: 'rootfs.0', bootname: 'a', state: 'booted', boot_status: 'good', version: '1.0.0' }),
    'a (rootfs.0): booted, good, 1.0.0',
  );
  assert.equal(
    describeSlot({ name: 'rootfs.1', bootname: 'b', state: 'inactive', boot_status: null, version: null }),
    'b (rootfs.1): inactive, version unknown',
  );
});

test('progress and refusals', () => {
  assert.equal(describeUpdateState({ state: 'idle', progress: 0 }), '');
  assert.equal(describeUpdateState({ state: 'installing', progress: 40, message: 'Copying' }), 'Installing: 40 % — Copying');
  assert.equal(describeUpdateState({ state: 'receiving', progress: 5, message: '' }), 'Uploading: 5 %');
  assert.match(uploadRefusal(422, 'bundle is for x, this head is y'), /refuses the bundle: bundle is for x/);
  assert.match(uploadRefusal(418, 'teapot'), /\(418\): teapot/);
});

test('the image in words', () => {
  assert.equal(describeImage(null), 'not an image');
  assert.equal(describeImage({ id: 'cylscan-rpi5', version: '1.2.3' }), 'cylscan-rpi5 1.2.3');
  assert.equal(describeImage({ id: null, version: '1.2.3' }), '1.2.3');
  assert.equal(describeImage({ id: null, version: null }), 'unnamed image');
});
