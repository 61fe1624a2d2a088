// SPDX-License-Identifier: Apache-2.0
#include "drivers/camera_v4l2.hpp"

#include <cerrno>
#include <ctime>
#include <exception>
#include <system_error>
#include <utility>

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>

#include "drivers/v4l2_logic.hpp"

namespace cylscan::drivers {

namespace {

constexpr unsigned int kBufferCount = 4;

std::chrono::nanoseconds monotonicNow() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return std::chrono::seconds(ts.tv_sec) + std::chrono::nanoseconds(ts.tv_nsec);
}

std::string formatList(const std::vector<std::uint32_t>& fourccs) {
  std::string out;
  for (std::uint32_t f : fourccs) {
    if (!out.empty()) out += ", ";
    out += fourccName(f);
  }
  return out.empty() ? std::string("none") : out;
}

}  // namespace

V4l2Camera::V4l2Camera(std::string name, std::filesystem::path device)
    : name_(std::move(name)), device_(std::move(device)) {
  fd_.reset(::open(device_.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC));
  if (!fd_.valid()) failErrno("cannot open the device");
  v4l2_capability cap{};
  if (ioctlRetry(fd_.get(), VIDIOC_QUERYCAP, &cap) != 0) failErrno("VIDIOC_QUERYCAP");
  const std::uint32_t caps =
      (cap.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? cap.device_caps : cap.capabilities;
  if ((caps & V4L2_CAP_VIDEO_CAPTURE) == 0) {
    fail((caps & V4L2_CAP_VIDEO_CAPTURE_MPLANE) != 0
             ? "is a multi-planar capture device, which this backend does not support"
             : "is not a video capture device");
  }
  if ((caps & V4L2_CAP_STREAMING) == 0) fail("does not support streaming I/O");
}

V4l2Camera::~V4l2Camera() {
  try {
    stop();
  } catch (const std::exception&) {
    // Closing the device stops the stream and frees the buffers anyway.
  }
}

void V4l2Camera::fail(const std::string& what) const {
  throw CameraError("camera '" + name_ + "' (v4l2 " + device_.string() + "): " + what);
}

void V4l2Camera::failErrno(const std::string& what) const {
  const int err = errno;
  fail(what + ": " + std::generic_category().message(err));
}

void V4l2Camera::configure(const CameraConfig& config) {
  if (streaming_) fail("configure while started");
  if (config.trigger == TriggerMode::Software) {
    fail(
        "V4L2 has no software trigger; use trigger = \"gpio\" (the sensor in external-trigger "
        "mode) or \"free\"");
  }
  negotiated_ = V4l2Negotiated{};
  setFormat(config);
  setControls(config);
  config_ = config;
}

void V4l2Camera::setFormat(const CameraConfig& config) {
  std::vector<std::uint32_t> fourccs;
  std::vector<MonoFormat> offered;
  for (std::uint32_t i = 0;; ++i) {
    v4l2_fmtdesc desc{};
    desc.index = i;
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (ioctlRetry(fd_.get(), VIDIOC_ENUM_FMT, &desc) != 0) {
      if (errno == EINVAL) break;
      failErrno("VIDIOC_ENUM_FMT");
    }
    fourccs.push_back(desc.pixelformat);
    if (auto f = v4l2MonoFormat(desc.pixelformat)) offered.push_back(*f);
  }
  const std::optional<std::size_t> choice = chooseMonoFormat(offered, config.bit_depth);
  if (!choice) {
    fail("offers no monochrome format (GREY, Y10, Y12, Y16, Y10P, Y12P); it offers " +
         formatList(fourccs));
  }
  const MonoFormat& want = offered[*choice];

  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (ioctlRetry(fd_.get(), VIDIOC_G_FMT, &fmt) != 0) failErrno("VIDIOC_G_FMT");
  if (config.width > 0) fmt.fmt.pix.width = static_cast<std::uint32_t>(config.width);
  if (config.height > 0) fmt.fmt.pix.height = static_cast<std::uint32_t>(config.height);
  fmt.fmt.pix.pixelformat = v4l2Fourcc(want);
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  fmt.fmt.pix.bytesperline = 0;  // let the driver choose
  if (ioctlRetry(fd_.get(), VIDIOC_S_FMT, &fmt) != 0) failErrno("VIDIOC_S_FMT " + want.name);
  if (fmt.fmt.pix.pixelformat != v4l2Fourcc(want)) {
    fail("asked for " + want.name + ", the driver set " + fourccName(fmt.fmt.pix.pixelformat));
  }
  const auto width = static_cast<int>(fmt.fmt.pix.width);
  const auto height = static_cast<int>(fmt.fmt.pix.height);
  if ((config.width > 0 && width != config.width) ||
      (config.height > 0 && height != config.height)) {
    fail("asked for " + std::to_string(config.width) + "x" + std::to_string(config.height) +
         ", the driver set " + std::to_string(width) + "x" + std::to_string(height));
  }
  const std::size_t row = minBytesPerLine(want.packing, width);
  negotiated_.format = want;
  negotiated_.width = width;
  negotiated_.height = height;
  negotiated_.stride = std::max<std::size_t>(fmt.fmt.pix.bytesperline, row);
  if (want.bits != config.bit_depth) {
    negotiated_.notes.push_back("bit depth " + std::to_string(config.bit_depth) + " not offered: " +
                                want.name + " gives " + std::to_string(want.bits) + " bits");
  }
}

void V4l2Camera::setControls(const CameraConfig& config) {
  auto query = [this](std::uint32_t id) -> std::optional<V4l2ControlRange> {
    v4l2_queryctrl q{};
    q.id = id;
    if (ioctlRetry(fd_.get(), VIDIOC_QUERYCTRL, &q) != 0) {
      if (errno == EINVAL) return std::nullopt;
      failErrno("VIDIOC_QUERYCTRL");
    }
    if ((q.flags & V4L2_CTRL_FLAG_DISABLED) != 0) return std::nullopt;
    return V4l2ControlRange{q.minimum, q.maximum, q.step, q.default_value};
  };
  auto set = [this](std::uint32_t id, std::int64_t value, const char* what) {
    v4l2_control c{};
    c.id = id;
    c.value = static_cast<std::int32_t>(value);
    if (ioctlRetry(fd_.get(), VIDIOC_S_CTRL, &c) != 0) {
      failErrno(std::string("setting ") + what + " to " + std::to_string(value));
    }
  };

  // The value the device holds, for a control left to it; its default when
  // the driver does not say (a write-only control, say).
  auto get = [this](std::uint32_t id, const V4l2ControlRange& range) {
    v4l2_control c{};
    c.id = id;
    if (ioctlRetry(fd_.get(), VIDIOC_G_CTRL, &c) != 0) return range.default_value;
    return static_cast<std::int64_t>(c.value);
  };

  // Queried whether or not exposure_us is set, for controls().
  const std::optional<V4l2ControlRange> range = query(V4L2_CID_EXPOSURE_ABSOLUTE);
  if (config.exposure_us <= 0) {
    if (range) {
      negotiated_.controls.exposure_us =
          v4l2ExposureControl(get(V4L2_CID_EXPOSURE_ABSOLUTE, *range), *range);
    }
  } else {
    if (!range) fail("has no V4L2_CID_EXPOSURE_ABSOLUTE control to set exposure_us");
    if (query(V4L2_CID_EXPOSURE_AUTO)) {
      set(V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL, "V4L2_CID_EXPOSURE_AUTO");
    }
    const ControlValue v = clampToRange(exposureUsToV4l2(config.exposure_us), *range);
    set(V4L2_CID_EXPOSURE_ABSOLUTE, v.value, "V4L2_CID_EXPOSURE_ABSOLUTE");
    negotiated_.exposure_us = v4l2ExposureToUs(v.value);
    negotiated_.controls.exposure_us = v4l2ExposureControl(v.value, *range);
    if (v.clamped) {
      negotiated_.notes.push_back("exposure " + std::to_string(config.exposure_us) +
                                  " µs clamped to " + std::to_string(negotiated_.exposure_us) +
                                  " µs (device range " +
                                  std::to_string(v4l2ExposureToUs(range->minimum)) + " to " +
                                  std::to_string(v4l2ExposureToUs(range->maximum)) + " µs)");
    }
  }

  std::uint32_t gain_id = V4L2_CID_GAIN;
  std::optional<V4l2ControlRange> gain = query(gain_id);
  if (!gain) {
    gain_id = V4L2_CID_ANALOGUE_GAIN;
    gain = query(gain_id);
  }
  if (!gain) {
    if (config.gain != 1.0) fail("has no V4L2_CID_GAIN or V4L2_CID_ANALOGUE_GAIN control");
    negotiated_.controls.gain = {1.0, 1.0, 1.0};
    return;
  }
  std::int64_t requested = 0;
  try {
    requested = gainToV4l2(config.gain, *gain);
  } catch (const std::invalid_argument& e) {
    fail(e.what());
  }
  const ControlValue v = clampToRange(requested, *gain);
  set(gain_id, v.value, "the gain control");
  negotiated_.gain_value = v.value;
  negotiated_.controls.gain = v4l2GainControl(v.value, *gain);
  if (v.clamped) {
    negotiated_.notes.push_back("gain control value " + std::to_string(requested) + " clamped to " +
                                std::to_string(v.value) + " (device range " +
                                std::to_string(gain->minimum) + " to " +
                                std::to_string(gain->maximum) + ")");
  }
}

void V4l2Camera::start() {
  if (streaming_) return;
  if (!config_) fail("start before configure");
  v4l2_requestbuffers req{};
  req.count = kBufferCount;
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (ioctlRetry(fd_.get(), VIDIOC_REQBUFS, &req) != 0) failErrno("VIDIOC_REQBUFS");
  if (req.count < 2) fail("the driver gave " + std::to_string(req.count) + " buffers, need 2");
  try {
    for (std::uint32_t i = 0; i < req.count; ++i) {
      v4l2_buffer buf{};
      buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buf.memory = V4L2_MEMORY_MMAP;
      buf.index = i;
      if (ioctlRetry(fd_.get(), VIDIOC_QUERYBUF, &buf) != 0) failErrno("VIDIOC_QUERYBUF");
      try {
        buffers_.emplace_back(fd_.get(), buf.length, static_cast<off_t>(buf.m.offset), false,
                              device_.string() + " buffer " + std::to_string(i));
      } catch (const std::system_error& e) {
        fail(e.what());
      }
    }
    queueAll();
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (ioctlRetry(fd_.get(), VIDIOC_STREAMON, &type) != 0) failErrno("VIDIOC_STREAMON");
  } catch (...) {
    releaseBuffers();
    throw;
  }
  streaming_ = true;
  sequence_ = SequenceCounter{};
}

void V4l2Camera::queueAll() {
  for (std::size_t i = 0; i < buffers_.size(); ++i) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = static_cast<std::uint32_t>(i);
    if (ioctlRetry(fd_.get(), VIDIOC_QBUF, &buf) != 0) failErrno("VIDIOC_QBUF");
  }
}

