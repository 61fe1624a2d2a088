// SPDX-License-Identifier: Apache-2.0
// The emulated board's mechanics and optics (tests/emulated-board): a test
// tool that runs in the guest beside the firmware, which sees only real
// kernel devices.
//
//   cylscan-emulated-feeder run --head HEAD --scene SCENE --chip DIR --video DEV --log FILE
//       follows every value the firmware sets on the gpio-sim chip (configfs
//       DIR) through the kernel's gpio:gpio_value trace events, turns step
//       pulses into stage angle on the virtual head's stage model (HEAD),
//       drives the home line through gpio-sim's pull, and on each trigger
//       edge renders the virtual head's frame for that angle (SCENE) and
//       queues it on vivid's video output node DEV, which vivid loops back
//       to its capture node (the firmware's camera). SIGTERM ends it; FILE
//       then gets one line per trigger and the stage's counters.
//       --stop-after K: after the K-th frame the camera's link goes silent
//       (vivid's "Percentage of Dropped Buffers" at 100: no capture frames).
//       --rt-priority P: runs at SCHED_FIFO priority P.
//   cylscan-emulated-feeder angles BUNDLE LOG --steps-per-deg S --tolerance-steps T
//       the bundle's executed angles against the angles the feeder counted.
//   cylscan-emulated-feeder compare PHASE_A PHASE_B --max-rms R --max-mismatch F
//       two `cylscan phase` outputs: the valid sets and the absolute phase.
//   cylscan-emulated-feeder calibration PHASE --out FILE
//       a quasi-calibration file for the camera of a `cylscan phase` output:
//       every pixel valid, its phase range that of the whole map, and a
//       plane's coordinates. Not a head's geometry: it lets the daemon
//       reconstruct every pixel, so that what a calibrated scan costs the
//       device in memory is measured.
#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sched.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "algo/quasi_calibration.hpp"
#include "drivers/sim/camera_model.hpp"
#include "drivers/sim/head_config.hpp"
#include "drivers/sim/projector.hpp"
#include "drivers/sim/renderer.hpp"
#include "drivers/sim/scene.hpp"
#include "drivers/sim/stage.hpp"
#include "formats/atomic_file.hpp"
#include "formats/capture_bundle.hpp"
#include "formats/images.hpp"
#include "formats/png.hpp"

namespace fs = std::filesystem;
using namespace cylscan;

namespace {

std::atomic<bool> g_stop{false};
void onSignal(int) {
  g_stop.store(true);
}

std::string readText(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error("cannot read " + file.string());
  std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  while (!s.empty() && (s.back() == '\n' || s.back() == ' '))
    s.pop_back();
  return s;
}

void writeText(const fs::path& file, const std::string& text) {
  std::ofstream out(file);
  out << text;
  out.flush();
  if (!out) throw std::runtime_error("cannot write '" + text + "' to " + file.string());
}

// Options "--name value" after the command's positional arguments.
struct Args {
  std::vector<std::string> positional;
  std::map<std::string, std::string> named;
  std::string get(const std::string& name) const {
    auto it = named.find(name);
    if (it == named.end()) throw std::invalid_argument("missing --" + name);
    return it->second;
  }
  std::string get(const std::string& name, const std::string& fallback) const {
    auto it = named.find(name);
    return it == named.end() ? fallback : it->second;
  }
};

Args parse(int argc, char** argv, int first) {
  Args a;
  for (int i = first; i < argc; ++i) {
    std::string s = argv[i];
    if (s.rfind("--", 0) == 0) {
      if (i + 1 >= argc) throw std::invalid_argument(s + " needs a value");
      a.named[s.substr(2)] = argv[++i];
    } else {
      a.positional.push_back(s);
    }
  }
  return a;
}

// The gpio-sim chip made through configfs: line offsets by name, the sysfs
// directory of its lines and the global GPIO numbers the trace events use.
class SimChip {
 public:
  explicit SimChip(const fs::path& configfs) {
    const fs::path bank = configfs / "bank0";
    chip_name_ = readText(bank / "chip_name");
    const std::string dev = readText(configfs / "dev_name");
    for (const auto& entry : fs::directory_iterator(bank)) {
      const std::string d = entry.path().filename().string();
      if (d.rfind("line", 0) != 0) continue;
      const int offset = std::stoi(d.substr(4));
      offsets_[readText(entry.path() / "name")] = offset;
    }
    sysfs_ = fs::path("/sys/devices/platform") / dev / chip_name_;
    base_ = findBase();
  }
  int offset(const std::string& name) const {
    auto it = offsets_.find(name);
    if (it == offsets_.end()) throw std::runtime_error("gpio-sim chip has no line '" + name + "'");
    return it->second;
  }
  int base() const { return base_; }
  int lines() const { return static_cast<int>(offsets_.size()); }
  void pull(int offset, bool up) const {
    writeText(sysfs_ / ("sim_gpio" + std::to_string(offset)) / "pull",
              up ? "pull-up" : "pull-down");
  }
  const std::string& name() const { return chip_name_; }

