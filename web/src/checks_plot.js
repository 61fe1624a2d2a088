// SPDX-License-Identifier: Apache-2.0
// The geometry of the checks' history plot (checks.js draws it as SVG): each
// measured check a dot at its time and its radius error (measured − nominal),
// and the band of ±tolerance it was judged against. Pure functions, no DOM,
// so that node tests them (tests/web/checks_plot.test.mjs).

// The y range shows at least this many tolerances each side of zero, so
// that the band never fills the plot and a drift towards its edge shows.
const MIN_SPAN_TOLERANCES = 2;
// ... and at most this many: one wild check (a knocked sphere) would
// otherwise squash every other into a line. Dots beyond are drawn at the edge.
const MAX_SPAN_TOLERANCES = 10;
// Room above the largest error, as a share of it.
const HEADROOM = 1.15;

// measured − nominal in mm, or null when the check measured nothing.
export function radiusError(check) {
  if (!check || !Number.isFinite(check.measured_radius_mm) || !Number.isFinite(check.radius_mm)) return null;
  return check.measured_radius_mm - check.radius_mm;
}

// Values from `lo` to `hi` at a 1-2-5 step, about `count` of them, and the step.
export function niceTicks(lo, hi, count = 5) {
  if (!(Number.isFinite(lo) && Number.isFinite(hi)) || hi <= lo || count < 1) return { step: NaN, values: [] };
  const raw = (hi - lo) / count;
  const magnitude = 10 ** Math.floor(Math.log10(raw));
  const step = [1, 2, 5, 10].map((f) => f * magnitude).find((s) => s >= raw * (1 - 1e-9));
  const values = [];
  // Integer multiples of the step, so that 0 is exactly 0 and no float drift piles up.
  for (let k = Math.ceil(lo / step - 1e-9); k * step <= hi + step * 1e-9; k++) values.push(k === 0 ? 0 : k * step);
  return { step, values };
}

// Decimals that show a 1-2-5 step (0.05 → 2, 0.1 → 1, 2 → 0).
export function decimalsFor(step) {
  if (!(step > 0) || !Number.isFinite(step)) return 3;
  return Math.max(0, Math.min(6, -Math.floor(Math.log10(step) + 1e-9)));
}

// A signed value as in "+0.012", "−0.250", "0.000" (a true minus sign).
export function formatSigned(value, decimals = 3) {
  if (!Number.isFinite(value)) return '–';
  const text = Math.abs(value).toFixed(decimals);
  if (Number(text) === 0) return (0).toFixed(decimals);
  return `${value < 0 ? '\u2212' : '+'}${text}`;
}

// The plot of `checks` (the API's records, any order) in a box of `width` ×
// `height` with `margin` {left, right, top, bottom} for the axes' labels.
// `tolerance` is the band drawn when no check measured anything yet.
// Returns the plot area {left, right, top, bottom}, the y range, the dots
// oldest first ({id, x, y, error, tolerance, pass, clipped, time}), the band
// as an SVG path, the y ticks ({value, y, label}), the zero line's y, and
// the times to label the x axis with ({x, time}).
export function checksPlot(checks, { width = 640, height = 200, margin = {}, tolerance = 0.1 } = {}) {
  const m = { left: 56, right: 12, top: 10, bottom: 24, ...margin };
  const area = { left: m.left, right: width - m.right, top: m.top, bottom: height - m.bottom };
  const measured = (Array.isArray(checks) ? checks : [])
    .map((check, index) => ({ check, index, error: radiusError(check), time: Date.parse(check && check.created) }))
    .filter((d) => d.error !== null);
  // Oldest first; by time when every check has one, else by the list's order
  // (newest first) reversed.
  const timed = measured.every((d) => Number.isFinite(d.time));
  measured.sort((a, b) => (timed ? a.time - b.time || b.index - a.index : b.index - a.index));

  const tolerances = measured.map((d) => d.check.tolerance_mm).filter((t) => t > 0 && Number.isFinite(t));
  const widest = tolerances.length ? Math.max(...tolerances) : tolerance > 0 ? tolerance : 0.1;
  const largest = measured.reduce((worst, d) => Math.max(worst, Math.abs(d.error)), 0);
  const half = Math.min(MAX_SPAN_TOLERANCES * widest, Math.max(MIN_SPAN_TOLERANCES * widest, largest * HEADROOM));
  const yMin = -half;
  const yMax = half;
  const yOf = (v) => area.top + ((yMax - Math.max(yMin, Math.min(yMax, v))) / (yMax - yMin)) * (area.bottom - area.top);

  // x: time, with a twentieth of the span free at each end so the first and
  // the last dots are not on the frame; a single time (or none) in the middle.
  const keys = measured.map((d, i) => (timed ? d.time : i));
  const first = keys.length ? keys[0] : 0;
  const last = keys.length ? keys[keys.length - 1] : 0;
  const pad = (last - first) / 20;
  const xOf = (key) =>
    last > first
      ? area.left + ((key - (first - pad)) / (last - first + 2 * pad)) * (area.right - area.left)
      : (area.left + area.right) / 2;

  const dots = measured.map((d, i) => ({
    id: d.check.id,
    x: xOf(keys[i]),
    y: yOf(d.error),
    error: d.error,
    tolerance: d.check.tolerance_mm,
    pass: d.check.pass === true,
    clipped: d.error < yMin || d.error > yMax,
    time: timed ? d.time : null,
  }));

  const band = bandPath(dots, area, yOf, widest);
  const { step, values } = niceTicks(yMin, yMax, 4);
  const decimals = decimalsFor(step);
  const yTicks = values.map((value) => ({ value, y: yOf(value), label: formatSigned(value, decimals) }));
  const xLabels = [];
  if (timed && dots.length > 0) {
    xLabels.push({ x: dots[0].x, time: dots[0].time });
    if (dots.length > 1 && last > first) xLabels.push({ x: dots[dots.length - 1].x, time: dots[dots.length - 1].time });
  }
  return { area, yMin, yMax, dots, band, yTicks, zeroY: yOf(0), xLabels };
}

// The ±tolerance band as a closed SVG path: each check's own tolerance from
// halfway to the previous dot to halfway to the next (the plot's edges at the
// ends), so that a check judged against another tolerance shows its own; with
// one tolerance throughout it is a plain rectangle. No dots: `fallback` across.
function bandPath(dots, area, yOf, fallback) {
  const steps = [];
  if (dots.length === 0) steps.push({ from: area.left, to: area.right, tolerance: fallback });
  for (let i = 0; i < dots.length; i++) {
    const from = i === 0 ? area.left : (dots[i - 1].x + dots[i].x) / 2;
    const to = i === dots.length - 1 ? area.right : (dots[i].x + dots[i + 1].x) / 2;
    const tolerance = dots[i].tolerance > 0 ? dots[i].tolerance : fallback;
    const previous = steps[steps.length - 1];
    if (previous && previous.tolerance === tolerance) previous.to = to;
    else steps.push({ from, to, tolerance });
  }
  const r = (v) => Math.round(v * 100) / 100;
  const upper = steps.flatMap((s) => [`${r(s.from)},${r(yOf(s.tolerance))}`, `${r(s.to)},${r(yOf(s.tolerance))}`]);
  const lower = steps
    .slice()
    .reverse()
    .flatMap((s) => [`${r(s.to)},${r(yOf(-s.tolerance))}`, `${r(s.from)},${r(yOf(-s.tolerance))}`]);
  return `M${[...upper, ...lower].join('L')}Z`;
}
