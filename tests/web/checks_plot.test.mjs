// SPDX-License-Identifier: Apache-2.0
// Unit test of the geometry of the page's checks plot (web/src/checks_plot.js):
// each measured check a dot at its time and radius error, oldest left, the
// ±tolerance band around zero, the y range that keeps the band readable
// whatever the errors, and the tick labels.
//   CYLSCAN_WEB_SRC=web/src node --test tests/web/checks_plot.test.mjs
import assert from 'node:assert/strict';
import { join } from 'node:path';
import { test } from 'node:test';
import { pathToFileURL } from 'node:url';

const src = process.env.CYLSCAN_WEB_SRC;
assert.ok(src, 'CYLSCAN_WEB_SRC must name web/src');
const { checksPlot, decimalsFor, formatSigned, niceTicks, radiusError } = await import(
  pathToFileURL(join(src, 'checks_plot.js')).href
);

const SIZE = { width: 640, height: 200, margin: { left: 50, right: 10, top: 10, bottom: 30 } };
const AREA = { left: 50, right: 630, top: 10, bottom: 170 };

// A check as GET /api/v1/checks lists it.
function check(id, created, measured, { radius = 50, tolerance = 0.1, state = 'done' } = {}) {
  const done = state === 'done';
  return {
    id,
    state,
    created,
    artifact: 'sphere',
    radius_mm: radius,
    tolerance_mm: tolerance,
    measured_radius_mm: done ? measured : null,
    rmse_mm: done ? 0.02 : null,
    probing_error_form_mm: done ? 0.1 : null,
    probing_error_size_mm: done ? 2 * (measured - radius) : null,
    points: done ? 5000 : 0,
    pass: done && Math.abs(measured - radius) <= tolerance,
  };
}

// Parses the band's path "Mx,yLx,y…Z" into points.
function bandPoints(path) {
  assert.match(path, /^M[-\d.,L]+Z$/);
  return path
    .slice(1, -1)
    .split('L')
    .map((pair) => pair.split(',').map(Number));
}

const close = (actual, expected, what, eps = 1e-6) =>
  assert.ok(Math.abs(actual - expected) <= eps, `${what}: ${actual}, want ${expected}`);

test('radiusError: measured − nominal, null without a measurement', () => {
  close(radiusError(check('a', '2026-01-01T00:00:00Z', 50.03)), 0.03, 'error');
  close(radiusError(check('a', '2026-01-01T00:00:00Z', 24.9, { radius: 25 })), -0.1, 'error');
  assert.equal(radiusError(check('a', '2026-01-01T00:00:00Z', 0, { state: 'failed' })), null);
  assert.equal(radiusError(check('a', '2026-01-01T00:00:00Z', 0, { state: 'running' })), null);
  assert.equal(radiusError(null), null);
});

test('niceTicks: 1-2-5 steps on multiples of the step, zero exactly', () => {
  assert.deepEqual(niceTicks(-0.2, 0.2, 4), { step: 0.1, values: [-0.2, -0.1, 0, 0.1, 0.2] });
  const { step, values } = niceTicks(-0.23, 0.23, 4);
  assert.equal(step, 0.2);
  assert.deepEqual(values, [-0.2, 0, 0.2]);
  assert.deepEqual(niceTicks(-0.345, 0.345, 4).values.map((v) => Number(v.toFixed(6))), [-0.2, 0, 0.2]);
  assert.deepEqual(niceTicks(-0.3, 0.3, 6).values.map((v) => Number(v.toFixed(6))), [-0.3, -0.2, -0.1, 0, 0.1, 0.2, 0.3]);
  assert.equal(niceTicks(-1, 1, 4).step, 0.5);
  assert.equal(niceTicks(0, 7, 4).step, 2);
  assert.ok(values.includes(0) && Object.is(values[values.indexOf(0)], 0));
  assert.deepEqual(niceTicks(1, 1, 4).values, []);
  assert.deepEqual(niceTicks(NaN, 1, 4).values, []);
});

