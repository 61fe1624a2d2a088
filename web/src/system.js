// SPDX-License-Identifier: Apache-2.0
// The System panel: the head's version, host name and slots, the last
// update's result, and the upload of a RAUC bundle (PUT
// /api/v1/system/update) with its progress, then RAUC's from the events.

import { apiUrl, authHeaders, getJson } from './api.js';
import { element } from './dom.js';
import {
  describeImage,
  describeLastUpdate,
  describeSlot,
  describeUpdateState,
  uploadRefusal,
} from './system_model.js';

export class SystemView {
  constructor(root) {
    this.root = root;
    this.field = (name) => root.querySelector(`[data-field="${name}"]`);
    this.form = root.querySelector('form');
    this.form.addEventListener('submit', (event) => {
      event.preventDefault();
      this.upload();
    });
    this.loaded = false;
  }

  async refresh() {
    try {
      const system = await getJson('system');
      this.loaded = true;
      this.field('version').textContent = system.version ?? '–';
      this.field('image').textContent = describeImage(system.image);
      this.field('hostname').textContent = system.hostname || '–';
      this.field('slot').textContent = system.slot ?? 'not an image';
      const list = this.field('slots');
      list.replaceChildren(...(system.slots ?? []).map((s) => element('li', { textContent: describeSlot(s) })));
      if (!system.slots || system.slots.length === 0)
        list.append(element('li', { className: 'muted', textContent: 'no slots: this head has no RAUC' }));
      this.form.querySelector('button').disabled = system.updates === false;
      this.onUpdate(system.update);
    } catch (error) {
      this.message(`System: ${error.message}`, 'error');
    }
  }

  // An `update` event, or the system's `update`.
  onUpdate(update) {
    if (!update) return;
    const bar = this.field('progress');
    bar.hidden = update.state === 'idle';
    bar.value = update.progress ?? 0;
    this.field('progress-text').textContent = describeUpdateState(update);
    this.field('last').textContent = describeLastUpdate(update.last);
    if (update.state === 'idle' && this.busy) {
      this.busy = false;
      this.refresh();
    }
    if (update.state !== 'idle') this.busy = true;
  }

  message(text, kind = '') {
    const box = this.field('message');
    box.hidden = !text;
    box.textContent = text;
    box.className = `message ${kind}`;
  }

  // XMLHttpRequest, not fetch: only it reports an upload's progress.
  upload() {
    const file = this.form.querySelector('input[type=file]').files[0];
    if (!file) return;
    const xhr = new XMLHttpRequest();
    xhr.open('PUT', apiUrl('system/update'));
    for (const [name, value] of Object.entries(authHeaders({ 'Content-Type': 'application/octet-stream' })))
      xhr.setRequestHeader(name, value);
    const bar = this.field('progress');
    bar.hidden = false;
    xhr.upload.onprogress = (event) => {
      if (!event.lengthComputable) return;
      bar.value = Math.round((100 * event.loaded) / event.total);
      this.field('progress-text').textContent = `Uploading: ${bar.value} %`;
    };
    xhr.onload = () => {
      let body = {};
      try {
        body = JSON.parse(xhr.responseText);
      } catch {
        // not JSON: the status says enough
      }
      if (xhr.status === 202) {
        this.message(`Installing ${body.version ?? 'the bundle'} into slot ${body.target_slot ?? '?'}…`, 'ok');
        this.busy = true;
      } else {
        bar.hidden = true;
        this.message(uploadRefusal(xhr.status, body.error ?? xhr.statusText), 'error');
      }
    };
    xhr.onerror = () => this.message('The upload was cut off.', 'error');
    this.message('Uploading…');
    xhr.send(file);
  }
}
