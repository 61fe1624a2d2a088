// SPDX-License-Identifier: Apache-2.0
#include "drivers/sim/head_config.hpp"

#include <set>
#include <sstream>
#include <stdexcept>

#include "drivers/toml_reader.hpp"

namespace cylscan::sim {

using drivers::ConfigError;
using drivers::parseTomlFile;
using drivers::TableReader;

HeadConfig defaultHeadConfig() {
  HeadConfig c;
  CameraParams main;
  main.name = "main";
  main.fx = 3478.26;
  main.fy = 3478.26;
  main.cx = 502.3;
  main.cy = 397.8;
  main.k1 = -0.085;
  main.k2 = 0.12;
  CameraParams aux = main;
  aux.name = "aux";
  aux.fx = 3481.5;
  aux.fy = 3480.9;
  aux.cx = 497.1;
  aux.cy = 402.6;
  aux.k1 = -0.09;
  aux.k2 = 0.14;
  aux.position_mm = {270.0, 1.5, -3.0};
  aux.rotation_deg = lookAtRotationDeg(toVec(aux.position_mm), Vec3(0, 0, 580), 0.2);
  c.cameras = {main, aux};
  return c;
}

HeadConfig idealOf(HeadConfig c) {
  const ProjectorParams projector;
  c.projector.low_half_offset_deg = projector.low_half_offset_deg;
  c.projector.slot_pitch_error_deg = projector.slot_pitch_error_deg;
  c.projector.slot_width_error = projector.slot_width_error;
  c.projector.source_warmup_drop = projector.source_warmup_drop;
  c.projector.source_warmup_tau_s = projector.source_warmup_tau_s;
  const StageParams stage;
  c.stage.backlash_deg = stage.backlash_deg;
  c.stage.home_repeatability_deg = stage.home_repeatability_deg;
  const CameraParams camera;
  for (CameraParams& cam : c.cameras) {
    cam.response_gamma = camera.response_gamma;
    cam.line_time_us = camera.line_time_us;
  }
  return c;
}

void validate(const HeadConfig& c) {
  validate(c.projector);
  validate(c.stage);
  if (c.cameras.empty() || c.cameras.front().name != "main") {
    throw std::invalid_argument("head: the first camera must be 'main'");
  }
  std::set<std::string> names;
  for (const CameraParams& cam : c.cameras) {
    validate(cam);
    if (!names.insert(cam.name).second) {
      throw std::invalid_argument("head: camera '" + cam.name + "' twice");
    }
  }
  const CameraParams& main = c.cameras.front();
  if (main.position_mm != std::array<double, 3>{0, 0, 0} ||
      main.rotation_deg != std::array<double, 3>{0, 0, 0}) {
    throw std::invalid_argument("head: the main camera defines the frame (no pose)");
  }
  if (!names.count(c.faults.camera)) {
    throw std::invalid_argument("faults.camera: no camera '" + c.faults.camera + "'");
  }
  if (!(c.noise.scale >= 0)) throw std::invalid_argument("noise.scale: must be >= 0");
  if (!(c.noise.reference_exposure_us > 0)) {
    throw std::invalid_argument("noise.reference_exposure_us: must be > 0");
  }
  if (c.render.exposure_samples < 1 || c.render.exposure_samples > 8) {
    throw std::invalid_argument("render.exposure_samples: must be in [1, 8]");
  }
  if (c.render.board_supersample < 1 || c.render.board_supersample > 8) {
    throw std::invalid_argument("render.board_supersample: must be in [1, 8]");
  }
  if (c.render.threads < 0) throw std::invalid_argument("render.threads: must be >= 0");
  std::set<std::string> lines;
  for (const LineConfig* l : {&c.lines.step, &c.lines.dir, &c.lines.enable, &c.lines.trigger,
                              &c.lines.light, &c.lines.home, &c.lines.fault}) {
    if (l->name.empty() || !lines.insert(l->name).second) {
      throw std::invalid_argument("lines: names must be non-empty and distinct ('" + l->name +
                                  "')");
    }
  }
}

namespace {

// A number as a person writes it in the file (20, not 20.000000).
std::string shortNumber(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

// A control's keys: its default value and the bounds of its range.
struct RangeKeys {
  const char* value;
  const char* min;
  const char* max;
};

// min <= max and the default within them. The error names a key the file
// gives: of a pair out of order, max unless only min is given; of a default
// out of range, the default, else the bound that excludes it.
void requireRange(const TableReader& r, double value, const RangeKeys& keys, double min,
                  double max) {
  if (max < min) {
    if (r.has(keys.max)) {
      r.fail(keys.max, "must be >= " + std::string(keys.min) + " (" + shortNumber(min) + ")");
    }
    r.fail(keys.min, "must be <= " + std::string(keys.max) + " (" + shortNumber(max) + ")");
  }
  if (value >= min && value <= max) return;
  const std::string range = std::string("[") + keys.min + ", " + keys.max + "] = [" +
                            shortNumber(min) + ", " + shortNumber(max) + "]";
  if (r.has(keys.value)) r.fail(keys.value, shortNumber(value) + " is outside " + range);
  r.fail(value < min ? keys.min : keys.max,
         std::string("must keep ") + keys.value + " (" + shortNumber(value) + ") within " + range);
}

// Calls a validate() and turns its std::invalid_argument into a ConfigError.
template <typename T>
void validateAt(const T& value, const TableReader& r) {
  try {
    validate(value);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(r.file(), 0, "", e.what());
  }
}

ProjectorParams readProjector(TableReader r) {
  ProjectorParams p;
  p.axis_origin_mm = r.vec3("axis_origin_mm", p.axis_origin_mm);
  p.rotation_deg = r.vec3("rotation_deg", p.rotation_deg);
  p.radius_mm = r.positive("radius_mm", p.radius_mm);
  p.theta_high_deg = r.positive("theta_high_deg", p.theta_high_deg);
  r.require(p.theta_high_deg < 90, "theta_high_deg", "must be < 90");
  p.theta_low_deg = r.positive("theta_low_deg", p.theta_low_deg);
  r.require(p.theta_low_deg < 90 && p.theta_low_deg != p.theta_high_deg, "theta_low_deg",
            "must be < 90 and differ from theta_high_deg");
  p.duty = r.number("duty", p.duty);
  r.require(p.duty > 0 && p.duty < 1, "duty", "must be in (0, 1)");
  p.low_half_offset_deg = r.number("low_half_offset_deg", p.low_half_offset_deg);
  r.require(std::abs(p.low_half_offset_deg) < p.theta_low_deg / 2, "low_half_offset_deg",
            "must be within half a low period of 180°");
  p.slot_pitch_error_deg = r.nonNegative("slot_pitch_error_deg", p.slot_pitch_error_deg);
  r.require(p.slot_pitch_error_deg < p.theta_high_deg / 10, "slot_pitch_error_deg",
            "must be < theta_high_deg / 10");
  p.slot_width_error = r.nonNegative("slot_width_error", p.slot_width_error);
  r.require(p.slot_width_error < 0.1, "slot_width_error", "must be < 0.1 (of a period)");
  p.slot_error_seed = static_cast<std::uint64_t>(r.integer("slot_error_seed", 1));
  const std::string kernel = r.string("blur_kernel", "gaussian");
  r.require(kernel == "gaussian" || kernel == "box", "blur_kernel", "must be gaussian or box");
  p.blur_kernel = kernel == "box" ? BlurKernel::Box : BlurKernel::Gaussian;
  p.blur_width_deg = r.nonNegative("blur_width_deg", p.blur_width_deg);
  r.require(p.blur_width_deg < 10, "blur_width_deg", "must be < 10");
  p.eccentricity_mm = r.nonNegative("eccentricity_mm", p.eccentricity_mm);
  r.require(p.eccentricity_mm < p.radius_mm / 2, "eccentricity_mm", "must be < radius_mm / 2");
  p.eccentricity_phase_deg = r.number("eccentricity_phase_deg", p.eccentricity_phase_deg);
  p.source_offset_mm = r.vec3("source_offset_mm", p.source_offset_mm);
  r.require(std::hypot(p.source_offset_mm[0], p.source_offset_mm[2]) + p.eccentricity_mm <
                p.radius_mm / 2,
            "source_offset_mm", "must keep the source well inside the cylinder");
  p.elevation_min_deg = r.number("elevation_min_deg", p.elevation_min_deg);
  p.elevation_max_deg = r.number("elevation_max_deg", p.elevation_max_deg);
  r.require(p.elevation_min_deg > -90 && p.elevation_min_deg < p.elevation_max_deg &&
                p.elevation_max_deg < 90,
            "elevation_max_deg", "must satisfy -90 < elevation_min_deg < elevation_max_deg < 90");
  p.source_level = r.nonNegative("source_level", p.source_level);
  p.reference_distance_mm = r.positive("reference_distance_mm", p.reference_distance_mm);
  p.source_warmup_drop = r.nonNegative("source_warmup_drop", p.source_warmup_drop);
  r.require(p.source_warmup_drop < 0.5, "source_warmup_drop", "must be < 0.5");
  p.source_warmup_tau_s = r.positive("source_warmup_tau_s", p.source_warmup_tau_s);
  r.finish();
  validateAt(p, r);
  return p;
}

StageParams readStage(TableReader r) {
  StageParams s;
  s.full_steps_per_rev = r.integer("full_steps_per_rev", s.full_steps_per_rev);
  r.require(s.full_steps_per_rev > 0, "full_steps_per_rev", "must be > 0");
  s.microsteps = r.integer("microsteps", s.microsteps);
  r.require(s.microsteps > 0 && s.microsteps <= 1024, "microsteps", "must be in [1, 1024]");
  s.gear_ratio = r.positive("gear_ratio", s.gear_ratio);
  s.max_speed_deg_s = r.positive("max_speed_deg_s", s.max_speed_deg_s);
  s.max_accel_deg_s2 = r.positive("max_accel_deg_s2", s.max_accel_deg_s2);
  s.start_speed_deg_s = r.positive("start_speed_deg_s", s.start_speed_deg_s);
  r.require(s.start_speed_deg_s <= s.max_speed_deg_s, "start_speed_deg_s",
            "must be <= max_speed_deg_s");
  s.home_deg = r.number("home_deg", s.home_deg);
  s.home_window_deg = r.positive("home_window_deg", s.home_window_deg);
  r.require(s.home_window_deg < 180, "home_window_deg", "must be < 180");
  s.settle_amplitude_deg = r.nonNegative("settle_amplitude_deg", s.settle_amplitude_deg);
  s.settle_tau_ms = r.positive("settle_tau_ms", s.settle_tau_ms);
  s.settle_freq_hz = r.positive("settle_freq_hz", s.settle_freq_hz);
  s.initial_deg = r.number("initial_deg", s.initial_deg);
  s.backlash_deg = r.nonNegative("backlash_deg", s.backlash_deg);
  r.require(s.backlash_deg < 1, "backlash_deg", "must be < 1");
  s.home_repeatability_deg = r.nonNegative("home_repeatability_deg", s.home_repeatability_deg);
  r.require(s.home_repeatability_deg < s.home_window_deg / 4, "home_repeatability_deg",
            "must be < home_window_deg / 4");
  s.home_seed = static_cast<std::uint64_t>(r.integer("home_seed", 1));
  r.finish();
  validateAt(s, r);
  return s;
}

CameraParams readCamera(TableReader r, const CameraParams& defaults) {
  CameraParams c = defaults;
  c.name = r.string("name", "");
  r.require(!c.name.empty(), "name", "is required");
  c.width = r.integer("width", c.width);
  r.require(c.width >= 16 && c.width <= 16384, "width", "must be in [16, 16384]");
  c.height = r.integer("height", c.height);
  r.require(c.height >= 16 && c.height <= 16384, "height", "must be in [16, 16384]");
  c.fx = r.positive("fx", c.fx);
  c.fy = r.positive("fy", c.fy);
  c.cx = r.number("cx", (c.width - 1) / 2.0);
  r.require(c.cx >= 0 && c.cx <= c.width, "cx", "must lie inside the image");
  c.cy = r.number("cy", (c.height - 1) / 2.0);
  r.require(c.cy >= 0 && c.cy <= c.height, "cy", "must lie inside the image");
  c.k1 = r.number("k1", 0.0);
  r.require(std::abs(c.k1) < 2, "k1", "is implausibly large");
  c.k2 = r.number("k2", 0.0);
  r.require(std::abs(c.k2) < 10, "k2", "is implausibly large");
  const bool is_main = c.name == "main";
  const bool has_pose = r.has("position_mm") || r.has("rotation_deg") || r.has("look_at_mm");
  r.require(!(is_main && has_pose), "position_mm",
            "the main camera defines the frame and takes no pose");
  c.position_mm = r.vec3("position_mm", {0, 0, 0});
  r.require(!(r.has("rotation_deg") && r.has("look_at_mm")), "look_at_mm",
            "give rotation_deg or look_at_mm, not both");
  if (r.has("look_at_mm")) {
    const Vec3 target = toVec(r.vec3("look_at_mm", {}));
    r.require((target - toVec(c.position_mm)).norm() > 1, "look_at_mm",
              "must differ from position_mm");
    try {
      c.rotation_deg = lookAtRotationDeg(toVec(c.position_mm), target, r.number("roll_deg", 0.0));
    } catch (const std::invalid_argument& e) {
      r.fail("look_at_mm", e.what());
    }
  } else {
    r.require(!r.has("roll_deg"), "roll_deg", "needs look_at_mm");
    c.rotation_deg = r.vec3("rotation_deg", {0, 0, 0});
  }
  c.bit_depth = r.integer("bit_depth", c.bit_depth);
  r.require(c.bit_depth == 8 || c.bit_depth == 10 || c.bit_depth == 12 || c.bit_depth == 16,
            "bit_depth", "must be 8, 10, 12 or 16");
  c.exposure_us = r.positive("exposure_us", c.exposure_us);
  c.exposure_min_us = r.positive("exposure_min_us", c.exposure_min_us);
  c.exposure_max_us = r.positive("exposure_max_us", c.exposure_max_us);
  requireRange(r, c.exposure_us, {"exposure_us", "exposure_min_us", "exposure_max_us"},
               c.exposure_min_us, c.exposure_max_us);
  c.gain = r.positive("gain", c.gain);
  c.gain_min = r.positive("gain_min", c.gain_min);
  c.gain_max = r.positive("gain_max", c.gain_max);
  requireRange(r, c.gain, {"gain", "gain_min", "gain_max"}, c.gain_min, c.gain_max);
  c.full_well_e = r.positive("full_well_e", c.full_well_e);
  r.require(c.full_well_e >= 100, "full_well_e", "must be >= 100");
  c.read_noise_e = r.nonNegative("read_noise_e", c.read_noise_e);
  c.trigger_latency_us = r.nonNegative("trigger_latency_us", c.trigger_latency_us);
  c.readout_us = r.nonNegative("readout_us", c.readout_us);
  c.frame_rate_hz = r.positive("frame_rate_hz", c.frame_rate_hz);
  c.response_gamma = r.positive("response_gamma", c.response_gamma);
  r.require(c.response_gamma >= 0.2 && c.response_gamma <= 5, "response_gamma",
            "must be in [0.2, 5]");
  c.line_time_us = r.nonNegative("line_time_us", c.line_time_us);
  r.require(c.line_time_us * c.height <= 1e6, "line_time_us", "must read the frame within 1 s");
  r.finish();
  validateAt(c, r);
  return c;
}

LineConfig readLine(TableReader& parent, std::string_view key, const LineConfig& fallback) {
  const toml::table* t = parent.table(key);
  if (t == nullptr) return fallback;
  TableReader r(*t, parent.file(), parent.keyPath(key));
  LineConfig l;
  l.name = r.string("name", fallback.name);
  r.require(!l.name.empty(), "name", "must not be empty");
  l.active_low = r.boolean("active_low", false);
  r.finish();
  return l;
}

}  // namespace

HeadConfig parseHeadConfig(const toml::table& table, const std::string& file,
                           const std::string& path) {
  TableReader root(table, file, path);
  HeadConfig c = defaultHeadConfig();
  auto sub = [&](std::string_view key) -> std::optional<TableReader> {
    const toml::table* t = root.table(key);
    if (t == nullptr) return std::nullopt;
    return TableReader(*t, file, root.keyPath(key));
  };
  if (auto r = sub("projector")) c.projector = readProjector(*r);
  if (auto r = sub("stage")) c.stage = readStage(*r);
  if (auto r = sub("noise")) {
    c.noise.scale = r->nonNegative("scale", c.noise.scale);
    c.noise.reference_exposure_us =
        r->positive("reference_exposure_us", c.noise.reference_exposure_us);
    r->finish();
  }
  if (auto r = sub("render")) {
    c.render.exposure_samples = r->integer("exposure_samples", c.render.exposure_samples);
    r->require(c.render.exposure_samples >= 1 && c.render.exposure_samples <= 8, "exposure_samples",
               "must be in [1, 8]");
    c.render.board_supersample = r->integer("board_supersample", c.render.board_supersample);
    r->require(c.render.board_supersample >= 1 && c.render.board_supersample <= 8,
               "board_supersample", "must be in [1, 8]");
    c.render.threads = r->integer("threads", c.render.threads);
    r->require(c.render.threads >= 0 && c.render.threads <= 64, "threads", "must be in [0, 64]");
    c.render.pace_real_time = r->boolean("pace_real_time", c.render.pace_real_time);
    r->finish();
  }
  if (auto r = sub("faults")) {
    FaultConfig& f = c.faults;
    f.camera = r->string("camera", f.camera);
    f.drop_frames = r->integer("drop_frames", f.drop_frames);
    r->require(f.drop_frames >= 0, "drop_frames", "must be >= 0");
    f.delay_first_frame_ms = r->nonNegative("delay_first_frame_ms", f.delay_first_frame_ms);
    f.corrupt_frames = r->integer("corrupt_frames", f.corrupt_frames);
    r->require(f.corrupt_frames >= 0, "corrupt_frames", "must be >= 0");
    f.lose_steps_after = r->integer("lose_steps_after", f.lose_steps_after);
    r->require(f.lose_steps_after >= 0, "lose_steps_after", "must be >= 0");
    f.lose_steps = r->integer("lose_steps", f.lose_steps);
    r->require(f.lose_steps >= 0, "lose_steps", "must be >= 0");
    f.home_switch = r->boolean("home_switch", f.home_switch);
    r->finish();
  }
  if (const toml::table* t = root.table("lines")) {
    TableReader r(*t, file, root.keyPath("lines"));
    c.lines.step = readLine(r, "step", c.lines.step);
    c.lines.dir = readLine(r, "dir", c.lines.dir);
    c.lines.enable = readLine(r, "enable", c.lines.enable);
    c.lines.trigger = readLine(r, "trigger", c.lines.trigger);
    c.lines.light = readLine(r, "light", c.lines.light);
    c.lines.home = readLine(r, "home", c.lines.home);
    c.lines.fault = readLine(r, "fault", c.lines.fault);
    r.finish();
  }
  if (const toml::array* cams = root.array("camera")) {
    c.cameras.clear();
    int index = 0;
    for (const toml::node& n : *cams) {
      const toml::table* t = n.as_table();
      if (t == nullptr) root.fail("camera", "must be an array of tables ([[camera]])");
      TableReader r(*t, file, root.keyPath("camera") + "[" + std::to_string(index) + "]");
      c.cameras.push_back(readCamera(r, CameraParams{}));
      ++index;
    }
  }
  root.finish();
  try {
    validate(c);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(file, 0, path, e.what());
  }
  return c;
}

HeadConfig loadHeadConfig(const std::filesystem::path& file) {
  const toml::table root = parseTomlFile(file.string());
  return parseHeadConfig(root, file.string());
}

HeadConfig withResolution(HeadConfig config, int width, int height) {
  for (CameraParams& cam : config.cameras)
    cam = CameraModel(cam).scaledTo(width, height);
  return config;
}

}  // namespace cylscan::sim
