// SPDX-License-Identifier: Apache-2.0
// What the calibration section shows of a session (docs/http-api.md,
// "Calibration session"), without the DOM so that node can test it: the
// target pose to take next on the virtual head, the counts, the guidance and
// the result as text, and how an event's session is merged with the one shown.

const DASH = '–';

const finite = (value) => typeof value === 'number' && Number.isFinite(value);

export function formatNumber(value, decimals) {
  return finite(value) ? value.toFixed(decimals) : DASH;
}

export function formatPx(value, decimals = 3) {
  return finite(value) ? `${value.toFixed(decimals)} px` : DASH;
}

export function formatMm(value, decimals = 4) {
  return finite(value) ? `${value.toFixed(decimals)} mm` : DASH;
}

// A share 0..1 as a percentage with at most 3 significant digits.
export function formatPercent(fraction) {
  if (!finite(fraction)) return DASH;
  const percent = fraction * 100;
  return `${percent === 0 ? '0' : Number(percent.toPrecision(3))} %`;
}

export function formatDegrees(value) {
  return finite(value) ? `${value.toFixed(1)}°` : DASH;
}

// A target's scene as a person reads it: "calibration/board07.toml" → "board07".
export function targetLabel(scene) {
  if (typeof scene !== 'string' || scene === '') return '';
  const name = scene.slice(scene.lastIndexOf('/') + 1);
  return name.endsWith('.toml') ? name.slice(0, -'.toml'.length) : name;
}

// The scenes already taken: board pairs or plane poses of the session that
// name one. A failed plane pose is not taken (it can be taken again); a pair
// tried is, whether or not the board was found (the pose would give the same).
export function takenScenes(items, { planes = false } = {}) {
  const taken = new Set();
  for (const item of Array.isArray(items) ? items : []) {
    if (!item || typeof item.scene !== 'string') continue;
    if (planes && item.state === 'failed') continue;
    taken.add(item.scene);
  }
  return taken;
}

// The target to take next: the first one not yet taken after `after` (the
// one just taken, or chosen), wrapping around to those skipped before it;
// null when every target is taken (or there are none).
export function nextTarget(targets, taken, after = null) {
  if (!Array.isArray(targets) || targets.length === 0) return null;
  const start = after === null ? 0 : targets.indexOf(after) + 1;
  for (let i = 0; i < targets.length; i++) {
    const scene = targets[(start + i) % targets.length];
    if (!taken.has(scene)) return scene;
  }
  return null;
}

// The counts the section shows and its buttons depend on.
export function sessionCounts(session) {
  const boards = Array.isArray(session?.boards) ? session.boards : [];
  const planes = Array.isArray(session?.planes) ? session.planes : [];
  return {
    boards: boards.length,
    kept: boards.filter((b) => b?.found?.main && b?.found?.aux).length,
    planes: planes.length,
    planesDone: planes.filter((p) => p?.state === 'done').length,
    planesFailed: planes.filter((p) => p?.state === 'failed').length,
    planeCapturing: planes.some((p) => p?.state === 'capturing'),
  };
}

// A session from an event or an answer that lacks `targets` (only
// GET /api/v1/calibration/session has them) keeps the ones known: they are
// the board's shipped poses, the same for every session.
export function mergeSession(known, incoming) {
  if (!incoming || typeof incoming !== 'object') return known ?? null;
  if (incoming.targets || !known?.targets) return incoming;
  return { ...incoming, targets: known.targets };
}

const CAMERA_ORDER = ['main', 'aux'];

function cameraNames(cameras) {
  const names = Object.keys(cameras ?? {});
  return [...CAMERA_ORDER.filter((n) => names.includes(n)), ...names.filter((n) => !CAMERA_ORDER.includes(n)).sort()];
}

