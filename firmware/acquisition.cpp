// SPDX-License-Identifier: Apache-2.0
#include "firmware/acquisition.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>

#include "drivers/realtime_thread.hpp"

namespace cylscan::firmware {
namespace {

using std::chrono::nanoseconds;

// How often a thread waiting for the other looks again. A frame comes at the
// earliest exposure + readout after its trigger (milliseconds), so 1 ms loses
// nothing, and on the virtual head's clock fewer polls are fewer wake-ups.
constexpr nanoseconds kPoll = std::chrono::milliseconds(1);
// The capture side waits for the stage (a move, homing, the step check) with
// polls that grow to this: a 180° travel is seconds of waiting, thousands of
// 1 ms wake-ups. Its frames wait in the cameras' queues, and the motion
// thread announces each stop-and-go trigger when the stage arrives, so a
// longer poll delays nothing.
constexpr nanoseconds kPollMax = std::chrono::milliseconds(4);

nanoseconds us(double value) {
  return nanoseconds{std::llround(value * 1e3)};
}

// "3000", "2.5": a setting as its profile would write it.
std::string number(double value) {
  std::ostringstream s;
  s << value;
  return s.str();
}

// Turns the light off and disables the stage however the scan ends.
class SafeState {
 public:
  SafeState(drivers::RotationStage& stage, drivers::OutputLine& light)
      : stage_(stage), light_(light) {}
  ~SafeState() {
    light_.set(false);
    stage_.disable();
  }
  SafeState(const SafeState&) = delete;
  SafeState& operator=(const SafeState&) = delete;

 private:
  drivers::RotationStage& stage_;
  drivers::OutputLine& light_;
};

// An output line that remembers the level it was last set to (one relaxed
// atomic store: still no allocation, no lock on the real-time path).
class MonitoredLine final : public drivers::OutputLine {
 public:
  MonitoredLine(std::unique_ptr<drivers::OutputLine> line, bool initial, std::atomic<bool>& level)
      : line_(std::move(line)), level_(level) {
    level_.store(initial, std::memory_order_relaxed);
  }
  void set(bool active) override {
    line_->set(active);
    level_.store(active, std::memory_order_relaxed);
  }

 private:
  std::unique_ptr<drivers::OutputLine> line_;
  std::atomic<bool>& level_;
};

bool sameLine(const drivers::LineSpec& a, const drivers::LineSpec& b) {
  return a.name == b.name && a.chip == b.chip && a.offset == b.offset;
}

// The board's GPIO with one output line monitored (the stage driver's enable
// line, which drivers::RotationStage requests itself).
class MonitoringGpio final : public drivers::GpioBackend {
 public:
  MonitoringGpio(drivers::GpioBackend& gpio, drivers::LineSpec watched, std::atomic<bool>& level)
      : gpio_(gpio), watched_(std::move(watched)), level_(level) {}
  std::unique_ptr<drivers::OutputLine> requestOutput(const drivers::LineSpec& spec,
                                                     bool initial_active) override {
    auto line = gpio_.requestOutput(spec, initial_active);
    if (!sameLine(spec, watched_)) return line;
    return std::make_unique<MonitoredLine>(std::move(line), initial_active, level_);
  }
  std::unique_ptr<drivers::InputLine> requestInput(const drivers::LineSpec& spec) override {
    return gpio_.requestInput(spec);
  }

 private:
  drivers::GpioBackend& gpio_;
  drivers::LineSpec watched_;
  std::atomic<bool>& level_;
};

// Stops the cameras of a scan however it ends.
class RunningCameras {
 public:
  RunningCameras(drivers::Board& board, const std::vector<std::string>& names) {
    for (const auto& name : names) {
      drivers::Camera& camera = board.camera(name);
      camera.start();
      cameras_.push_back(&camera);
    }
  }
  ~RunningCameras() {
    for (drivers::Camera* camera : cameras_) {
      try {
        camera->stop();
      } catch (...) {  // a camera that cannot stop must not hide the scan's own error
      }
    }
  }
  RunningCameras(const RunningCameras&) = delete;
  RunningCameras& operator=(const RunningCameras&) = delete;