 private:
  // debugfs: "gpiochipN: GPIOs B-E, parent: ...".
  int findBase() const {
    std::ifstream in("/sys/kernel/debug/gpio");
    std::string line;
    const std::string key = chip_name_ + ": GPIOs ";
    while (std::getline(in, line)) {
      if (line.rfind(key, 0) == 0) return std::stoi(line.substr(key.size()));
    }
    throw std::runtime_error("no " + chip_name_ + " in /sys/kernel/debug/gpio (debugfs mounted?)");
  }
  std::string chip_name_;
  fs::path sysfs_;
  std::map<std::string, int> offsets_;
  int base_ = 0;
};

// The kernel's gpio:gpio_value events ("... 123.456789: gpio_value: 515 set 1").
class GpioTrace {
 public:
  struct Event {
    int gpio = 0;
    bool value = false;
    std::chrono::nanoseconds time{0};
  };
  GpioTrace(const fs::path& tracefs, int base, int count) : dir_(tracefs) {
    writeText(dir_ / "tracing_on", "0");
    writeText(dir_ / "trace_clock", "mono");
    writeText(dir_ / "buffer_size_kb", "16384");
    writeText(dir_ / "trace", "");
    writeText(dir_ / "events/gpio/gpio_value/filter",
              "gpio >= " + std::to_string(base) + " && gpio < " + std::to_string(base + count));
    writeText(dir_ / "events/gpio/gpio_value/enable", "1");
    writeText(dir_ / "tracing_on", "1");
    fd_ = ::open((dir_ / "trace_pipe").c_str(), O_RDONLY | O_NONBLOCK);
    if (fd_ < 0)
      throw std::runtime_error("cannot open trace_pipe: " + std::string(strerror(errno)));
  }
  ~GpioTrace() {
    if (fd_ >= 0) ::close(fd_);
  }
  GpioTrace(const GpioTrace&) = delete;
  GpioTrace& operator=(const GpioTrace&) = delete;

  // Events that arrived within `timeout_ms` (possibly none).
  std::vector<Event> read(int timeout_ms) {
    std::vector<Event> events;
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return events;
    char buf[65536];
    const ssize_t n = ::read(fd_, buf, sizeof buf);
    if (n <= 0) return events;
    pending_.append(buf, static_cast<std::size_t>(n));
    std::size_t start = 0;
    for (std::size_t nl; (nl = pending_.find('\n', start)) != std::string::npos; start = nl + 1) {
      const std::string line = pending_.substr(start, nl - start);
      const std::size_t tag = line.find(": gpio_value: ");
      if (tag == std::string::npos) continue;
      const std::size_t ts = line.rfind(' ', tag);
      unsigned gpio = 0;
      char kind[8] = {};
      int value = 0;
      if (std::sscanf(line.c_str() + tag + 14, "%u %7s %d", &gpio, kind, &value) != 3) continue;
      if (std::strcmp(kind, "set") != 0) continue;
      const double seconds = std::stod(line.substr(ts + 1, tag - ts - 1));
      events.push_back({static_cast<int>(gpio), value != 0,
                        std::chrono::nanoseconds(static_cast<std::int64_t>(seconds * 1e9))});
    }
    pending_.erase(0, start);
    return events;
  }
  // Events the ring buffer had to drop (they would be steps the feeder missed).
  long overruns() const {
    long total = 0;
    for (const auto& cpu : fs::directory_iterator(dir_ / "per_cpu")) {
      std::ifstream in(cpu.path() / "stats");
      std::string key;
      while (in >> key) {
        if (key == "overrun:") {
          long v = 0;
          in >> v;
          total += v;
        }
      }
    }
    return total;
  }

