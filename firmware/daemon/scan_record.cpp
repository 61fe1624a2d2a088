// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/scan_record.hpp"

#include <cxxabi.h>

#include <algorithm>
#include <cstdlib>
#include <memory>
#include <type_traits>
#include <typeinfo>
#include <utility>

#include "firmware/peak_memory.hpp"

namespace cylscan::firmware {
namespace {

using nlohmann::json;

double microseconds(std::chrono::nanoseconds t) {
  return static_cast<double>(t.count()) / 1e3;
}

json jitterJson(const JitterFigures& f) {
  return {{"count", f.count}, {"p50_us", f.p50_us}, {"p99_us", f.p99_us}, {"max_us", f.max_us}};
}

json cameraJson(const CameraOutput& c) {
  json j = {{"camera", c.camera}, {"calibrated", c.calibrated}, {"points", c.points}};
  if (c.calibrated) {
    j["phase"] = toString(c.phase);
    j["phase_valid_fraction"] = c.phase_valid_fraction;
    j["file"] = c.file;
  }
  return j;
}

// `v` as a T when it is one (integers within T's range), else nullopt.
template <typename T>
std::optional<T> valueAs(const json& v) {
  if constexpr (std::is_same_v<T, bool>) {
    if (v.is_boolean()) return v.get<bool>();
  } else if constexpr (std::is_integral_v<T>) {
    if (v.is_number_unsigned()) {
      const auto u = v.get<std::uint64_t>();
      if (std::in_range<T>(u)) return static_cast<T>(u);
    } else if (v.is_number_integer()) {
      const auto i = v.get<std::int64_t>();
      if (std::in_range<T>(i)) return static_cast<T>(i);
    }
  } else if constexpr (std::is_floating_point_v<T>) {
    if (v.is_number()) return v.get<T>();
  } else if constexpr (std::is_same_v<T, std::string>) {
    if (v.is_string()) return v.get<std::string>();
  } else {
    static_assert(std::is_same_v<T, std::vector<std::string>>);
    if (v.is_array() &&
        std::all_of(v.begin(), v.end(), [](const json& e) { return e.is_string(); }))
      return v.get<std::vector<std::string>>();
  }
  return std::nullopt;
}

// The fields of one JSON object, each read with its type checked;
// ScanRecordError naming the field (its path from the record) otherwise.
class Fields {
 public:
  Fields(const json& object, std::string path) : object_(object), path_(std::move(path)) {
    if (!object_.is_object()) throw ScanRecordError(where() + "is not a JSON object");
  }

  bool has(const char* key) const { return object_.contains(key); }
  const json& at(const char* key) const { return object_.at(key); }
  std::string name(const char* key) const { return path_.empty() ? key : path_ + "." + key; }

  template <typename T>
  T required(const char* key) const {
    if (!has(key)) throw ScanRecordError(name(key) + ": missing");
    return get<T>(key);
  }
  // Left as it is when absent.
  template <typename T>
  void read(const char* key, T& out) const {
    if (has(key)) out = get<T>(key);
  }
  // Absent or null: nullopt.
  template <typename T>
  void read(const char* key, std::optional<T>& out) const {
    if (has(key) && !at(key).is_null()) out = get<T>(key);
  }

 private:
  template <typename T>
  T get(const char* key) const {
    std::optional<T> v = valueAs<T>(at(key));
    if (!v) throw ScanRecordError(name(key) + ": wrong type or out of range");
    return std::move(*v);
  }
  std::string where() const { return path_.empty() ? "" : path_ + ": "; }