 private:
  std::vector<drivers::Camera*> cameras_;
};

// Continuous mode: the sweep of one motion set, always upwards so that the
// backlash is taken up the same way for every frame of every scan.
drivers::SweepRequest sweepRequest(const ScanOptions& options, const SetPlan& set,
                                   const drivers::StageConfig& stage) {
  const int n = static_cast<int>(set.positions.size());
  drivers::SweepRequest request;
  request.direction = 1;
  // One frame step per frame period: the set's own step (θ/N for a sets
  // plan; a ring plan's common Δ, which differs from θ/N), unless that is
  // faster than the stage may turn. The cameras are triggered (run() refuses
  // free-running ones), so a slower sweep only triggers them less often.
  const double frame_step_deg = set.step_deg > 0 ? set.step_deg : set.period_deg / n;
  request.speed_deg_s =
      options.sweep_speed_deg_s > 0
          ? options.sweep_speed_deg_s
          : std::min(frame_step_deg * options.frame_rate_hz, stage.max_speed_deg_s);
  request.range_steps = set.positions.back() - set.positions.front();
  for (const auto p : set.positions)
    request.trigger_offsets.push_back(p - set.positions.front());
  request.trigger_pulse_us = options.trigger_pulse_us;
  request.trigger_lead_us = options.exposure_us / 2;  // the exposure centred on the step
  return request;
}

// Where the stage is when a motion set begins (its first frame, or its
// sweep's run-up) and when it ends (its last frame, or the sweep's run-out).
struct SetSpan {
  std::int64_t begin = 0;
  std::int64_t end = 0;
};

SetSpan spanOf(const ScanOptions& options, const SetPlan& set, const drivers::StageConfig& stage) {
  if (options.mode == ScanMode::StopAndGo) return {set.positions.front(), set.positions.back()};
  const drivers::SweepPlan sweep = drivers::planSweep(stage, sweepRequest(options, set, stage));
  return {set.positions.front() - sweep.run_up_steps, set.positions.back() + sweep.run_out_steps};
}

// A way from one place to another: the signed steps of the move.
struct Leg {
  std::int64_t steps = 0;
  bool checks = false;  // passes a home edge that checks the step count
};

// A longer way round is taken when it passes a home edge and the shorter one
// does not, up to this fraction of a turn: the scan's step count is then
// checked on the way instead of by seeking home afterwards (seconds).
constexpr double kCheckDetourTurns = 0.05;

// The ways from `from` to `to`: directly, and with a whole number of steps
// a turn, either way round (the count is kept within the plan's turn).
std::vector<Leg> waysBetween(const drivers::RotationStage& stage, std::int64_t from,
                             std::int64_t to) {
  std::vector<Leg> ways;
  const std::optional<std::int64_t> turn = stage.config().stepsPerTurn();
  if (!turn) {
    ways.push_back({to - from, stage.passesCheckedEdge(from, to - from)});
    return ways;
  }
  const std::int64_t up = ((to - from) % *turn + *turn) % *turn;
  ways.push_back({up, stage.passesCheckedEdge(from, up)});
  if (up != 0) ways.push_back({up - *turn, stage.passesCheckedEdge(from, up - *turn)});
  return ways;
}

Leg chooseLeg(const drivers::RotationStage& stage, std::int64_t from, std::int64_t to,
              bool want_check) {
  const std::vector<Leg> ways = waysBetween(stage, from, to);
  Leg best = ways.front();
  for (const Leg& w : ways)
    if (std::abs(w.steps) < std::abs(best.steps)) best = w;
  if (!want_check || best.checks) return best;
  const std::optional<std::int64_t> turn = stage.config().stepsPerTurn();
  const double detour = turn ? kCheckDetourTurns * static_cast<double>(*turn) : 0.0;
  for (const Leg& w : ways) {
    if (w.checks && static_cast<double>(std::abs(w.steps) - std::abs(best.steps)) <= detour)
      return w;
  }
  return best;
}

}  // namespace

// The order the stage runs the two motion sets in and the way to each: the
// set nearer to where the stage stands first, so that scans alternate and
// each starts where the last ended; between them, the way that passes home
// when that costs little.
struct Acquisition::Route {
  std::array<FringeSet, 2> order{FringeSet::High, FringeSet::Low};
  int firstFrame(FringeSet id, const ScanPlan& plan) const {
    return id == order[0] ? 0 : static_cast<int>(plan.set(order[0]).positions.size());
  }
};

// What the two threads share. Written before the scan starts, then only
// through the atomics (release on publish, acquire on read).
struct Acquisition::Shared {
  Shared(int frames, Route r)
      : route(r),
        angle_deg(static_cast<std::size_t>(frames)),
        trigger_ns(static_cast<std::size_t>(frames)) {}