 private:
  fs::path dir_;
  int fd_ = -1;
  std::string pending_;
};

std::chrono::nanoseconds monotonicNow() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return std::chrono::seconds(ts.tv_sec) + std::chrono::nanoseconds(ts.tv_nsec);
}

// vivid's video output node, streaming GREY frames through mmap buffers.
// vivid's output thread takes a queued buffer off its queue only when another
// is queued behind it, so the last frame queued stays on the output, and its
// capture node (looped back) repeats it until the next: the feeder queues one
// buffer per rendered frame and takes buffers back as vivid returns them.
class VividOutput {
 public:
  VividOutput(const fs::path& device, int width, int height) : device_(device.string()) {
    fd_ = ::open(device.c_str(), O_RDWR | O_NONBLOCK);
    if (fd_ < 0) fail("cannot open");
    v4l2_format fmt{};
    fmt.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    fmt.fmt.pix.width = static_cast<unsigned>(width);
    fmt.fmt.pix.height = static_cast<unsigned>(height);
    fmt.fmt.pix.pixelformat = V4L2_PIX_FMT_GREY;
    fmt.fmt.pix.field = V4L2_FIELD_NONE;
    if (::ioctl(fd_, VIDIOC_S_FMT, &fmt) < 0) fail("VIDIOC_S_FMT (output GREY)");
    if (fmt.fmt.pix.pixelformat != V4L2_PIX_FMT_GREY ||
        static_cast<int>(fmt.fmt.pix.width) != width ||
        static_cast<int>(fmt.fmt.pix.height) != height)
      throw std::runtime_error(device_ + ": the output does not take " + std::to_string(width) +
                               "x" + std::to_string(height) + " GREY");
    stride_ = fmt.fmt.pix.bytesperline;
    width_ = width;
    height_ = height;
    v4l2_requestbuffers req{};
    req.count = 3;
    req.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    req.memory = V4L2_MEMORY_MMAP;
    if (::ioctl(fd_, VIDIOC_REQBUFS, &req) < 0 || req.count < 2) fail("VIDIOC_REQBUFS");
    for (unsigned i = 0; i < req.count; ++i) {
      v4l2_buffer b{};
      b.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
      b.memory = V4L2_MEMORY_MMAP;
      b.index = i;
      if (::ioctl(fd_, VIDIOC_QUERYBUF, &b) < 0) fail("VIDIOC_QUERYBUF");
      void* p = ::mmap(nullptr, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, b.m.offset);
      if (p == MAP_FAILED) fail("mmap");
      maps_.push_back({static_cast<std::uint8_t*>(p), b.length});
      free_.push_back(i);
    }
  }
  ~VividOutput() {
    if (streaming_) {
      int type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
      ::ioctl(fd_, VIDIOC_STREAMOFF, &type);
    }
    for (const auto& m : maps_)
      ::munmap(m.first, m.second);
    if (fd_ >= 0) ::close(fd_);
  }
  VividOutput(const VividOutput&) = delete;
  VividOutput& operator=(const VividOutput&) = delete;

