// SPDX-License-Identifier: Apache-2.0
// The one helper the views build their elements with.

// A new `tag` element with `props` assigned and `children` appended.
export function element(tag, props = {}, children = []) {
  const node = document.createElement(tag);
  Object.assign(node, props);
  for (const child of children) node.append(child);
  return node;
}
