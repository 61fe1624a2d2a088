// SPDX-License-Identifier: Apache-2.0
#include "drivers/sim/head_core.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace cylscan::sim {

const char* roleName(LineRole role) {
  static constexpr const char* kNames[] = {"step",  "dir",  "enable", "trigger",
                                           "light", "home", "fault"};
  return kNames[static_cast<int>(role)];
}

HeadCore::HeadCore(HeadConfig config_in, Scene scene, std::uint64_t seed_in)
    : config((validate(config_in), std::move(config_in))),
      seed(seed_in),
      clock(config.render.pace_real_time),
      projector(config.projector),
      stage(config.stage),
      noise(seed_in),
      scene_(std::move(scene)) {
  for (const CameraParams& p : config.cameras)
    camera_models.emplace_back(p);
  geometry_.resize(camera_models.size());
  for (int i = 0; i < static_cast<int>(camera_models.size()); ++i) {
    cameras.push_back(std::make_unique<VirtualCamera>(*this, i));
  }
  light_history_.push({Nanoseconds{0}, false});
  // Faults present from power-up ([faults]).
  const FaultConfig& f = config.faults;
  VirtualCamera& faulty = *cameras[static_cast<std::size_t>(cameraIndex(f.camera))];
  faulty.dropFrames(f.drop_frames);
  faulty.delayNextFrame(Nanoseconds{std::llround(f.delay_first_frame_ms * 1e6)});
  for (int k = 0; k < f.corrupt_frames; ++k)
    faulty.corruptNextFrame();
  if (f.lose_steps > 0) {
    stage.loseStepsAfter(static_cast<std::uint64_t>(f.lose_steps_after),
                         static_cast<std::uint64_t>(f.lose_steps));
  }
  if (!f.home_switch) stage.breakHomeSwitch();
}

HeadCore::~HeadCore() = default;

const LineConfig& HeadCore::line(LineRole role) const {
  const LinesConfig& l = config.lines;
  switch (role) {
    case LineRole::Step:
      return l.step;
    case LineRole::Dir:
      return l.dir;
    case LineRole::Enable:
      return l.enable;
    case LineRole::Trigger:
      return l.trigger;
    case LineRole::Light:
      return l.light;
    case LineRole::Home:
      return l.home;
    case LineRole::Fault:
      return l.fault;
  }
  return l.fault;
}

std::optional<LineRole> HeadCore::roleOf(std::string_view name) const {
  for (int r = 0; r < kLineRoles; ++r) {
    if (line(static_cast<LineRole>(r)).name == name) return static_cast<LineRole>(r);
  }
  return std::nullopt;
}

int HeadCore::cameraIndex(std::string_view name) const {
  for (std::size_t i = 0; i < camera_models.size(); ++i) {
    if (camera_models[i].params().name == name) return static_cast<int>(i);
  }
  throw std::invalid_argument("virtual head: no camera '" + std::string(name) + "'");
}

void HeadCore::drive(LineRole role, bool active) {
  const auto r = static_cast<std::size_t>(role);
  const bool rising = active && !level[r];
  const Nanoseconds t = clock.now();
  if (active != level[r]) trace.record(role, active, t);
  level[r] = active;
  const std::uint64_t edges_before = stage.edgeCount();
  bool event = false;
  switch (role) {
    case LineRole::Step:
      if (rising) stage.stepPulse(t);
      break;
    case LineRole::Dir:
      stage.setDirection(active);
      break;
    case LineRole::Enable:
      stage.setEnabled(active, t);
      break;
    case LineRole::Trigger:
      if (rising) {
        for (auto& cam : cameras)
          event = cam->triggerEdge(t) || event;
      }
      break;
    case LineRole::Light:
      light_history_.push({t, active});
      break;
    case LineRole::Home:
    case LineRole::Fault:
      break;
  }
  // A new frame or input edge: threads waiting for one re-check.
  if (event || stage.edgeCount() != edges_before) clock.notifyEvent();
}

