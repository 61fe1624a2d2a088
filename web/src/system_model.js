// SPDX-License-Identifier: Apache-2.0
// What the System panel shows of GET /api/v1/system and of `update` events
// (docs/http-api.md, "System update"), as text: no DOM, so node tests it.

// The result of the last update, as one sentence; '' when there was none.
export function describeLastUpdate(last) {
  if (!last) return 'No update installed through the page yet.';
  const version = last.version ? ` ${last.version}` : '';
  const slot = last.target_slot ? ` into slot ${last.target_slot}` : '';
  switch (last.result) {
    case 'installing':
      return `Installing${version}${slot}.`;
    case 'installed':
      return `Installed${version}${slot}; waiting for the reboot.`;
    case 'booted':
      return `Update${version} running from slot ${last.target_slot}.`;
    case 'rolled back':
      return `Update${version} rolled back: ${last.message}`;
    case 'failed':
      return `Update${version} failed: ${last.message}`;
    default:
      return `Update${version}: ${last.result}`;
  }
}

// The image the head runs: "cylscan-rpi5 1.2.3"; outside an image, says so.
export function describeImage(image) {
  if (!image) return 'not an image';
  return [image.id, image.version].filter((part) => part).join(' ') || 'unnamed image';
}

// One line per slot: "a (rootfs.0): booted, good, 1.2.3".
export function describeSlot(slot) {
  const parts = [slot.state];
  if (slot.boot_status) parts.push(slot.boot_status);
  parts.push(slot.version ?? 'version unknown');
  return `${slot.bootname} (${slot.name}): ${parts.join(', ')}`;
}

// The progress line of an `update` event (or the system's `update`).
export function describeUpdateState(update) {
  if (!update || update.state === 'idle') return '';
  const what = update.state === 'receiving' ? 'Uploading' : 'Installing';
  const message = update.message ? ` — ${update.message}` : '';
  return `${what}: ${update.progress ?? 0} %${message}`;
}

// The message of a refused upload, by its status.
export function uploadRefusal(status, error) {
  const reasons = {
    401: 'A token is needed to update the head.',
    409: `The head is busy: ${error}`,
    413: `The bundle is too large: ${error}`,
    422: `The head refuses the bundle: ${error}`,
    503: `This head cannot install updates: ${error}`,
    507: `No room for the bundle: ${error}`,
  };
  return reasons[status] ?? `Update refused (${status}): ${error}`;
}