  const json& object_;
  std::string path_;
};

ScanState parseState(const std::string& name) {
  for (ScanState s :
       {ScanState::kQueued, ScanState::kRunning, ScanState::kDone, ScanState::kFailed})
    if (toString(s) == name) return s;
  throw ScanRecordError("state: '" + name + "' is not queued, running, done or failed");
}

// `parse` of the field's string, its std::invalid_argument as ScanRecordError.
template <typename Parse>
auto parsed(const Fields& f, const char* key, Parse parse) {
  try {
    return parse(f.required<std::string>(key));
  } catch (const std::invalid_argument& e) {
    throw ScanRecordError(f.name(key) + ": " + e.what());
  }
}

JitterFigures jitterFrom(const Fields& f) {
  JitterFigures j;
  f.read("count", j.count);
  f.read("p50_us", j.p50_us);
  f.read("p99_us", j.p99_us);
  f.read("max_us", j.max_us);
  return j;
}

CameraOutput cameraFrom(const Fields& f) {
  CameraOutput c;
  c.camera = f.required<std::string>("camera");
  f.read("calibrated", c.calibrated);
  f.read("points", c.points);
  if (f.has("phase")) c.phase = parsed(f, "phase", parsePhaseSource);
  f.read("phase_valid_fraction", c.phase_valid_fraction);
  f.read("file", c.file);
  return c;
}

algo::OrderResidual residualFrom(const Fields& f) {
  algo::OrderResidual r;
  f.read("centre_rad", r.centre_rad);
  f.read("spread_rad", r.spread_rad);
  f.read("bound_rad", r.bound_rad);
  f.read("samples", r.samples);
  f.read("decided_by_neighbours", r.decided_by_neighbours);
  return r;
}

OutputFigures outputFrom(const Fields& f) {
  OutputFigures o;
  if (f.has("phase")) o.phase = parsed(f, "phase", parsePhaseSource);
  f.read("phase_valid_fraction", o.phase_valid_fraction);
  if (f.has("order_residual"))
    o.order_residual = residualFrom(Fields(f.at("order_residual"), "order_residual"));
  f.read("points", o.points);
  if (f.has("cameras") || f.has("cloud")) {
    RingOutput ring;
    if (f.has("cameras")) {
      const json& cameras = f.at("cameras");
      if (!cameras.is_array()) throw ScanRecordError("cameras: not an array");
      for (std::size_t i = 0; i < cameras.size(); ++i)
        ring.cameras.push_back(
            cameraFrom(Fields(cameras[i], "cameras[" + std::to_string(i) + "]")));
    }
    if (f.has("cloud")) ring.cloud = parsed(f, "cloud", parseMergedCloud);
    f.read("cloud_note", ring.cloud_note);
    o.ring = std::move(ring);
  }
  return o;
}

AcquisitionFigures acquisitionFrom(const Fields& f) {
  AcquisitionFigures a;
  f.read("retries", a.retries);
  f.read("homed", a.homed);
  f.read("realtime", a.realtime);
  f.read("board_seconds", a.board_seconds);
  f.read("warnings", a.warnings);
  if (f.has("step_jitter")) a.step_jitter = jitterFrom(Fields(f.at("step_jitter"), "step_jitter"));
  f.read("step_reramps", a.step_reramps);
  if (f.has("trigger_jitter"))
    a.trigger_jitter = jitterFrom(Fields(f.at("trigger_jitter"), "trigger_jitter"));
  if (f.has("board_seconds_split")) {
    const Fields split(f.at("board_seconds_split"), "board_seconds_split");
    for (const char* part : {"homing", "travel", "sets", "settling", "step_check"}) {
      double seconds = 0;
      split.read(part, seconds);
      a.time_split_s[part] = seconds;
    }
  }
  if (f.has("step_check")) {
    const Fields c(f.at("step_check"), "step_check");
    drivers::StepCheck check;
    c.read("expected_edge", check.expected_edge);
    c.read("found_edge", check.found_edge);
    c.read("passed", check.passed);
    a.step_check = check;
  }
  f.read("peak_resident_bytes", a.peak_resident_bytes);
  return a;
}

std::string typeName(const std::type_info& type) {
  int status = 0;
  const std::unique_ptr<char, decltype(&std::free)> name(
      abi::__cxa_demangle(type.name(), nullptr, nullptr, &status), &std::free);
  return status == 0 && name ? name.get() : type.name();
}

}  // namespace

std::string toString(ScanState state) {
  switch (state) {
    case ScanState::kQueued:
      return "queued";
    case ScanState::kRunning:
      return "running";
    case ScanState::kDone:
      return "done";
    case ScanState::kFailed:
      return "failed";
  }
  return "failed";
}

JitterFigures jitterFigures(const drivers::JitterStats::Snapshot& s) {
  return {s.count, microseconds(s.p50), microseconds(s.p99), microseconds(s.max)};
}

AcquisitionFigures acquisitionFigures(const ScanReport& report) {
  AcquisitionFigures a;
  a.time_split_s = timeSplitSeconds(report.split);
  a.step_check = report.step_check;
  a.peak_resident_bytes = peakResidentBytes();
  a.retries = report.retries;
  a.homed = report.homed;
  a.realtime = report.realtime;
  a.board_seconds = static_cast<double>(report.duration.count()) / 1e9;
  a.warnings = report.warnings;
  a.step_jitter = jitterFigures(report.step_jitter);
  a.step_reramps = report.step_reramps;
  a.trigger_jitter = jitterFigures(report.trigger_jitter);
  return a;
}

void to_json(json& j, const ScanRecord& r) {
  j = {{"id", r.id},
       {"state", toString(r.state)},
       {"progress", r.progress},
       {"created", r.created},
       {"finished", r.finished ? json(*r.finished) : json(nullptr)},
       {"duration_s", r.duration_s ? json(*r.duration_s) : json(nullptr)},
       {"options", r.options},
       {"frames", r.frames},
       {"frames_done", r.frames_done},
       {"files", r.files},
       {"calibrated", r.calibrated}};
  if (r.error) j["error"] = *r.error;
  if (r.output) {
    j["phase"] = toString(r.output->phase);
    j["phase_valid_fraction"] = r.output->phase_valid_fraction;
    j["order_residual"] = orderResidualJson(r.output->order_residual);
    if (r.output->points) j["points"] = *r.output->points;
    if (const auto& ring = r.output->ring) {
      json cameras = json::array();
      for (const CameraOutput& c : ring->cameras)
        cameras.push_back(cameraJson(c));
      j["cameras"] = std::move(cameras);
      j["cloud"] = toString(ring->cloud);
      if (!ring->cloud_note.empty()) j["cloud_note"] = ring->cloud_note;
    }
  }
  if (const auto& a = r.acquisition) {
    j["retries"] = a->retries;
    j["homed"] = a->homed;
    j["realtime"] = a->realtime;
    j["board_seconds"] = a->board_seconds;
    j["warnings"] = a->warnings;
    j["step_jitter"] = jitterJson(a->step_jitter);
    j["step_reramps"] = a->step_reramps;
    j["trigger_jitter"] = jitterJson(a->trigger_jitter);
    if (!a->time_split_s.empty()) j["board_seconds_split"] = a->time_split_s;
    if (a->step_check) {
      j["step_check"] = {{"expected_edge", a->step_check->expected_edge},
                         {"found_edge", a->step_check->found_edge},
                         {"lost_steps", a->step_check->lostSteps()},
                         {"passed", a->step_check->passed}};
    }
    if (a->peak_resident_bytes > 0) j["peak_resident_bytes"] = a->peak_resident_bytes;
  }
  if (r.bundle) j["bundle"] = *r.bundle;
}

void from_json(const json& j, ScanRecord& record) {
  const Fields f(j, "");
  ScanRecord r;
  r.id = f.required<std::string>("id");
  r.state = parseState(f.required<std::string>("state"));
  r.created = f.required<std::string>("created");
  f.read("progress", r.progress);
  f.read("finished", r.finished);
  f.read("duration_s", r.duration_s);
  if (f.has("options")) {
    if (!f.at("options").is_object()) throw ScanRecordError("options: not a JSON object");
    r.options = f.at("options");
  }
  f.read("frames", r.frames);
  f.read("frames_done", r.frames_done);
  f.read("calibrated", r.calibrated);
  f.read("files", r.files);
  f.read("error", r.error);
  if (r.state == ScanState::kDone) {
    r.output = outputFrom(f);
    r.acquisition = acquisitionFrom(f);
    f.read("bundle", r.bundle);
  }
  record = std::move(r);
}

std::string failureText(const std::exception_ptr& failure) {
  try {
    if (failure) std::rethrow_exception(failure);
    return "internal error: the scan failed without an exception";
  } catch (const std::exception& e) {
    std::string message = e.what();
    if (message.find_first_not_of(" \t\r\n") != std::string::npos) return message;
    return "internal error: " + typeName(typeid(e)) + " without a message";
  } catch (...) {
    return "internal error: an exception that is not a std::exception";
  }
}

}  // namespace cylscan::firmware