std::uint64_t HeadCore::lightSampleAt(Nanoseconds t) const {
  std::uint64_t lo = light_history_.oldest(), hi = light_history_.count();
  while (hi - lo > 1) {
    const std::uint64_t mid = lo + (hi - lo) / 2;
    if (light_history_.at(mid).time <= t) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return lo;
}

bool HeadCore::lightAt(Nanoseconds t) const {
  return light_history_.at(lightSampleAt(t)).on;
}

std::optional<HeadCore::Nanoseconds> HeadCore::lightOnSince(Nanoseconds t) const {
  std::uint64_t i = lightSampleAt(t);
  if (!light_history_.at(i).on) return std::nullopt;
  // Writes that left the light on are not edges: go back to the first of them.
  while (i > light_history_.oldest() && light_history_.at(i - 1).on)
    --i;
  return light_history_.at(i).time;
}

std::shared_ptr<const PixelGeometry> HeadCore::geometryFor(int camera) {
  std::lock_guard lock(scene_mutex_);
  auto& slot = geometry_[static_cast<std::size_t>(camera)];
  if (!slot) {
    TraceOptions options;
    options.threads = config.render.threads;
    const bool board = std::any_of(scene_.objects.begin(), scene_.objects.end(), [](const auto& o) {
      return std::holds_alternative<Checkerboard>(o.shape);
    });
    options.supersample = board ? config.render.board_supersample : 1;
    slot = std::make_shared<const PixelGeometry>(
        tracePixels(scene_, camera_models[static_cast<std::size_t>(camera)], projector, options));
  }
  return slot;
}

void HeadCore::setScene(Scene scene) {
  std::lock_guard lock(scene_mutex_);
  scene_ = std::move(scene);
  for (auto& g : geometry_)
    g.reset();
}

Scene HeadCore::scene() const {
  std::lock_guard lock(scene_mutex_);
  return scene_;
}

// ---- VirtualCamera ---------------------------------------------------------

VirtualCamera::VirtualCamera(HeadCore& core, int index)
    : core_(core),
      index_(index),
      params_(core.camera_models[static_cast<std::size_t>(index)].params()) {}

std::string VirtualCamera::name() const {
  return params_.name;
}

drivers::CameraControls VirtualCamera::controls() const {
  const CameraParams& model = core_.camera_models[static_cast<std::size_t>(index_)].params();
  return {{params_.exposure_us, model.exposure_min_us, model.exposure_max_us},
          {params_.gain, model.gain_min, model.gain_max}};
}

VirtualCamera::Nanoseconds VirtualCamera::exposure() const {
  return Nanoseconds{std::llround(params_.exposure_us * 1e3)};
}

VirtualCamera::Nanoseconds VirtualCamera::rolling() const {
  return Nanoseconds{std::llround(params_.line_time_us * 1e3 * (params_.height - 1))};
}

void VirtualCamera::configure(const drivers::CameraConfig& config) {
  if (started_)
    throw drivers::CameraError("camera '" + params_.name + "': configure while started");
  const CameraParams& model = core_.camera_models[static_cast<std::size_t>(index_)].params();
  if ((config.width != 0 && config.width != model.width) ||
      (config.height != 0 && config.height != model.height)) {
    throw drivers::CameraError("camera '" + params_.name + "': the sensor is " +
                               std::to_string(model.width) + "x" + std::to_string(model.height) +
                               ", cannot deliver " + std::to_string(config.width) + "x" +
                               std::to_string(config.height));
  }
  if (config.bit_depth != 8 && config.bit_depth != 10 && config.bit_depth != 12 &&
      config.bit_depth != 16) {
    throw drivers::CameraError("camera '" + params_.name + "': bit_depth " +
                               std::to_string(config.bit_depth) + " not supported (8/10/12/16)");
  }
  if (config.exposure_us < 0 || !std::isfinite(config.exposure_us)) {
    throw drivers::CameraError("camera '" + params_.name + "': exposure_us must be >= 0");
  }
  if (!(config.gain > 0) || !std::isfinite(config.gain)) {
    throw drivers::CameraError("camera '" + params_.name + "': gain must be > 0");
  }
  params_.bit_depth = config.bit_depth;
  params_.exposure_us =
      config.exposure_us > 0
          ? std::clamp(config.exposure_us, model.exposure_min_us, model.exposure_max_us)
          : model.exposure_us;
  params_.gain = std::clamp(config.gain, model.gain_min, model.gain_max);
  mode_ = config.trigger;
  stream_ = config.trigger == drivers::TriggerMode::FreeRunning ? drivers::FrameStream::Continuous
                                                                : config.stream;
  if (stream_ == drivers::FrameStream::Continuous && mode_ == drivers::TriggerMode::Software) {
    throw drivers::CameraError("camera '" + params_.name +
                               "': a software trigger delivers one frame per request, not a "
                               "continuous stream");
  }
}

void VirtualCamera::start() {
  pending_.clear();
  stream_origin_ = core_.clock.now();
  link_frame_ = -1;
  shown_.reset();
  shown_image_.release();
  started_ = true;
}

void VirtualCamera::stop() {
  started_ = false;
  pending_.clear();
  delay_ns_ = 0;  // the delay was of a frame in flight, discarded with it
}

bool VirtualCamera::expose(Nanoseconds start) {
  if (start < last_start_ + exposure()) {  // still exposing the previous frame
    ++missed_;
    return false;
  }
  if (!pending_.push({start, next_sequence_})) {
    ++missed_;
    return false;
  }
  last_start_ = start;
  ++next_sequence_;
  return true;
}

bool VirtualCamera::triggerEdge(Nanoseconds t) {
  if (!started_ || mode_ != drivers::TriggerMode::GpioPulse) return false;
  return expose(t + Nanoseconds{std::llround(params_.trigger_latency_us * 1e3)});
}

void VirtualCamera::requestFrame() {
  if (mode_ != drivers::TriggerMode::Software) {
    throw drivers::CameraError("camera '" + params_.name +
                               "': requestFrame needs TriggerMode::Software");
  }
  if (!started_) throw drivers::CameraError("camera '" + params_.name + "': not started");
  const Nanoseconds t = core_.clock.now();
  if (!expose(t + Nanoseconds{std::llround(params_.trigger_latency_us * 1e3)})) {
    throw drivers::CameraError("camera '" + params_.name + "': busy, frame request refused");
  }
  core_.clock.notifyEvent();
}

std::optional<drivers::Frame> VirtualCamera::waitLinkFrame(Nanoseconds timeout) {
  const Nanoseconds deadline = core_.clock.now() + std::max(timeout, Nanoseconds{0});
  const Nanoseconds period{std::llround(1e9 / params_.frame_rate_hz)};
  const Nanoseconds readout{std::llround(params_.readout_us * 1e3)};
  const Nanoseconds transfer = exposure() + rolling() + readout;
  for (;;) {
    // The first link frame not delivered yet.
    const Nanoseconds since = core_.clock.now() - stream_origin_ - transfer;
    std::int64_t k = since.count() <= 0 ? 0 : (since + period - Nanoseconds{1}) / period;
    k = std::max(k, link_frame_ + 1);
    const Nanoseconds start = stream_origin_ + k * period;
    const Nanoseconds ready = start + transfer + Nanoseconds{delay_ns_.load()};
    if (ready > deadline) {
      core_.clock.sleepUntil(deadline);
      return std::nullopt;
    }
    core_.clock.sleepUntil(ready);
    delay_ns_ = 0;
    link_frame_ = k;
    if (drop_ > 0) {  // never delivered: a gap in the sequence
      --drop_;
      continue;
    }
    drivers::Frame frame;
    frame.sequence = static_cast<std::uint64_t>(k);
    frame.timestamp = start;
    if (mode_ == drivers::TriggerMode::FreeRunning) {
      frame.image = renderExposure({start, frame.sequence});
    } else {
      // The latest exposure finished by the link frame's start.
      while (const std::optional<Pending> p = pending_.front()) {
        if (p->start + transfer > start) break;
        shown_ = *p;
        shown_image_.release();
        pending_.pop();
      }
      if (!shown_) {
        frame.image = cv::Mat::zeros(params_.height, params_.width,
                                     params_.bit_depth > 8 ? CV_16UC1 : CV_8UC1);
      } else {
        if (shown_image_.empty()) shown_image_ = renderExposure(*shown_);
        frame.image = shown_image_.clone();
      }
    }
    tearIfAsked(frame.image);
    return frame;
  }
}

std::optional<drivers::Frame> VirtualCamera::waitFrame(Nanoseconds timeout) {
  if (!started_) throw drivers::CameraError("camera '" + params_.name + "': not started");
  if (stream_ == drivers::FrameStream::Continuous) return waitLinkFrame(timeout);
  const Nanoseconds deadline = core_.clock.now() + std::max(timeout, Nanoseconds{0});
  const Nanoseconds readout{std::llround(params_.readout_us * 1e3)};
  for (;;) {
    // Read before looking, so a trigger in between is not missed.
    const std::uint64_t epoch = core_.clock.eventEpoch();
    const std::optional<Pending> p = pending_.front();
    if (!p) {
      if (core_.clock.now() >= deadline) return std::nullopt;
      // Nothing is coming unless another thread triggers: wait for an event
      // or the deadline (alone in virtual time: the deadline at once).
      core_.clock.waitForEvent(epoch, deadline);
      continue;
    }
    // The last row ends its exposure `rolling` after the first, then the frame is read out.
    const Nanoseconds ready =
        p->start + exposure() + rolling() + readout + Nanoseconds{delay_ns_.load()};
    if (ready > deadline) {
      core_.clock.sleepUntil(deadline);
      return std::nullopt;
    }
    core_.clock.sleepUntil(ready);
    delay_ns_ = 0;
    pending_.pop();
    if (drop_ > 0) {  // exposed, never delivered: a gap in the sequence
      --drop_;
      continue;
    }
    return render(*p);
  }
}

cv::Mat VirtualCamera::renderExposure(const Pending& p) {
  const auto geometry = core_.geometryFor(index_);
  Exposure e;
  const int n = core_.config.render.exposure_samples;
  const Nanoseconds exp = exposure();
  const Nanoseconds rolling = this->rolling();
  for (int j = 0; j < n; ++j) {
    const auto k = static_cast<std::size_t>(j);
    const Nanoseconds t = p.start + exp * (2 * j + 1) / (2 * n);
    e.stage_deg[k] = core_.stage.angleAt(t);
    e.stage_deg_last_row[k] = core_.stage.angleAt(t + rolling);
    e.light[k] = core_.lightAt(t);
  }
  e.samples = n;
  bool uniform = true;
  for (int j = 1; j < n; ++j) {
    const auto k = static_cast<std::size_t>(j);
    uniform =
        uniform && std::abs(e.stage_deg[k] - e.stage_deg[0]) < 1e-9 && e.light[k] == e.light[0];
  }
  for (int j = 0; j < n; ++j) {
    const auto k = static_cast<std::size_t>(j);
    uniform = uniform && std::abs(e.stage_deg_last_row[k] - e.stage_deg[k]) < 1e-9;
  }
  if (uniform) e.samples = 1;
  e.rolling = false;
  for (int j = 0; j < e.samples; ++j) {
    const auto k = static_cast<std::size_t>(j);
    e.rolling = e.rolling || std::abs(e.stage_deg_last_row[k] - e.stage_deg[k]) >= 1e-9;
  }
  const Nanoseconds middle = p.start + exp / 2;
  if (const std::optional<Nanoseconds> on = core_.lightOnSince(middle))
    e.source_gain =
        core_.projector.params().warmupFactor(static_cast<double>((middle - *on).count()) * 1e-9);
  e.response_gamma = params_.response_gamma;
  e.exposure_us = params_.exposure_us;
  e.reference_exposure_us = core_.config.noise.reference_exposure_us;
  e.gain = params_.gain;
  e.bit_depth = params_.bit_depth;
  e.full_well_e = params_.full_well_e;
  e.read_noise_e = params_.read_noise_e;
  e.noise_scale = core_.config.noise.scale;
  e.noise_key =
      mixBits(core_.seed ^ mixBits((static_cast<std::uint64_t>(index_) << 48) ^ p.sequence));
  return renderFrame(*geometry, core_.projector, e, core_.noise, core_.config.render.threads);
}

drivers::Frame VirtualCamera::render(const Pending& p) {
  drivers::Frame frame;
  frame.image = renderExposure(p);
  frame.sequence = p.sequence;
  frame.timestamp = p.start;
  tearIfAsked(frame.image);
  return frame;
}

void VirtualCamera::tearIfAsked(cv::Mat& image) {
  if (corrupt_ <= 0) return;
  --corrupt_;  // a torn transfer: the lower half of the frame is garbage
  cv::Mat lower = image.rowRange(image.rows / 2, image.rows);
  cv::randu(lower, 0, image.depth() == CV_8U ? 256 : 4096);
}

}  // namespace cylscan::sim