test('decimalsFor and formatSigned: labels as a person reads them', () => {
  assert.equal(decimalsFor(0.05), 2);
  assert.equal(decimalsFor(0.1), 1);
  assert.equal(decimalsFor(0.2), 1);
  assert.equal(decimalsFor(2), 0);
  assert.equal(decimalsFor(0.001), 3);
  assert.equal(formatSigned(0.0123, 3), '+0.012');
  assert.equal(formatSigned(-0.25, 3), '\u22120.250');
  assert.equal(formatSigned(-0.0001, 3), '0.000');
  assert.equal(formatSigned(0, 1), '0.0');
  assert.equal(formatSigned(NaN), '–');
});

test('dots: measured checks only, oldest left, at their time and error', () => {
  // Newest first, as the daemon lists them; a failed and a running check measure nothing.
  const checks = [
    check('run', '2026-03-01T00:00:00Z', 0, { state: 'running' }),
    check('c', '2026-02-01T00:00:00Z', 50.08),
    check('bad', '2026-01-20T00:00:00Z', 0, { state: 'failed' }),
    check('b', '2026-01-11T00:00:00Z', 49.95),
    check('a', '2026-01-01T00:00:00Z', 50.0),
  ];
  const plot = checksPlot(checks, SIZE);
  assert.deepEqual(plot.area, AREA);
  assert.deepEqual(plot.dots.map((d) => d.id), ['a', 'b', 'c']);
  assert.deepEqual(plot.dots.map((d) => d.pass), [true, true, true]);
  // Time scale with a twentieth of the span free at each end.
  const span = Date.parse('2026-02-01T00:00:00Z') - Date.parse('2026-01-01T00:00:00Z');
  const pad = span / 20;
  const xOf = (iso) => AREA.left + ((Date.parse(iso) - Date.parse('2026-01-01T00:00:00Z') + pad) / (span + 2 * pad)) * 580;
  close(plot.dots[0].x, xOf('2026-01-01T00:00:00Z'), 'x of a');
  close(plot.dots[1].x, xOf('2026-01-11T00:00:00Z'), 'x of b');
  close(plot.dots[2].x, xOf('2026-02-01T00:00:00Z'), 'x of c');
  // Symmetric y range: the largest error with headroom, at least 2 tolerances.
  close(plot.yMax, 0.2, 'yMax');
  close(plot.yMin, -0.2, 'yMin');
  close(plot.zeroY, 90, 'zero line');
  const yOf = (v) => AREA.top + ((0.2 - v) / 0.4) * 160;
  close(plot.dots[0].y, yOf(0), 'y of a');
  close(plot.dots[1].y, yOf(-0.05), 'y of b');
  close(plot.dots[2].y, yOf(0.08), 'y of c');
  assert.ok(plot.dots[2].y < plot.zeroY, 'a larger radius is above zero');
  assert.deepEqual(plot.yTicks.map((t) => t.label), ['\u22120.2', '\u22120.1', '0.0', '+0.1', '+0.2']);
  close(plot.yTicks[2].y, plot.zeroY, 'the 0 tick on the zero line');
  assert.deepEqual(plot.xLabels.map((l) => l.time), [Date.parse('2026-01-01T00:00:00Z'), Date.parse('2026-02-01T00:00:00Z')]);
});

test('band: ±tolerance across the plot, a rectangle when the tolerance is one', () => {
  const plot = checksPlot([check('b', '2026-01-02T00:00:00Z', 50.01), check('a', '2026-01-01T00:00:00Z', 49.99)], SIZE);
  const points = bandPoints(plot.band);
  const xs = points.map(([x]) => x);
  const ys = [...new Set(points.map(([, y]) => y))].sort((p, q) => p - q);
  close(Math.min(...xs), AREA.left, 'band left');
  close(Math.max(...xs), AREA.right, 'band right');
  assert.equal(ys.length, 2, `a rectangle: ${plot.band}`);
  const yOf = (v) => AREA.top + ((plot.yMax - v) / (plot.yMax - plot.yMin)) * 160;
  close(ys[0], yOf(0.1), 'band top', 0.01);
  close(ys[1], yOf(-0.1), 'band bottom', 0.01);
});