  const Route route;
  // Frames are counted in the order the stage runs them (route.order).
  std::vector<double> angle_deg;                      // written before `triggered` passes the frame
  std::vector<std::atomic<std::int64_t>> trigger_ns;  // latest trigger of each frame
  std::atomic<int> triggered{0};                      // frames triggered (or, continuous, armed)
  // Stop-and-go: when the next trigger fires (the end of the settle), told
  // as the stage arrives so that the capture side can sleep until then.
  std::atomic<std::int64_t> next_trigger_ns{0};
  std::atomic<int> acked{0};             // frames received from every camera
  std::atomic<int> retrigger{-1};        // frame (stop-and-go) or first frame of a set to redo
  std::atomic<int> sweep_generation{0};  // continuous: sweeps started (a re-sweep is a new one)
  std::atomic<bool> failed{false};
  std::atomic<bool> motion_done{false};
  std::atomic<bool> motion_attached{false};
  std::optional<drivers::StepCheck> step_check;  // written before motion_done
  ScanTimeSplit split;                           // the same
  std::mutex error_mutex;
  std::string error;

  void fail(const std::string& message) {
    {
      const std::lock_guard lock(error_mutex);
      if (error.empty()) error = message;
    }
    failed.store(true, std::memory_order_release);
  }
  bool stopping() const { return failed.load(std::memory_order_acquire); }
};

Acquisition::Acquisition(drivers::Board& board) : board_(board) {
  const drivers::BoardProfile& profile = board.profile();
  drivers::StageLineSpecs specs;
  specs.step = profile.gpio.step;
  specs.dir = profile.gpio.dir;
  specs.enable = profile.gpio.enable;
  specs.home = profile.gpio.home;
  specs.fault = profile.gpio.fault;
  MonitoringGpio gpio(board.gpio(), profile.gpio.enable, enable_level_);
  stage_ = std::make_unique<drivers::RotationStage>(profile.stage, board.clock(), gpio, specs);
  light_ = std::make_unique<MonitoredLine>(board.gpio().requestOutput(profile.gpio.light, false),
                                           false, light_level_);
  publishStage();
  std::set<std::string> lines;
  for (const auto& camera : profile.cameras) {
    if (camera.config.trigger != drivers::TriggerMode::GpioPulse) continue;
    if (!lines.insert(camera.trigger_line).second) continue;
    const auto it = profile.gpio.triggers.find(camera.trigger_line);
    if (it == profile.gpio.triggers.end()) {
      throw drivers::GpioError("camera '" + camera.name + "': trigger line '" +
                               camera.trigger_line + "' is not in [gpio]");
    }
    trigger_.addLine(board.gpio().requestOutput(it->second, false));
  }
}

Acquisition::~Acquisition() {
  // A line that fails now (a GPIO chip gone, a kernel error) must not end the
  // program from a destructor; the stage driver's own destructor disables it
  // again and reports nothing either.
  try {
    light_->set(false);
  } catch (...) {  // nothing can be reported from a destructor
  }
  try {
    stage_->disable();
  } catch (...) {  // as above
  }
}

HeadOutputs Acquisition::outputs() const {
  HeadOutputs o;
  o.stage_enabled = enable_level_.load(std::memory_order_relaxed);
  o.light = light_level_.load(std::memory_order_relaxed);
  o.homed = homed_.load(std::memory_order_acquire);
  o.position_deg = position_deg_.load(std::memory_order_acquire);
  return o;
}

void Acquisition::publishStage() {
  homed_.store(stage_->homed(), std::memory_order_release);
  position_deg_.store(stage_->angleDeg(), std::memory_order_release);
}

void Acquisition::abort() noexcept {
  abort_.store(true, std::memory_order_release);
  stage_->abort();
}

void Acquisition::armSoftwareTriggers(const std::vector<std::string>& cameras) {
  trigger_.clearSoftwareCameras();
  for (const auto& name : cameras) {
    if (board_.profile().camera(name).config.trigger == drivers::TriggerMode::Software)
      trigger_.addSoftwareCamera(board_.camera(name));
  }
}

std::vector<cv::Mat> Acquisition::still(const StillOptions& options) {
  abort_.store(false, std::memory_order_release);
  if (options.cameras.empty()) throw std::invalid_argument("still: no camera to capture");
  armSoftwareTriggers(options.cameras);
  drivers::Clock& clock = board_.clock();
  const nanoseconds timeout = us(options.frame_timeout_ms * 1e3);
  struct LightOff {  // however the capture ends
    drivers::OutputLine& light;
    ~LightOff() {
      try {
        light.set(false);
      } catch (...) {  // the capture's own error comes first
      }
    }
  } light_off{*light_};
  const drivers::ClockThread attach(clock);
  const RunningCameras cameras(board_, options.cameras);
  light_->set(options.light);
  std::vector<cv::Mat> images;
  for (int attempt = 0;; ++attempt) {
    const nanoseconds triggered = clock.now();
    trigger_.set(true);
    clock.sleepUntil(clock.now() + us(options.trigger_pulse_us));
    trigger_.set(false);
    images.clear();
    std::string silent;  // the first camera without a frame of this trigger
    for (const std::string& name : options.cameras) {
      const nanoseconds latency = us(board_.profile().camera(name).image_latency_ms * 1e3);
      const nanoseconds give_up = clock.now() + latency + timeout;
      std::optional<drivers::Frame> frame;
      for (;;) {
        if (abort_.load(std::memory_order_acquire)) throw ScanError("capture aborted");
        frame = board_.camera(name).waitFrame(timeout);
        // A frame exposed before the trigger (or a stream's older frame) is
        // passed over, until the stream has had its latency and timeout.
        if (!frame || frame->timestamp >= triggered + latency) break;
        if (clock.now() > give_up) {
          frame.reset();
          break;
        }
      }
      if (!frame) {
        silent = name;
        break;
      }
      images.push_back(frame->image.clone());
    }
    if (silent.empty()) return images;
    if (attempt > 0) {
      throw ScanError("capture failed: camera '" + silent + "': no frame within " +
                      number(options.frame_timeout_ms) + " ms of the trigger, twice");
    }
  }
}

void Acquisition::motion(const ScanOptions& options, const ScanPlan& plan, Shared& shared) {
  drivers::Clock& clock = board_.clock();
  const drivers::ClockThread attach(clock);
  shared.motion_attached.store(true, std::memory_order_release);
  // However the motion ends, the capture side learns it.
  struct Done {
    std::atomic<bool>& flag;
    ~Done() { flag.store(true, std::memory_order_release); }
  } done{shared.motion_done};
  auto pulse = [&](int frame) {
    shared.trigger_ns[static_cast<std::size_t>(frame)].store(clock.now().count(),
                                                             std::memory_order_release);
    trigger_.set(true);
    clock.sleepUntil(clock.now() + us(options.trigger_pulse_us));
    trigger_.set(false);
  };
  // Waits (on the clock) until the capture side has `frames` frames, or asks
  // to redo from frame `first`.
  enum class Ack { kDone, kRedo, kStop };
  auto awaitAck = [&](int frames, int first) {
    for (;;) {
      if (shared.stopping() || abort_.load(std::memory_order_acquire)) return Ack::kStop;
      if (shared.acked.load(std::memory_order_acquire) >= frames) return Ack::kDone;
      int asked = first;
      if (shared.retrigger.compare_exchange_strong(asked, -1)) return Ack::kRedo;
      clock.sleepUntil(clock.now() + kPoll);
    }
  };
  try {
    ScanTimeSplit& split = shared.split;
    nanoseconds mark = clock.now();
    const auto lap = [&](nanoseconds& into) {
      const nanoseconds now = clock.now();
      into += now - mark;
      mark = now;
    };
    if (!stage_->homed()) {
      stage_->enable();
      stage_->home();
    }
    stage_->enable();
    stage_->resetPassedChecks();
    lap(split.homing);
    int base = 0;
    for (const FringeSet id : shared.route.order) {
      const SetPlan& set = plan.set(id);
      const int n = static_cast<int>(set.positions.size());
      const SetSpan span = spanOf(options, set, stage_->config());
      const Leg leg = chooseLeg(*stage_, stage_->position(), span.begin,
                                options.verify_steps && stage_->passedChecks() == 0);
      if (stage_->config().stepsPerTurn()) {
        if (leg.steps != 0) stage_->turnTo(span.begin, leg.steps > 0 ? 1 : -1);
      } else {
        stage_->moveToStep(span.begin);
      }
      lap(split.travel);
      if (options.mode == ScanMode::StopAndGo) {
        for (int k = 0; k < n; ++k) {
          const int frame = base + k;
          stage_->moveToStep(set.positions[static_cast<std::size_t>(k)]);
          lap(split.sets);
          const nanoseconds settled = clock.now() + us(options.settle_ms * 1e3);
          shared.next_trigger_ns.store(settled.count(), std::memory_order_release);
          clock.sleepUntil(settled);
          lap(split.settling);
          shared.angle_deg[static_cast<std::size_t>(frame)] = stage_->angleDeg();
          shared.triggered.store(frame + 1, std::memory_order_release);
          pulse(frame);
          Ack ack;
          while ((ack = awaitAck(frame + 1, frame)) == Ack::kRedo)
            pulse(frame);
          if (ack == Ack::kStop) return;
        }
      } else {
        const drivers::SweepRequest request = sweepRequest(options, set, board_.profile().stage);
        for (;;) {
          const drivers::PreparedSweep sweep = stage_->prepareSweep(set.positions.front(), request);
          for (int k = 0; k < n; ++k)
            shared.angle_deg[static_cast<std::size_t>(base) + static_cast<std::size_t>(k)] =
                sweep.trigger_angles_deg[static_cast<std::size_t>(k)];
          const nanoseconds start = clock.now();
          for (int k = 0; k < n; ++k)
            shared.trigger_ns[static_cast<std::size_t>(base) + static_cast<std::size_t>(k)].store(
                start.count());
          shared.sweep_generation.fetch_add(1, std::memory_order_acq_rel);
          shared.triggered.store(base + n, std::memory_order_release);
          stage_->runSweep(sweep, trigger_);
          const Ack ack = awaitAck(base + n, base);
          if (ack == Ack::kStop) return;
          if (ack == Ack::kDone) break;  // else sweep the set again
        }
      }
      lap(split.sets);
      base += n;
    }
    if (stage_->lastPassedCheck()) {
      shared.step_check = stage_->lastPassedCheck();
    } else if (options.verify_steps) {
      shared.step_check = stage_->verifyStepCount();
    }
    lap(split.step_check);
    stage_->disable();
  } catch (const std::exception& e) {
    shared.fail(e.what());
  }
}

void Acquisition::capture(const ScanOptions& options, const ScanPlan& plan, FrameSink& sink,
                          Shared& shared, const std::function<void(const ScanProgress&)>& progress,
                          ScanReport& report) {
  drivers::Clock& clock = board_.clock();
  const nanoseconds timeout = us(options.frame_timeout_ms * 1e3);
  auto halted = [&] { return shared.stopping() || abort_.load(std::memory_order_acquire); };
  // Waits on the board's clock until `done()`, or returns false when the scan
  // halts or the motion ends first.
  auto awaitMotion = [&](const auto& done) {
    nanoseconds poll = kPoll;
    while (!done()) {
      if (halted() || shared.motion_done.load(std::memory_order_acquire)) return false;
      const nanoseconds now = clock.now();
      const nanoseconds announced{shared.next_trigger_ns.load(std::memory_order_acquire)};
      if (announced > now) {
        clock.sleepUntil(announced);
        poll = kPoll;
      } else {
        clock.sleepUntil(now + poll);
        poll = std::min(2 * poll, kPollMax);
      }
    }
    return true;
  };
  std::map<std::string, std::optional<std::uint64_t>> next_sequence;
  std::map<std::string, int> received, skip;  // frames of the current set, per camera
  // How each camera's frames are taken: a continuous stream's frame of a
  // trigger is the first one stamped its image latency after it, and its
  // sequence gaps are frames nobody read, not lost exposures.
  struct Stream {
    bool continuous = false;
    nanoseconds latency{0};
  };
  std::map<std::string, Stream> streams;
  for (const std::string& name : options.cameras) {
    const drivers::CameraProfile& profile = board_.profile().camera(name);
    streams[name] = {profile.config.stream == drivers::FrameStream::Continuous ||
                         profile.config.trigger == drivers::TriggerMode::FreeRunning,
                     us(profile.image_latency_ms * 1e3)};
  }
  int base = 0;
  for (const FringeSet id : shared.route.order) {
    const int n = static_cast<int>(plan.set(id).positions.size());
    received.clear();
    skip.clear();
    for (int k = 0; k < n; ++k) {
      const int frame = base + k;
      if (!awaitMotion([&] { return shared.triggered.load(std::memory_order_acquire) > frame; }))
        return;
      bool retried = false;
      for (const std::string& name : options.cameras) {
        drivers::Camera& camera = board_.camera(name);
        // The set this camera's frame belongs to: the motion set itself, or
        // (ring plan) the other one for a camera facing the other half.
        const FringeSet camera_set = plan.setOf(name, id);
        const Stream& stream = streams[name];
        // A stream whose frames never get new enough (a camera that repeats
        // an old frame, stamps from another clock) times out like silence.
        nanoseconds give_up = clock.now() + stream.latency + timeout;
        for (;;) {
          if (halted()) return;
          std::optional<drivers::Frame> f = camera.waitFrame(timeout);
          const std::int64_t triggered_at =
              shared.trigger_ns[static_cast<std::size_t>(frame)].load(std::memory_order_acquire);
          const bool too_old = f && f->timestamp.count() < triggered_at + stream.latency.count();
          const bool stale = too_old && clock.now() > give_up;
          if (stale) f.reset();
          if (!f) {
            give_up = clock.now() + stream.latency + timeout;
            if (retried) {
              shared.fail(
                  "camera '" + name + "': no frame " + std::to_string(k) + " of the " +
                  std::string(toString(camera_set)) + " set within " +
                  number(options.frame_timeout_ms) + " ms, twice" +
                  (stale ? " (its frames kept coming, none stamped after the trigger)" : ""));
              return;
            }
            retried = true;
            ++report.retries;
            for (auto& [camera_name, sequence] : next_sequence)
              sequence.reset();  // the lost exposure may have used a sequence number
            if (options.mode == ScanMode::StopAndGo) {
              shared.retrigger.store(frame, std::memory_order_release);  // the same frame again
              continue;
            }
            // Continuous: the set is swept again. Its frames come from the
            // start; each camera skips those it already has.
            const int generation = shared.sweep_generation.load(std::memory_order_acquire);
            shared.retrigger.store(base, std::memory_order_release);
            while (shared.sweep_generation.load(std::memory_order_acquire) == generation) {
              if (halted() || shared.motion_done.load(std::memory_order_acquire)) return;
              clock.sleepUntil(clock.now() + kPoll);
            }
            for (const std::string& c : options.cameras)
              skip[c] = received[c];
            continue;
          }
          // Exposed before this frame's trigger (or sweep), or a stream's older frame.
          if (too_old) continue;
          if (skip[name] > 0) {  // a re-sweep's frame this camera already has
            --skip[name];
            continue;
          }
          std::optional<std::uint64_t>& expected = next_sequence[name];
          if (expected && f->sequence != *expected && !stream.continuous) {
            shared.fail("camera '" + name + "': frame sequence jumped from " +
                        std::to_string(*expected) + " to " + std::to_string(f->sequence) +
                        " at frame " + std::to_string(k) + " of the " +
                        std::string(toString(camera_set)) + " set: a frame was lost");
            return;
          }
          expected = f->sequence + 1;
          ++received[name];
          sink.onFrame(name, camera_set, k, shared.angle_deg[static_cast<std::size_t>(frame)],
                       f->image);
          break;
        }
      }
      shared.acked.store(frame + 1, std::memory_order_release);
      ++report.frames;
      if (k == n - 1) {
        report.set_duration[id == FringeSet::High ? 0 : 1] =
            clock.now() - nanoseconds{shared.trigger_ns[static_cast<std::size_t>(base)].load()};
      }
      if (progress) progress({frame + 1, plan.frames(), id});
    }
    base += n;
  }
  awaitMotion([] { return false; });  // until the motion ends (the step check) or halts
}

std::map<std::string, double> timeSplitSeconds(const ScanTimeSplit& split) {
  const auto s = [](nanoseconds t) { return static_cast<double>(t.count()) / 1e9; };
  return {{"homing", s(split.homing)},
          {"travel", s(split.travel)},
          {"sets", s(split.sets)},
          {"settling", s(split.settling)},
          {"step_check", s(split.step_check)}};
}

std::chrono::nanoseconds shortestScan(const ScanOptions& options, const ScanPlan& plan,
                                      const drivers::StageConfig& stage) {
  ScanOptions continuous = options;
  continuous.mode = ScanMode::Continuous;
  const auto duration = [](const drivers::StepSchedule& s) {
    return s.step_ns.empty() ? nanoseconds{0} : nanoseconds{s.step_ns.back()};
  };
  nanoseconds sweeps{0};
  for (const FringeSet id : kFringeSets)
    sweeps +=
        duration(drivers::planSweep(stage, sweepRequest(continuous, plan.set(id), stage)).schedule);
  const SetSpan high = spanOf(continuous, plan.high, stage);
  const SetSpan low = spanOf(continuous, plan.low, stage);
  const std::optional<std::int64_t> turn = stage.stepsPerTurn();
  const auto gap = [&](std::int64_t from, std::int64_t to) {
    const std::int64_t direct = std::abs(to - from);
    if (!turn) return direct;
    const std::int64_t up = ((to - from) % *turn + *turn) % *turn;
    return std::min(up, *turn - up);
  };
  const std::int64_t travel = std::min(gap(high.end, low.begin), gap(low.end, high.begin));
  return sweeps + duration(drivers::planMove(stage, travel));
}

std::array<FringeSet, 2> Acquisition::nextSetOrder(const ScanOptions& options,
                                                   const ScanPlan& plan) const {
  const drivers::StageConfig& config = stage_->config();
  // Homing leaves the stage at its home edge.
  const std::int64_t at = stage_->homed()
                              ? stage_->position()
                              : std::llround(config.home_offset_deg * config.stepsPerDeg());
  const auto travel = [&](FringeSet first, FringeSet second) {
    const SetSpan a = spanOf(options, plan.set(first), config);
    const SetSpan b = spanOf(options, plan.set(second), config);
    return std::abs(chooseLeg(*stage_, at, a.begin, false).steps) +
           std::abs(chooseLeg(*stage_, a.end, b.begin, false).steps);
  };
  if (travel(FringeSet::Low, FringeSet::High) < travel(FringeSet::High, FringeSet::Low))
    return {FringeSet::Low, FringeSet::High};
  return {FringeSet::High, FringeSet::Low};
}

ScanReport Acquisition::run(const ScanOptions& options, const ScanPlan& plan, FrameSink& sink,
                            const std::function<void(const ScanProgress&)>& progress) {
  abort_.store(false, std::memory_order_release);
  struct Publish {  // the stage's state when the scan ends, however it ends
    Acquisition& acquisition;
    ~Publish() { acquisition.publishStage(); }
  } publish{*this};
  if (options.cameras.empty()) throw std::invalid_argument("scan: no camera to capture");
  armSoftwareTriggers(options.cameras);
  for (const auto& name : options.cameras) {
    const drivers::CameraProfile& camera = board_.profile().camera(name);
    if (camera.config.trigger == drivers::TriggerMode::FreeRunning &&
        options.mode == ScanMode::Continuous)
      throw std::invalid_argument("scan: camera '" + name +
                                  "' is free-running; continuous mode needs triggered cameras");
    if (camera.config.stream == drivers::FrameStream::Continuous &&
        options.mode == ScanMode::Continuous)
      throw std::invalid_argument("scan: camera '" + name +
                                  "' streams continuously (stream = \"continuous\"); continuous "
                                  "mode needs cameras that deliver one frame per trigger");
  }
  ScanReport report;
  Shared shared(plan.frames(), Route{nextSetOrder(options, plan)});
  drivers::Clock& clock = board_.clock();
  const nanoseconds started = clock.now();
  // The executor is idle between scans: its lateness figures start again so
  // the report holds this scan's edges only (homing included), not every
  // edge since the board was opened.
  stage_->resetTimingStats();
  report.homed = !stage_->homed();
  {
    const SafeState safe(*stage_, *light_);
    const RunningCameras cameras(board_, options.cameras);
    light_->set(true);
    std::optional<drivers::RealtimeThread> thread;
    {
      const drivers::ClockThread attach(clock);
      drivers::RealtimeOptions realtime;
      realtime.priority = options.realtime_priority;
      realtime.lock_memory = options.lock_memory;
      thread.emplace([&] { motion(options, plan, shared); }, realtime);
      // Both threads take part in the clock before either acts (a
      // discrete-event clock must know every participant).
      while (!shared.motion_attached.load(std::memory_order_acquire))
        std::this_thread::yield();
      report.realtime = thread->realtime();
      report.warnings = thread->warnings();
      try {
        capture(options, plan, sink, shared, progress, report);
      } catch (const std::exception& e) {
        shared.fail(e.what());
        stage_->abort();
        // Detach before joining (the join blocks outside the clock).
      }
      if (shared.stopping()) stage_->abort();
    }
    thread->join();
  }
  report.duration = clock.now() - started;
  report.step_check = shared.step_check;
  report.split = shared.split;
  report.step_jitter = stage_->executor().stepJitter().snapshot();
  report.trigger_jitter = stage_->executor().triggerJitter().snapshot();
  report.step_reramps = stage_->executor().reramps();
  report.step_slip = stage_->executor().slip();
  if (report.step_reramps > 0) {
    report.warnings.push_back("the step executor woke late " + std::to_string(report.step_reramps) +
                              " time(s) at speed and re-ramped the stage instead of bursting the "
                              "overdue steps (the moves ran " +
                              std::to_string(static_cast<double>(report.step_slip.count()) / 1e6) +
                              " ms late in all)");
  }
  if (abort_.load(std::memory_order_acquire)) throw ScanError("scan aborted");
  if (shared.stopping()) {
    const std::lock_guard lock(shared.error_mutex);
    throw ScanError("scan failed: " + shared.error);
  }
  const auto anglesOf = [&](FringeSet id) {
    const auto first = shared.angle_deg.begin() + shared.route.firstFrame(id, plan);
    return std::vector<double>(first, first + static_cast<long>(plan.set(id).positions.size()));
  };
  report.high_deg = anglesOf(FringeSet::High);
  report.low_deg = anglesOf(FringeSet::Low);
  report.first_set = shared.route.order[0];
  return report;
}

}  // namespace cylscan::firmware
