// SPDX-License-Identifier: Apache-2.0
// Unit test of what the page's calibration section shows of a session
// (web/src/calibration_model.js): the next target pose on the virtual head,
// the counts, how an event's session keeps the targets, the guidance and the
// result as text, and the question before a session is replaced.
//   CYLSCAN_WEB_SRC=web/src node --test tests/web/calibration_model.test.mjs
import assert from 'node:assert/strict';
import { join } from 'node:path';
import { test } from 'node:test';
import { pathToFileURL } from 'node:url';

const src = process.env.CYLSCAN_WEB_SRC;
assert.ok(src, 'CYLSCAN_WEB_SRC must name web/src');
const model = await import(pathToFileURL(join(src, 'calibration_model.js')).href);
const {
  describeCalibration,
  formatPercent,
  guidanceRows,
  guidanceVerdict,
  mergeSession,
  nextTarget,
  replaceWarning,
  resultCameraRows,
  resultPoseRows,
  resultSummary,
  sessionCounts,
  takenScenes,
  targetLabel,
} = model;

const boards = ['calibration/board00.toml', 'calibration/board01.toml', 'calibration/board02.toml', 'calibration/board03.toml'];

test('the next target is the first not taken after the one just taken, wrapping around', () => {
  assert.equal(nextTarget(boards, new Set()), boards[0]);
  assert.equal(nextTarget(boards, new Set([boards[0]]), boards[0]), boards[1]);
  // board01 skipped, board02 taken: on to board03, then back to board01.
  assert.equal(nextTarget(boards, new Set([boards[0], boards[2]]), boards[2]), boards[3]);
  assert.equal(nextTarget(boards, new Set([boards[0], boards[2], boards[3]]), boards[3]), boards[1]);
  assert.equal(nextTarget(boards, new Set(boards), boards[3]), null);
  // Without a last one, or with one that is no target: from the start.
  assert.equal(nextTarget(boards, new Set([boards[0]]), 'elsewhere.toml'), boards[1]);
  assert.equal(nextTarget([], new Set()), null);
  assert.equal(nextTarget(undefined, new Set()), null);
});

test('taken scenes: every pair tried, but no failed plane pose', () => {
  const pairs = [
    { index: 0, found: { main: true, aux: true }, scene: boards[0] },
    { index: 1, found: { main: false, aux: true }, scene: boards[1] },
    { index: 2, found: { main: true, aux: true } },
  ];
  assert.deepEqual([...takenScenes(pairs)], [boards[0], boards[1]]);
  const planes = [
    { index: 0, state: 'done', scene: 'calibration/plane00.toml' },
    { index: 1, state: 'failed', scene: 'calibration/plane01.toml' },
    { index: 2, state: 'capturing', scene: 'calibration/plane02.toml' },
  ];
  assert.deepEqual([...takenScenes(planes, { planes: true })], ['calibration/plane00.toml', 'calibration/plane02.toml']);
  assert.equal(takenScenes(null).size, 0);
});

test('counts of a session', () => {
  const counts = sessionCounts({
    boards: [
      { index: 0, found: { main: true, aux: true } },
      { index: 1, found: { main: true, aux: false } },
      { index: 2, found: { main: true, aux: true } },
    ],
    planes: [{ index: 0, state: 'done' }, { index: 1, state: 'failed' }, { index: 2, state: 'capturing' }],
  });
  assert.deepEqual(counts, { boards: 3, kept: 2, planes: 3, planesDone: 1, planesFailed: 1, planeCapturing: true });
  assert.deepEqual(sessionCounts(null), { boards: 0, kept: 0, planes: 0, planesDone: 0, planesFailed: 0, planeCapturing: false });
});

test('an event without targets keeps those known; one with them takes them', () => {
  const known = { created: 'a', state: 'capturing', targets: { boards, planes: [] } };
  const event = { created: 'a', state: 'solving', boards: [] };
  const merged = mergeSession(known, event);
  assert.equal(merged.state, 'solving');
  assert.equal(merged.targets, known.targets);
  const other = { created: 'b', targets: { boards: [boards[0]], planes: [] } };
  assert.equal(mergeSession(known, other), other);
  assert.equal(mergeSession(null, event), event);
  assert.equal(mergeSession(known, null), known);
});

test('target labels', () => {
  assert.equal(targetLabel('calibration/board07.toml'), 'board07');
  assert.equal(targetLabel('plate.toml'), 'plate');
  assert.equal(targetLabel(undefined), '');
});