// The guidance as rows of text, one per camera: {camera, ready, cells}; a
// camera without an estimate yet (fewer than 4 kept pairs) has ready false.
export function guidanceRows(guidance) {
  const cameras = guidance?.cameras ?? {};
  return cameraNames(cameras).map((camera) => {
    const g = cameras[camera];
    if (!g) return { camera, ready: false, cells: null };
    const sigma = g.sigma_px ?? {};
    return {
      camera,
      ready: true,
      cells: {
        fx: formatPx(sigma.fx),
        fy: formatPx(sigma.fy),
        cx: formatPx(sigma.cx),
        cy: formatPx(sigma.cy),
        rms: formatPx(g.rms_px),
        coverage: formatPercent(g.coverage),
        tilt: formatDegrees(g.max_tilt_deg),
      },
    };
  });
}

// Whether the guidance says the views are enough: 'enough', 'not-enough', or
// 'unknown' (a daemon without guidance).
export function guidanceVerdict(guidance) {
  if (!guidance || typeof guidance.enough !== 'boolean') return 'unknown';
  return guidance.enough ? 'enough' : 'not-enough';
}

// The solved session's figures as text.
export function resultSummary(result) {
  if (!result) return null;
  const rejected = Array.isArray(result.boards_rejected) ? result.boards_rejected : [];
  return {
    stereoRms: formatPx(result.stereo_rms_px),
    boardsUsed: finite(result.boards_used) ? String(result.boards_used) : DASH,
    boardsRejected:
      rejected.length === 0 ? 'none' : rejected.map((r) => `#${r.index}${r.reason ? ` (${r.reason})` : ''}`).join(', '),
    pooledRmse: formatMm(result.pooled_rmse_mm),
    baseline: formatMm(result.baseline_mm, 2),
    pixels: finite(result.pixels_calibrated) ? result.pixels_calibrated.toLocaleString('en-US') : DASH,
  };
}

// One row per camera of the result: each intrinsic with its σ, and the RMS.
export function resultCameraRows(result) {
  const cameras = result?.cameras ?? {};
  return cameraNames(cameras).map((camera) => {
    const c = cameras[camera] ?? {};
    const sigma = c.sigma_px ?? {};
    const withSigma = (key) => (finite(c[key]) ? `${c[key].toFixed(2)} ± ${formatNumber(sigma[key], 3)}` : DASH);
    return { camera, fx: withSigma('fx'), fy: withSigma('fy'), cx: withSigma('cx'), cy: withSigma('cy'), rms: formatPx(c.rms_px) };
  });
}

// One row per plane pose of the result, with the scene it was taken of.
export function resultPoseRows(result, planes = []) {
  const poses = Array.isArray(result?.poses) ? result.poses : [];
  const sceneOf = new Map((Array.isArray(planes) ? planes : []).map((p) => [p.index, p.scene]));
  return poses.map((pose) => ({
    index: pose.index,
    scene: targetLabel(sceneOf.get(pose.index)),
    rmse: formatMm(pose.rmse_mm),
    planeFit: formatMm(pose.plane_fit_rmse_mm),
    mainValid: formatPercent(pose.main_valid_fraction),
    auxValid: formatPercent(pose.aux_valid_fraction),
  }));
}

// The calibration info of an install or a rollback (the shape of
// GET /api/v1/calibration's "main") as a phrase.
export function describeCalibration(info) {
  if (!info || !info.installed) return 'no calibration';
  const size = finite(info.width) && finite(info.height) ? `${info.width} × ${info.height} px` : '';
  const phase = info.phase_source ? `${info.phase_source} phase` : '';
  const parts = [size, phase].filter(Boolean);
  return parts.length ? `a calibration (${parts.join(', ')})` : 'a calibration';
}

// The question asked before a new session replaces the current one, or null
// when there is nothing to lose.
export function replaceWarning(session) {
  if (!session) return null;
  const { boards, planes } = sessionCounts(session);
  if (session.state === 'solving') return null; // the daemon refuses: its words are shown
  if (boards === 0 && planes === 0 && session.state !== 'solved') return null;
  const taken = `${boards} board pair${boards === 1 ? '' : 's'} and ${planes} plane pose${planes === 1 ? '' : 's'}`;
  if (session.state === 'solved') {
    return `Start a new calibration session? The current one (${taken}) is solved: unless its calibration is installed, it is lost.`;
  }
  return `Start a new calibration session? The current one (${taken}) is not solved and will be thrown away.`;
}