void V4l2Camera::releaseBuffers() {
  buffers_.clear();
  v4l2_requestbuffers req{};
  req.count = 0;
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  ioctlRetry(fd_.get(), VIDIOC_REQBUFS,
             &req);  // frees the driver's buffers; nothing to do on error
}

void V4l2Camera::stop() {
  if (!streaming_) return;
  streaming_ = false;
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  const int r = ioctlRetry(fd_.get(), VIDIOC_STREAMOFF, &type);
  const int err = errno;
  releaseBuffers();
  if (r != 0) fail(std::string("VIDIOC_STREAMOFF: ") + std::generic_category().message(err));
}

void V4l2Camera::restartStream() {
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  // STREAMOFF returns every buffer to the application, queued or done.
  if (ioctlRetry(fd_.get(), VIDIOC_STREAMOFF, &type) != 0) failErrno("restart: VIDIOC_STREAMOFF");
  queueAll();
  if (ioctlRetry(fd_.get(), VIDIOC_STREAMON, &type) != 0) failErrno("restart: VIDIOC_STREAMON");
  sequence_.restart();
}

void V4l2Camera::requestFrame() {
  fail("V4L2 has no software trigger (requestFrame)");
}

std::optional<Frame> V4l2Camera::dequeue() {
  v4l2_buffer buf{};
  buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  buf.memory = V4L2_MEMORY_MMAP;
  if (ioctlRetry(fd_.get(), VIDIOC_DQBUF, &buf) != 0) {
    if (errno == EAGAIN) return std::nullopt;
    failErrno("VIDIOC_DQBUF");
  }
  const std::chrono::nanoseconds dequeued = monotonicNow();
  auto requeue = [&] {
    if (ioctlRetry(fd_.get(), VIDIOC_QBUF, &buf) != 0) failErrno("VIDIOC_QBUF");
  };
  if (buf.index >= buffers_.size()) fail("VIDIOC_DQBUF returned an unknown buffer index");
  if ((buf.flags & V4L2_BUF_FLAG_ERROR) != 0) {
    requeue();  // a corrupt frame is a lost frame: the sequence shows the gap
    return std::nullopt;
  }
  Frame frame;
  std::span<const std::uint8_t> data = buffers_[buf.index].bytes();
  if (buf.bytesused > 0 && buf.bytesused < data.size()) data = data.first(buf.bytesused);
  try {
    frame.image = unpackMono(data, negotiated_.width, negotiated_.height, negotiated_.stride,
                             negotiated_.format.packing, negotiated_.format.bits);
  } catch (const std::invalid_argument& e) {
    requeue();
    fail(e.what());
  }
  frame.sequence = sequence_.next(buf.sequence);
  const bool monotonic =
      (buf.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
  const std::chrono::nanoseconds stamp = monotonic
                                             ? std::chrono::seconds(buf.timestamp.tv_sec) +
                                                   std::chrono::microseconds(buf.timestamp.tv_usec)
                                             : dequeued;
  const bool soe = (buf.flags & V4L2_BUF_FLAG_TSTAMP_SRC_MASK) == V4L2_BUF_FLAG_TSTAMP_SRC_SOE;
  frame.timestamp = exposureStart(stamp, soe && monotonic, negotiated_.exposure_us);
  requeue();
  return frame;
}

std::optional<Frame> V4l2Camera::waitFrame(std::chrono::nanoseconds timeout) {
  if (!streaming_) fail("waitFrame before start");
  const std::chrono::nanoseconds deadline = monotonicNow() + timeout;
  bool restarted = false;
  for (;;) {
    const std::chrono::nanoseconds left =
        std::max(deadline - monotonicNow(), std::chrono::nanoseconds(0));
    timespec ts{};
    ts.tv_sec = static_cast<time_t>(left.count() / 1'000'000'000);
    ts.tv_nsec = static_cast<long>(left.count() % 1'000'000'000);
    pollfd pfd{fd_.get(), POLLIN, 0};
    const int r = ::ppoll(&pfd, 1, &ts, nullptr);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) failErrno("poll");
    if (r == 0) {
      if (timeout > std::chrono::nanoseconds(0) && !restarted) restartStream();
      return std::nullopt;
    }
    try {
      if ((pfd.revents & POLLERR) != 0) fail("the stream reported an error (POLLERR)");
      if (std::optional<Frame> f = dequeue()) return f;
    } catch (const CameraError&) {
      if (restarted) throw;
      restartStream();
      restarted = true;
    }
    if (monotonicNow() >= deadline) return std::nullopt;
  }
}

}  // namespace cylscan::drivers