test('band: each check its own tolerance, changing halfway between the dots', () => {
  const plot = checksPlot(
    [check('b', '2026-01-03T00:00:00Z', 50.0, { tolerance: 0.05 }), check('a', '2026-01-01T00:00:00Z', 50.0, { tolerance: 0.1 })],
    SIZE,
  );
  const points = bandPoints(plot.band);
  const mid = Math.round(((plot.dots[0].x + plot.dots[1].x) / 2) * 100) / 100;
  const yOf = (v) => Math.round((AREA.top + ((plot.yMax - v) / (plot.yMax - plot.yMin)) * 160) * 100) / 100;
  assert.deepEqual(points.slice(0, 4), [
    [AREA.left, yOf(0.1)],
    [mid, yOf(0.1)],
    [mid, yOf(0.05)],
    [AREA.right, yOf(0.05)],
  ]);
  assert.deepEqual(points.slice(4), [
    [AREA.right, yOf(-0.05)],
    [mid, yOf(-0.05)],
    [mid, yOf(-0.1)],
    [AREA.left, yOf(-0.1)],
  ]);
});

test('y range: grows with the errors up to 10 tolerances; beyond, dots sit on the edge, marked', () => {
  const drifted = checksPlot([check('b', '2026-01-02T00:00:00Z', 50.3), check('a', '2026-01-01T00:00:00Z', 50.0)], SIZE);
  close(drifted.yMax, 0.3 * 1.15, 'yMax with headroom');
  assert.deepEqual(drifted.dots.map((d) => [d.pass, d.clipped]), [[true, false], [false, false]]);
  const wild = checksPlot([check('b', '2026-01-02T00:00:00Z', 45), check('a', '2026-01-01T00:00:00Z', 50.02)], SIZE);
  close(wild.yMax, 1, 'capped at 10 tolerances');
  close(wild.yMin, -1, 'capped at 10 tolerances');
  const [a, b] = wild.dots;
  assert.equal(b.clipped, true);
  assert.equal(a.clipped, false);
  close(b.y, AREA.bottom, 'the wild check on the bottom edge');
  close(b.error, -5, 'its error kept');
});

test('one check, or none: in the middle; the band of the tolerance given', () => {
  const one = checksPlot([check('a', '2026-01-01T00:00:00Z', 50.02)], SIZE);
  assert.equal(one.dots.length, 1);
  close(one.dots[0].x, (AREA.left + AREA.right) / 2, 'x of the only dot');
  assert.equal(one.xLabels.length, 1);
  const none = checksPlot([check('f', '2026-01-01T00:00:00Z', 0, { state: 'failed' })], { ...SIZE, tolerance: 0.25 });
  assert.equal(none.dots.length, 0);
  close(none.yMax, 0.5, 'two tolerances given');
  assert.equal(new Set(bandPoints(none.band).map(([, y]) => y)).size, 2);
  assert.deepEqual(none.xLabels, []);
  assert.equal(checksPlot(undefined, SIZE).dots.length, 0);
});

test('checks at one time, or without a time: all drawn, in the list order reversed', () => {
  const same = checksPlot(
    [check('b', '2026-01-01T00:00:00Z', 50.01), check('a', '2026-01-01T00:00:00Z', 49.99)],
    SIZE,
  );
  assert.deepEqual(same.dots.map((d) => d.id), ['a', 'b']);
  const untimed = checksPlot([check('c', 'soon', 50.0), check('b', '', 50.01), check('a', undefined, 49.99)], SIZE);
  assert.deepEqual(untimed.dots.map((d) => d.id), ['a', 'b', 'c']);
  assert.ok(untimed.dots[0].x < untimed.dots[1].x && untimed.dots[1].x < untimed.dots[2].x);
  assert.ok(untimed.dots.every((d) => d.time === null));
  assert.deepEqual(untimed.xLabels, []);
});