test('guidance rows: main first, a camera without an estimate says so', () => {
  const guidance = {
    enough: false,
    advice: 'more views',
    cameras: {
      aux: null,
      main: { sigma_px: { fx: 2.4, fy: 2.3, cx: 3.216, cy: 2.18 }, rms_px: 0.1155, coverage: 0.5625, max_tilt_deg: 32.16 },
    },
  };
  const rows = guidanceRows(guidance);
  assert.deepEqual(rows.map((r) => r.camera), ['main', 'aux']);
  assert.deepEqual(rows[0].cells, {
    fx: '2.400 px',
    fy: '2.300 px',
    cx: '3.216 px',
    cy: '2.180 px',
    rms: '0.116 px',
    coverage: '56.3 %',
    tilt: '32.2°',
  });
  assert.equal(rows[1].ready, false);
  assert.equal(guidanceVerdict(guidance), 'not-enough');
  assert.equal(guidanceVerdict({ ...guidance, enough: true }), 'enough');
  assert.equal(guidanceVerdict(undefined), 'unknown');
  assert.deepEqual(guidanceRows(undefined), []);
});

test('percentages', () => {
  assert.equal(formatPercent(1), '100 %');
  assert.equal(formatPercent(0.9155517578125), '91.6 %');
  assert.equal(formatPercent(0), '0 %');
  assert.equal(formatPercent(null), '–');
});

const result = {
  stereo_rms_px: 0.12345,
  boards_used: 63,
  boards_rejected: [{ index: 5, reason: 'reprojection outlier' }],
  pooled_rmse_mm: 0.0238,
  baseline_mm: 269.4428,
  pixels_calibrated: 81920,
  cameras: {
    main: { fx: 1111.628, fy: 1111.447, cx: 160.877, cy: 125.812, rms_px: 0.1155, sigma_px: { fx: 2.4, fy: 2.32, cx: 3.233, cy: 2.197 } },
    aux: { fx: 1111.28, fy: 1111.3, cx: 155.66, cy: 127.64, rms_px: 0.1353, sigma_px: { fx: 3.2, fy: 3.27, cx: 4.34, cy: 3.36 } },
  },
  poses: [
    { index: 0, rmse_mm: 0.01656, plane_fit_rmse_mm: 0.0312, main_valid_fraction: 1, aux_valid_fraction: 0.9156 },
    { index: 2, rmse_mm: 0.0186, plane_fit_rmse_mm: 0.03, main_valid_fraction: 0.5, aux_valid_fraction: null },
  ],
};

test('the result as text', () => {
  assert.deepEqual(resultSummary(result), {
    stereoRms: '0.123 px',
    boardsUsed: '63',
    boardsRejected: '#5 (reprojection outlier)',
    pooledRmse: '0.0238 mm',
    baseline: '269.44 mm',
    pixels: '81,920',
  });
  assert.equal(resultSummary({ ...result, boards_rejected: [] }).boardsRejected, 'none');
  assert.equal(resultSummary(null), null);
  const cameras = resultCameraRows(result);
  assert.deepEqual(cameras.map((c) => c.camera), ['main', 'aux']);
  assert.deepEqual(cameras[0], { camera: 'main', fx: '1111.63 ± 2.400', fy: '1111.45 ± 2.320', cx: '160.88 ± 3.233', cy: '125.81 ± 2.197', rms: '0.116 px' });
  const poses = resultPoseRows(result, [
    { index: 0, scene: 'calibration/plane00.toml' },
    { index: 2, scene: 'calibration/plane02.toml' },
  ]);
  assert.deepEqual(poses, [
    { index: 0, scene: 'plane00', rmse: '0.0166 mm', planeFit: '0.0312 mm', mainValid: '100 %', auxValid: '91.6 %' },
    { index: 2, scene: 'plane02', rmse: '0.0186 mm', planeFit: '0.0300 mm', mainValid: '50 %', auxValid: '–' },
  ]);
});

test('calibration info as a phrase', () => {
  assert.equal(describeCalibration({ installed: true, width: 320, height: 256, phase_source: 'fused' }), 'a calibration (320 × 256 px, fused phase)');
  assert.equal(describeCalibration({ installed: false }), 'no calibration');
  assert.equal(describeCalibration(null), 'no calibration');
});

test('the question before a new session replaces the current one', () => {
  assert.equal(replaceWarning(null), null);
  assert.equal(replaceWarning({ state: 'capturing', boards: [], planes: [] }), null);
  const unsolved = replaceWarning({ state: 'capturing', boards: [{ index: 0 }], planes: [] });
  assert.match(unsolved, /1 board pair and 0 plane poses\) is not solved and will be thrown away/);
  assert.match(replaceWarning({ state: 'failed', boards: [{}, {}], planes: [{}] }), /2 board pairs and 1 plane pose\) is not solved/);
  assert.match(replaceWarning({ state: 'solved', boards: [{}], planes: [{}] }), /is solved: unless its calibration is installed, it is lost/);
  // A solve under way is refused by the daemon, whose words are shown instead.
  assert.equal(replaceWarning({ state: 'solving', boards: [{}], planes: [] }), null);
});
