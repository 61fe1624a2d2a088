// SPDX-License-Identifier: Apache-2.0
// Bundles the page: SRC/index.html, SRC/main.js (with three.js and the CSS it
// imports) into OUT/index.html, OUT/assets/app.js, OUT/assets/app.css. The
// page loads nothing from elsewhere.
//
//   node build.mjs [--src DIR] [--out DIR]
//
// Packages (esbuild, three) are resolved from the node_modules beside this
// file: CMake copies it into the build tree, where `npm ci` ran.
import { copyFile, mkdir, rm } from 'node:fs/promises';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { parseArgs } from 'node:util';
import * as esbuild from 'esbuild';

const here = dirname(fileURLToPath(import.meta.url));
const { values } = parseArgs({
  options: { src: { type: 'string', default: join(here, 'src') }, out: { type: 'string', default: join(here, 'dist') } },
});
const src = resolve(values.src);
const out = resolve(values.out);

await rm(out, { recursive: true, force: true });
await mkdir(join(out, 'assets'), { recursive: true });
await esbuild.build({
  entryPoints: { app: join(src, 'main.js') },
  bundle: true,
  format: 'esm',
  target: ['es2020'],
  minify: true,
  legalComments: 'eof', // keeps three.js's licence notice
  nodePaths: [join(here, 'node_modules')],
  outdir: join(out, 'assets'),
  logLevel: 'warning',
});
await copyFile(join(src, 'index.html'), join(out, 'index.html'));
console.log(`web: bundled ${src} into ${out}`);