  // Queues `frame` (8-bit, the output's size); starts the stream with the first.
  void queue(const cv::Mat& frame) {
    if (frame.cols != width_ || frame.rows != height_ || frame.type() != CV_8UC1)
      throw std::runtime_error("frame is not " + std::to_string(width_) + "x" +
                               std::to_string(height_) + " 8-bit");
    reclaim(free_.empty() ? 2000 : 0);
    if (free_.empty())
      throw std::runtime_error(device_ + ": vivid returned no output buffer in 2 s");
    const unsigned index = free_.back();
    free_.pop_back();
    std::uint8_t* dst = maps_[index].first;
    for (int y = 0; y < height_; ++y)
      std::memcpy(dst + static_cast<std::size_t>(y) * stride_, frame.ptr(y),
                  static_cast<std::size_t>(width_));
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = index;
    b.bytesused = static_cast<unsigned>(static_cast<std::size_t>(stride_) * height_);
    b.field = V4L2_FIELD_NONE;
    if (::ioctl(fd_, VIDIOC_QBUF, &b) < 0) fail("VIDIOC_QBUF");
    if (!streaming_) {
      int type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
      if (::ioctl(fd_, VIDIOC_STREAMON, &type) < 0) fail("VIDIOC_STREAMON");
      streaming_ = true;
    }
  }

