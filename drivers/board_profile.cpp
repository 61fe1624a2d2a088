// SPDX-License-Identifier: Apache-2.0
#include "drivers/board_profile.hpp"

#include <array>
#include <cmath>
#include <set>
#include <stdexcept>

#include "drivers/toml_reader.hpp"

namespace cylscan::drivers {

namespace {

namespace fs = std::filesystem;

constexpr std::string_view kTriggerKey = "trigger";

bool isTriggerKey(std::string_view key) {
  return key == kTriggerKey || (key.size() > kTriggerKey.size() + 1 &&
                                key.substr(0, kTriggerKey.size() + 1) == "trigger_");
}

// A line: { name = "GPIO17" } or { chip = "gpiochip0", offset = 17 }, with active_low.
LineSpec readLine(TableReader& parent, std::string_view key) {
  const toml::table* t = parent.table(key);
  if (t == nullptr) parent.fail(key, "is required");
  TableReader r(*t, parent.file(), parent.keyPath(key));
  LineSpec spec;
  spec.role = std::string(key);
  spec.name = r.string("name", "");
  spec.chip = r.string("chip", "");
  spec.offset = r.integer("offset", -1);
  spec.active_low = r.boolean("active_low", false);
  const bool by_name = r.has("name");
  const bool by_chip = r.has("chip") || r.has("offset");
  r.require(by_name || by_chip, "name", "give the line's name, or its chip and offset");
  r.require(!(by_name && by_chip), r.has("chip") ? "chip" : "offset",
            "give the line's name, or its chip and offset, not both");
  if (by_name) r.require(!spec.name.empty(), "name", "must not be empty");
  if (by_chip) {
    r.require(r.has("chip") && !spec.chip.empty(), "chip",
              "is required with offset (\"gpiochip0\", \"/dev/gpiochip0\" or a chip label)");
    r.require(r.has("offset"), "offset", "is required with chip");
    r.require(spec.offset >= 0, "offset", "must be >= 0");
  }
  r.finish();
  return spec;
}

std::string lineKey(const LineSpec& s) {
  return s.name.empty() ? s.chip + ":" + std::to_string(s.offset) : s.name;
}

GpioProfile readGpio(TableReader r, const toml::table& table) {
  GpioProfile g;
  g.step = readLine(r, "step");
  g.dir = readLine(r, "dir");
  g.enable = readLine(r, "enable");
  g.light = readLine(r, "light");
  g.home = readLine(r, "home");
  if (r.has("fault")) g.fault = readLine(r, "fault");
  for (const auto& [k, v] : table) {
    if (isTriggerKey(k.str())) g.triggers.emplace(std::string(k.str()), readLine(r, k.str()));
  }
  r.finish();  // any other key is unknown

  // No line twice (by name, or by chip and offset as written).
  std::map<std::string, std::string> seen;
  std::vector<const LineSpec*> all{&g.step, &g.dir, &g.enable, &g.light, &g.home};
  if (g.fault) all.push_back(&*g.fault);
  for (const auto& [k, spec] : g.triggers)
    all.push_back(&spec);
  for (const LineSpec* s : all) {
    const auto [it, fresh] = seen.emplace(lineKey(*s), s->role);
    r.require(fresh, s->role, "is the same line as " + it->second + " (" + it->first + ")");
  }
  return g;
}

StageConfig readStage(TableReader r) {
  StageConfig s;
  s.full_steps_per_rev = r.integer("full_steps_per_rev", s.full_steps_per_rev);
  r.require(s.full_steps_per_rev > 0, "full_steps_per_rev", "must be > 0");
  s.microsteps = r.integer("microsteps", s.microsteps);
  r.require(s.microsteps >= 1 && s.microsteps <= 1024, "microsteps", "must be in [1, 1024]");
  s.gear_ratio = r.positive("gear_ratio", s.gear_ratio);
  s.max_speed_deg_s = r.positive("max_speed_deg_s", s.max_speed_deg_s);
  s.accel_deg_s2 = r.positive("accel_deg_s2", s.accel_deg_s2);
  s.start_speed_deg_s = r.positive("start_speed_deg_s", s.start_speed_deg_s);
  r.require(s.start_speed_deg_s <= s.max_speed_deg_s, "start_speed_deg_s",
            "must be <= max_speed_deg_s");
  s.step_pulse_us = r.positive("step_pulse_us", s.step_pulse_us);
  const double period_us = 1e6 / (s.max_speed_deg_s * s.stepsPerDeg());
  r.require(2 * s.step_pulse_us <= period_us, "step_pulse_us",
            "a step period at max_speed_deg_s is " + std::to_string(period_us) +
                " µs: too short for a pulse of this width and a gap as long");
  s.dir_setup_us = r.nonNegative("dir_setup_us", s.dir_setup_us);
  s.enable_settle_ms = r.nonNegative("enable_settle_ms", s.enable_settle_ms);
  s.settle_ms = r.nonNegative("settle_ms", s.settle_ms);
  s.home_direction = r.integer("home_direction", s.home_direction);
  r.require(s.home_direction == 1 || s.home_direction == -1, "home_direction", "must be +1 or -1");
  s.home_seek_speed_deg_s = r.positive("home_seek_speed_deg_s", s.home_seek_speed_deg_s);
  r.require(s.home_seek_speed_deg_s <= s.max_speed_deg_s, "home_seek_speed_deg_s",
            "must be <= max_speed_deg_s");
  s.home_approach_speed_deg_s =
      r.positive("home_approach_speed_deg_s", s.home_approach_speed_deg_s);
  r.require(s.home_approach_speed_deg_s <= s.home_seek_speed_deg_s, "home_approach_speed_deg_s",
            "must be <= home_seek_speed_deg_s");
  s.home_backoff_deg = r.nonNegative("home_backoff_deg", s.home_backoff_deg);
  s.home_max_travel_deg = r.positive("home_max_travel_deg", s.home_max_travel_deg);
  s.home_offset_deg = r.number("home_offset_deg", s.home_offset_deg);
  s.step_check_tolerance_steps =
      r.integer("step_check_tolerance_steps", s.step_check_tolerance_steps);
  r.require(s.step_check_tolerance_steps >= 0, "step_check_tolerance_steps", "must be >= 0");
  r.finish();
  return s;
}

CameraProfile readCamera(TableReader r, const GpioProfile& gpio) {
  CameraProfile c;
  c.name = r.string("name", "");
  r.require(!c.name.empty(), "name", "is required");
  r.require(isCameraName(c.name), "name",
            "'" + c.name + "' is not a camera name (" + std::string(kCameraNameRule) + ")");
  const std::string backend = r.string("backend", "");
  if (backend == "sim") {
    r.require(virtualHeadBuilt(), "backend",
              "\"sim\" is a camera of the virtual head, and " + std::string(kNoVirtualHead));
    c.backend = CameraBackendKind::Sim;
  } else if (backend == "v4l2") {
    c.backend = CameraBackendKind::V4l2;
  } else if (backend == "libcamera") {
    c.backend = CameraBackendKind::Libcamera;
  } else {
    r.fail("backend", backend.empty() ? "is required (\"sim\", \"v4l2\" or \"libcamera\")"
                                      : "unknown backend '" + backend +
                                            "' (\"sim\", \"v4l2\" or \"libcamera\")");
  }
  c.device = r.string("device", c.backend == CameraBackendKind::Sim ? c.name : "");
  r.require(!c.device.empty(), "device",
            c.backend == CameraBackendKind::V4l2
                ? "is required (the video device, e.g. \"/dev/video0\")"
                : "is required (the libcamera camera id, or its index \"0\")");
  c.config.width = r.integer("width", 0);
  r.require(c.config.width >= 0 && c.config.width <= 16384, "width",
            "must be in [0, 16384] (0: the camera's default)");
  c.config.height = r.integer("height", 0);
  r.require(c.config.height >= 0 && c.config.height <= 16384, "height",
            "must be in [0, 16384] (0: the camera's default)");
  r.require((c.config.width == 0) == (c.config.height == 0), "height",
            "give width and height together");
  c.config.bit_depth = r.integer("bit_depth", 8);
  r.require(c.config.bit_depth == 8 || c.config.bit_depth == 10 || c.config.bit_depth == 12 ||
                c.config.bit_depth == 16,
            "bit_depth", "must be 8, 10, 12 or 16");
  c.config.exposure_us = r.nonNegative("exposure_us", 0.0);
  c.config.gain = r.positive("gain", 1.0);
  c.frame_rate_hz = r.positive("frame_rate_hz", c.frame_rate_hz);
  if (r.has("azimuth_deg")) {
    const std::array<double, 2> a = r.vec2("azimuth_deg", {0, 0});
    r.require(std::isfinite(a[0]) && std::isfinite(a[1]) && a[0] < a[1] && a[1] - a[0] < 360,
              "azimuth_deg", "must be [lo, hi] with lo < hi and hi - lo < 360");
    c.azimuth_deg = a;
  }
  const std::string trigger = r.string("trigger", "gpio");
  if (trigger == "gpio") {
    c.config.trigger = TriggerMode::GpioPulse;
  } else if (trigger == "software") {
    c.config.trigger = TriggerMode::Software;
  } else if (trigger == "free") {
    c.config.trigger = TriggerMode::FreeRunning;
  } else {
    r.fail("trigger", "unknown trigger '" + trigger + "' (\"gpio\", \"software\" or \"free\")");
  }
  r.require(!(c.backend == CameraBackendKind::V4l2 && c.config.trigger == TriggerMode::Software),
            "trigger", "V4L2 has no software trigger: use \"gpio\" or \"free\"");
  if (c.config.trigger == TriggerMode::GpioPulse) {
    c.trigger_line = r.string("trigger_line", std::string(kTriggerKey));
    if (!gpio.triggers.contains(c.trigger_line)) {
      std::string have;
      for (const auto& [k, v] : gpio.triggers)
        have += (have.empty() ? "" : ", ") + k;
      r.fail("trigger_line", "'" + c.trigger_line + "' is not a trigger line in [gpio] (" +
                                 (have.empty() ? std::string("it has none") : "it has " + have) +
                                 ")");
    }
    c.trigger_pulse_us = r.positive("trigger_pulse_us", c.trigger_pulse_us);
  } else {
    r.require(!r.has("trigger_line"), "trigger_line", "only with trigger = \"gpio\"");
    r.require(!r.has("trigger_pulse_us"), "trigger_pulse_us", "only with trigger = \"gpio\"");
  }
  const bool free_running = c.config.trigger == TriggerMode::FreeRunning;
  const std::string stream = r.string("stream", free_running ? "continuous" : "per-exposure");
  if (stream == "per-exposure") {
    r.require(!free_running, "stream",
              "a free-running camera streams continuously: leave it out or use \"continuous\"");
    c.config.stream = FrameStream::PerExposure;
  } else if (stream == "continuous") {
    r.require(c.config.trigger != TriggerMode::Software, "stream",
              "\"continuous\" needs trigger = \"gpio\" or \"free\" (a software trigger "
              "requests one frame)");
    c.config.stream = FrameStream::Continuous;
  } else {
    r.fail("stream", "unknown stream '" + stream + "' (\"per-exposure\" or \"continuous\")");
  }
  c.image_latency_ms = r.nonNegative("image_latency_ms", 0.0);
  r.require(c.image_latency_ms <= 60000, "image_latency_ms", "must be at most 60000");
  r.require(!r.has("image_latency_ms") || c.config.stream == FrameStream::Continuous,
            "image_latency_ms", "only with stream = \"continuous\"");
  r.finish();
  return c;
}

fs::path existingFile(TableReader& r, std::string_view key, const fs::path& dir) {
  fs::path p = dir / r.string(key, "");
  std::error_code ec;
  r.require(fs::is_regular_file(p, ec), key, "no such file: " + p.string());
  return p;
}

}  // namespace

std::string_view toString(CameraBackendKind backend) {
  switch (backend) {
    case CameraBackendKind::Sim:
      return "sim";
    case CameraBackendKind::V4l2:
      return "v4l2";
    case CameraBackendKind::Libcamera:
      return "libcamera";
  }
  return "?";
}

std::string_view toString(TriggerMode trigger) {
  switch (trigger) {
    case TriggerMode::GpioPulse:
      return "gpio";
    case TriggerMode::Software:
      return "software";
    case TriggerMode::FreeRunning:
      return "free";
  }
  return "?";
}

std::string_view toString(FrameStream stream) {
  return stream == FrameStream::PerExposure ? "per-exposure" : "continuous";
}

const toml::table& BoardProfile::scanTable() const {
  static const toml::table kNone;
  if (document == nullptr) return kNone;
  const toml::table* scan = (*document)["scan"].as_table();
  return scan != nullptr ? *scan : kNone;
}

const CameraProfile& BoardProfile::camera(std::string_view camera_name) const {
  for (const CameraProfile& c : cameras) {
    if (c.name == camera_name) return c;
  }
  throw std::invalid_argument("board '" + name + "': no camera '" + std::string(camera_name) + "'");
}

BoardProfile parseBoardProfile(toml::table parsed, const fs::path& file) {
  const std::string f = file.string();
  const fs::path dir = file.parent_path();
  BoardProfile b;
  b.document = std::make_shared<const toml::table>(std::move(parsed));
  const toml::table& table = *b.document;
  TableReader root(table, f, "");
  b.file = file;

  const toml::table* board = root.table("board");
  if (board == nullptr) root.fail("board", "is required (name, description)");
  {
    TableReader r(*board, f, "board");
    b.name = r.string("name", "");
    r.require(!b.name.empty(), "name", "is required");
    b.description = r.string("description", "");
    r.finish();
  }

  const toml::table* gpio = root.table("gpio");
  if (gpio == nullptr) root.fail("gpio", "is required (step, dir, enable, light, home, ...)");
  b.gpio = readGpio(TableReader(*gpio, f, "gpio"), *gpio);

  if (const toml::table* t = root.table("stage")) b.stage = readStage(TableReader(*t, f, "stage"));

  const toml::array* cams = root.array("camera");
  if (cams == nullptr || cams->empty()) {
    root.fail("camera", "is required: [[camera]] tables, \"main\" first");
  }
  std::set<std::string> names;
  for (std::size_t i = 0; i < cams->size(); ++i) {
    const toml::table* t = cams->get(i)->as_table();
    if (t == nullptr) root.fail("camera", "must be an array of tables ([[camera]])");
    TableReader r(*t, f, "camera[" + std::to_string(i) + "]");
    CameraProfile c = readCamera(r, b.gpio);
    r.require(i != 0 || c.name == "main", "name", "the first camera must be \"main\"");
    r.require(names.insert(c.name).second, "name", "camera '" + c.name + "' twice");
    b.cameras.push_back(std::move(c));
  }

  (void)root.table("scan");  // the firmware's (scanTable)

  if (const toml::table* t = root.table("sim")) {
    root.require(virtualHeadBuilt(), "sim",
                 "describes a virtual head, and " + std::string(kNoVirtualHead));
    TableReader r(*t, f, "sim");
    SimProfile s;
    const toml::node* head = t->get("head");
    r.require(head != nullptr, "head",
              "is required: a head file (\"head.toml\") or the head's tables ([sim.head])");
    if (head->is_table()) {
      s.head = sim::parseHeadConfig(*r.table("head"), f, "sim.head");
    } else if (head->is_string()) {
      s.head_file = existingFile(r, "head", dir);
      s.head = sim::loadHeadConfig(s.head_file);
    } else {
      r.fail("head", "must be a file name or a table");
    }
    if (r.has("scene")) s.scene = existingFile(r, "scene", dir);
    if (r.has("resolution")) {
      // The head's cameras at another resolution with the same fields of view
      // (a quick head for tests and previews).
      const std::array<double, 2> size = r.vec2("resolution", {0, 0});
      r.require(size[0] >= 16 && size[0] <= 8192 && size[1] >= 16 && size[1] <= 8192 &&
                    size[0] == std::floor(size[0]) && size[1] == std::floor(size[1]),
                "resolution", "must be [width, height], whole numbers in [16, 8192]");
      s.head = sim::withResolution(s.head, static_cast<int>(size[0]), static_cast<int>(size[1]));
    }
    const int seed = r.integer("seed", 1);
    r.require(seed >= 0, "seed", "must be >= 0");
    s.seed = static_cast<std::uint64_t>(seed);
    r.finish();
    b.sim = std::move(s);
  }
  root.finish();

  // The cameras and [sim] agree: a board drives the virtual head or hardware.
  for (std::size_t i = 0; i < b.cameras.size(); ++i) {
    const CameraProfile& c = b.cameras[i];
    TableReader r(*cams->get(i)->as_table(), f, "camera[" + std::to_string(i) + "]");
    if (!b.sim) {
      r.require(c.backend != CameraBackendKind::Sim, "backend",
                "\"sim\" needs the virtual head: a [sim] section");
      continue;
    }
    r.require(c.backend == CameraBackendKind::Sim, "backend",
              "a board with [sim] drives the virtual head: its cameras are \"sim\"");
    const sim::CameraParams* model = nullptr;
    for (const sim::CameraParams& p : b.sim->head.cameras) {
      if (p.name == c.device) model = &p;
    }
    r.require(model != nullptr, "device", "the virtual head has no camera '" + c.device + "'");
    r.require(
        c.config.width == 0 || (c.config.width == model->width && c.config.height == model->height),
        "width",
        "the virtual head's camera '" + c.device + "' is " + std::to_string(model->width) + "x" +
            std::to_string(model->height));
  }
  return b;
}

BoardProfile loadBoardProfile(const fs::path& dir_or_file) {
  std::error_code ec;
  const fs::path file =
      fs::is_directory(dir_or_file, ec) ? dir_or_file / "board.toml" : dir_or_file;
  return parseBoardProfile(parseTomlFile(file.string()), file);
}

}  // namespace cylscan::drivers