  // Sets one of vivid's controls by its name (the streaming controls are
  // shared by its capture and output nodes).
  void setControl(const std::string& name, int value) {
    v4l2_queryctrl q{};
    q.id = V4L2_CTRL_FLAG_NEXT_CTRL;
    while (::ioctl(fd_, VIDIOC_QUERYCTRL, &q) == 0) {
      if (name == reinterpret_cast<const char*>(q.name)) {
        v4l2_control c{};
        c.id = q.id;
        c.value = value;
        if (::ioctl(fd_, VIDIOC_S_CTRL, &c) < 0) fail("setting '" + name + "'");
        return;
      }
      q.id |= V4L2_CTRL_FLAG_NEXT_CTRL;
    }
    throw std::runtime_error(device_ + ": no control '" + name + "'");
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error(device_ + ": " + what + ": " + strerror(errno));
  }
  // Takes back the buffers vivid is done with, waiting up to `timeout_ms` for one.
  void reclaim(int timeout_ms) {
    if (!streaming_) return;
    pollfd p{fd_, POLLOUT, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return;
    for (;;) {
      v4l2_buffer b{};
      b.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
      b.memory = V4L2_MEMORY_MMAP;
      if (::ioctl(fd_, VIDIOC_DQBUF, &b) < 0) {
        if (errno == EAGAIN) return;
        fail("VIDIOC_DQBUF");
      }
      free_.push_back(b.index);
    }
  }

  std::string device_;
  int fd_ = -1;
  int width_ = 0, height_ = 0;
  unsigned stride_ = 0;
  bool streaming_ = false;
  std::vector<std::pair<std::uint8_t*, std::size_t>> maps_;
  std::vector<unsigned> free_;
};

int runFeeder(const Args& a) {
  const sim::HeadConfig head = sim::loadHeadConfig(a.get("head"));
  const sim::Scene scene = sim::loadScene(a.get("scene"));
  const std::uint64_t seed = std::stoull(a.get("seed", "1"));
  const long stop_after = std::stol(a.get("stop-after", "-1"));
  const SimChip chip(a.get("chip"));
  const sim::CameraParams& cam = head.cameras.front();
  const sim::CameraModel camera(cam);
  const sim::CylindricalProjector projector(head.projector);
  sim::StageModel stage(head.stage);
  const sim::NoiseTable noise(seed);

  sim::TraceOptions trace_options;
  trace_options.threads = head.render.threads;
  std::cerr << "feeder: tracing " << cam.width << "x" << cam.height << " pixels of the scene\n";
  const sim::PixelGeometry geometry = tracePixels(scene, camera, projector, trace_options);
  VividOutput out(a.get("video"), cam.width, cam.height);
  out.setControl("Percentage of Dropped Buffers", 0);
  out.queue(cv::Mat::zeros(cam.height, cam.width, CV_8UC1));  // streaming before the capture

  const int step = chip.offset(head.lines.step.name);
  const int dir = chip.offset(head.lines.dir.name);
  const int enable = chip.offset(head.lines.enable.name);
  const int trigger = chip.offset(head.lines.trigger.name);
  const int light = chip.offset(head.lines.light.name);
  const int home = chip.offset(head.lines.home.name);
  bool home_level = stage.homeActive();
  chip.pull(home, home_level);
  GpioTrace trace(a.get("tracefs", "/sys/kernel/tracing"), chip.base(), chip.lines());
  // The home switch should follow the step that reaches it before the
  // firmware's next one: above the firmware's threads when asked.
  if (const int rt = std::stoi(a.get("rt-priority", "0")); rt > 0) {
    sched_param sp{};
    sp.sched_priority = rt;
    if (::sched_setscheduler(0, SCHED_FIFO, &sp) != 0)
      std::cerr << "feeder: SCHED_FIFO " << rt << ": " << strerror(errno) << " (running without)\n";
  }
  std::signal(SIGTERM, onSignal);
  std::signal(SIGINT, onSignal);
  std::cerr << "feeder: ready (" << chip.name() << ", gpio base " << chip.base() << ")\n";
  { std::ofstream(a.get("log") + ".ready") << "ready\n"; }

  std::map<int, bool> level;
  std::ostringstream log;
  long triggers = 0, written = 0, home_edges = 0;
  double worst_latency_ms = 0;  // trigger edge → its frame queued on the output
  while (!g_stop.load()) {
    for (const GpioTrace::Event& e : trace.read(200)) {
      const int offset = e.gpio - chip.base();
      const bool was = level[offset];
      level[offset] = e.value;
      const bool rising = e.value && !was;
      if (offset == step && rising) {
        stage.stepPulse(e.time);
      } else if (offset == dir) {
        stage.setDirection(e.value);
      } else if (offset == enable) {
        stage.setEnabled(e.value, e.time);
      } else if (offset == trigger && rising) {
        sim::Exposure x;
        x.samples = 1;
        x.stage_deg[0] = stage.angleAt(e.time);
        x.light[0] = level[light];
        x.exposure_us = cam.exposure_us;
        x.reference_exposure_us = head.noise.reference_exposure_us;
        x.gain = cam.gain;
        x.bit_depth = cam.bit_depth;
        x.full_well_e = cam.full_well_e;
        x.read_noise_e = cam.read_noise_e;
        x.noise_scale = head.noise.scale;
        // The virtual head's key for camera 0's exposure number `triggers`.
        x.noise_key = sim::mixBits(seed ^ sim::mixBits(static_cast<std::uint64_t>(triggers)));
        ++triggers;
        double latency_ms = 0;
        if (stop_after < 0 || triggers <= stop_after) {
          out.queue(sim::renderFrame(geometry, projector, x, noise, head.render.threads));
          latency_ms = static_cast<double>((monotonicNow() - e.time).count()) / 1e6;
          worst_latency_ms = std::max(worst_latency_ms, latency_ms);
          ++written;
        } else if (triggers == stop_after + 1) {
          // The camera's link goes silent: vivid delivers no more frames.
          out.setControl("Percentage of Dropped Buffers", 100);
        }
        log << "trigger " << triggers - 1 << " position " << stage.position() << " angle_deg "
            << x.stage_deg[0] << " light " << x.light[0] << " queued_after_ms " << latency_ms
            << "\n";
      }
      if (stage.homeActive() != home_level) {
        home_level = stage.homeActive();
        chip.pull(home, home_level);
        ++home_edges;
      }
    }
  }
  const sim::StageCounters& c = stage.counters();
  log << "pulses " << c.pulses << " ignored " << c.ignored << " lost " << c.lost << " forward "
      << c.forward << " backward " << c.backward << " position " << stage.position()
      << " home_edges " << home_edges << " triggers " << triggers << " written " << written
      << " trace_overruns " << trace.overruns() << " enabled " << stage.enabled()
      << " worst_queue_ms " << worst_latency_ms << "\n";
  out.setControl("Percentage of Dropped Buffers", 0);
  std::ofstream(a.get("log")) << log.str();
  std::cerr << "feeder: " << triggers << " triggers, " << written << " frames, " << c.pulses
            << " step pulses\n";
  return 0;
}

// "key value" pairs of the feeder log's lines starting with `first`.
std::vector<std::map<std::string, std::string>> logLines(const fs::path& file,
                                                         const std::string& first) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error("cannot read " + file.string());
  std::vector<std::map<std::string, std::string>> lines;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream s(line);
    std::string k, v;
    std::map<std::string, std::string> m;
    bool first_key = true;
    while (s >> k >> v) {
      if (first_key && k != first) break;
      first_key = false;
      m[k] = v;
    }
    if (!m.empty()) lines.push_back(m);
  }
  return lines;
}

int runAngles(const Args& a) {
  if (a.positional.size() != 2) throw std::invalid_argument("angles BUNDLE LOG");
  const formats::CaptureBundleReader bundle(a.positional[0]);
  const auto triggers = logLines(a.positional[1], "trigger");
  const double steps_per_deg = std::stod(a.get("steps-per-deg"));
  const double tolerance = std::stod(a.get("tolerance-steps"));
  // The stage runs the nearer set first and the firmware counts within one
  // turn, from its home edge; the feeder counts from power-up. So the frames
  // meet the triggers in one of the two set orders, with one offset modulo a
  // turn for the whole scan, and the same steps between any two frames.
  const double turn = 360.0 * steps_per_deg;
  const auto wrap = [&](double x) { return x - turn * std::round(x / turn); };
  struct Match {
    std::string order;
    double offset = 0;
    double worst = std::numeric_limits<double>::infinity();
  };
  std::optional<Match> best;
  for (const auto& order :
       {std::array{FringeSet::High, FringeSet::Low}, std::array{FringeSet::Low, FringeSet::High}}) {
    std::vector<double> executed;
    for (FringeSet id : order)
      for (double d : bundle.info().set(id).stage_deg)
        executed.push_back(d);
    if (executed.size() != triggers.size()) {
      std::cout << "the bundle has " << executed.size() << " frames, the feeder saw "
                << triggers.size() << " trigger pulses\n";
      return 1;
    }
    Match m;
    m.order = std::string(toString(order[0])) + " set first";
    m.offset = wrap(executed[0] * steps_per_deg - std::stod(triggers[0].at("position")));
    m.worst = 0;
    for (std::size_t i = 0; i < executed.size(); ++i) {
      const double fw = executed[i] * steps_per_deg;
      const double seen = std::stod(triggers[i].at("position"));
      m.worst = std::max(m.worst, std::abs(wrap(fw - seen - m.offset)));
    }
    if (!best || m.worst < best->worst) best = m;
  }
  std::cout << triggers.size() << " frames (" << best->order << "); firmware minus feeder "
            << best->offset << " steps (home edge, modulo a turn), largest further difference "
            << best->worst << " steps\n";
  return std::abs(best->offset) <= tolerance && best->worst <= 0.5 ? 0 : 1;
}

int runCompare(const Args& a) {
  if (a.positional.size() != 2) throw std::invalid_argument("compare PHASE_A PHASE_B");
  const fs::path pa = a.positional[0], pb = a.positional[1];
  const cv::Mat phase_a = formats::readFloatTiff(pa / "absolute.tiff");
  const cv::Mat phase_b = formats::readFloatTiff(pb / "absolute.tiff");
  const cv::Mat invalid_a = formats::readPng(pa / "invalid.png");
  const cv::Mat invalid_b = formats::readPng(pb / "invalid.png");
  if (phase_a.size() != phase_b.size()) {
    std::cout << "phase maps differ in size\n";
    return 1;
  }
  long valid_a = 0, valid_b = 0, both = 0, mismatch = 0;
  double sum = 0, sum2 = 0, worst = 0;
  for (int y = 0; y < phase_a.rows; ++y) {
    for (int x = 0; x < phase_a.cols; ++x) {
      const bool va = invalid_a.at<std::uint8_t>(y, x) == 0;
      const bool vb = invalid_b.at<std::uint8_t>(y, x) == 0;
      valid_a += va;
      valid_b += vb;
      mismatch += va != vb;
      if (va && vb) {
        ++both;
        const double d = phase_a.at<float>(y, x) - phase_b.at<float>(y, x);
        sum += d;
        sum2 += d * d;
        worst = std::max(worst, std::abs(d));
      }
    }
  }
  const double rms = both > 0 ? std::sqrt(sum2 / static_cast<double>(both)) : INFINITY;
  const double mismatch_fraction =
      static_cast<double>(mismatch) / static_cast<double>(std::max(valid_a, 1L));
  std::cout << "valid " << valid_a << " / " << valid_b << " pixels, " << mismatch
            << " differ in validity (" << mismatch_fraction * 100 << " %); absolute phase: RMS "
            << rms << " rad, mean " << (both > 0 ? sum / static_cast<double>(both) : 0.0)
            << " rad, largest " << worst << " rad\n";
  return rms <= std::stod(a.get("max-rms")) &&
                 mismatch_fraction <= std::stod(a.get("max-mismatch")) && valid_a > 0
             ? 0
             : 1;
}

int runCalibration(const Args& a) {
  if (a.positional.size() != 1) throw std::invalid_argument("calibration PHASE --out FILE");
  const fs::path dir = a.positional[0];
  const cv::Mat phase = formats::readFloatTiff(dir / "absolute.tiff");
  const cv::Mat invalid = formats::readPng(dir / "invalid.png");
  float lo = std::numeric_limits<float>::infinity();
  float hi = -lo;
  for (int y = 0; y < phase.rows; ++y) {
    for (int x = 0; x < phase.cols; ++x) {
      if (invalid.at<std::uint8_t>(y, x) != 0) continue;
      lo = std::min(lo, phase.at<float>(y, x));
      hi = std::max(hi, phase.at<float>(y, x));
    }
  }
  if (!(hi > lo)) throw std::invalid_argument("no valid phase range in " + dir.string());
  const auto n = static_cast<std::size_t>(phase.total());
  std::vector<algo::PixelPolynomial> pixels(n);
  for (int y = 0; y < phase.rows; ++y) {
    for (int x = 0; x < phase.cols; ++x) {
      algo::PixelPolynomial& p =
          pixels[static_cast<std::size_t>(y) * static_cast<std::size_t>(phase.cols) +
                 static_cast<std::size_t>(x)];
      p.phase_centre = 0.5f * (lo + hi);
      p.phase_inv_half = 2.0f / (hi - lo);
      p.x[0] = 0.1f * static_cast<float>(x);
      p.y[0] = 0.1f * static_cast<float>(y);
      p.z[0] = 400.0f;
      p.z[1] = 20.0f;
    }
  }
  algo::QuasiCalibrationInfo info;
  info.pose_count = 14;
  info.min_poses = 6;
  const algo::QuasiCalibration calibration(phase.size(), std::vector<std::uint8_t>(n, 1),
                                           std::move(pixels), info);
  const std::vector<std::byte> bytes = calibration.serialize();
  formats::writeFileAtomically(a.get("out"), bytes);
  std::cout << phase.cols << "x" << phase.rows << ", phase " << lo << " to " << hi << " rad, "
            << bytes.size() << " bytes\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string cmd = argc > 1 ? argv[1] : "";
    const Args a = parse(argc, argv, 2);
    if (cmd == "run") return runFeeder(a);
    if (cmd == "angles") return runAngles(a);
    if (cmd == "compare") return runCompare(a);
    if (cmd == "calibration") return runCalibration(a);
    std::cerr << "usage: " << argv[0]
              << " run|angles|compare|calibration ... (see the source's header)\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "feeder: " << e.what() << "\n";
    return 1;
  }
}
