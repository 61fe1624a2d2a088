// SPDX-License-Identifier: Apache-2.0
#include "drivers/camera_libcamera.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <system_error>
#include <utility>

#include <libcamera/libcamera.h>

#include "drivers/libcamera_logic.hpp"
#include "drivers/posix_io.hpp"

namespace cylscan::drivers {

namespace lc = libcamera;

namespace {

constexpr std::size_t kMaxQueuedFrames = 8;  // older frames are dropped: a sequence gap
constexpr unsigned int kMinBuffers = 4;

// libcamera allows one CameraManager per process: the cameras share it, and
// the last one to go stops it.
struct ManagerHolder {
  lc::CameraManager manager;
  bool started = false;
  ~ManagerHolder() {
    if (started) manager.stop();
  }
};

std::shared_ptr<lc::CameraManager> sharedManager() {
  static std::mutex mutex;
  static std::weak_ptr<lc::CameraManager> weak;
  const std::lock_guard lock(mutex);
  if (auto m = weak.lock()) return m;
  auto holder = std::make_shared<ManagerHolder>();
  if (const int r = holder->manager.start(); r != 0) {
    throw CameraError(std::string("libcamera: cannot start the camera manager: ") +
                      std::generic_category().message(-r));
  }
  holder->started = true;
  std::shared_ptr<lc::CameraManager> manager(holder, &holder->manager);
  weak = manager;
  return manager;
}

// A bound of a ControlInfo as a number; nullopt when the camera gives none,
// or one of another type than T.
template <typename T>
std::optional<double> bound(const lc::ControlValue& v) {
  if (v.isNone() || v.isArray() || v.type() != lc::details::control_type<T>::value) {
    return std::nullopt;
  }
  return static_cast<double>(v.get<T>());
}

bool isIndex(const std::string& s) {
  return !s.empty() && s.size() < 4 &&
         std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c) != 0; });
}

}  // namespace

struct LibcameraCamera::Impl {
  std::string name;
  std::string id;
  std::shared_ptr<lc::CameraManager> manager;
  std::shared_ptr<lc::Camera> camera;
  std::unique_ptr<lc::CameraConfiguration> configuration;
  std::optional<CameraConfig> config;
  LibcameraNegotiated negotiated;
  std::optional<std::int32_t> exposure;  // µs, to set in every request
  std::optional<float> gain;
  bool has_ae = false;

  std::unique_ptr<lc::FrameBufferAllocator> allocator;
  std::vector<std::unique_ptr<lc::Request>> requests;
  std::map<const lc::FrameBuffer*, MemoryMap> maps;

  // Shared with libcamera's completion thread.
  std::mutex mutex;
  std::condition_variable ready;
  bool running = false;
  std::deque<Frame> frames;
  std::vector<lc::Request*> idle;  // Software: requests waiting for requestFrame()
  std::optional<std::string> error;
  SequenceCounter sequence;

  [[noreturn]] void fail(const std::string& what) const {
    throw CameraError("camera '" + name + "' (libcamera " + id + "): " + what);
  }

  void setControls(lc::ControlList& list) const {
    if (has_ae) list.set(lc::controls::AeEnable, false);
    if (exposure) list.set(lc::controls::ExposureTime, *exposure);
    if (gain) list.set(lc::controls::AnalogueGain, *gain);
  }

  // Copies the frame of a completed request; called with `mutex` held.
  void takeFrame(lc::Request* request) {
    const auto& buffers = request->buffers();
    if (buffers.empty()) return;
    const lc::FrameBuffer* buffer = buffers.begin()->second;
    const lc::FrameMetadata& md = buffer->metadata();
    if (md.status != lc::FrameMetadata::FrameSuccess) return;  // lost: a sequence gap
    const auto map = maps.find(buffer);
    if (map == maps.end()) return;
    Frame frame;
    try {
      frame.image =
          unpackMono(map->second.bytes(), negotiated.width, negotiated.height, negotiated.stride,
                     negotiated.format.packing, negotiated.format.bits);
    } catch (const std::invalid_argument& e) {
      error = e.what();
      return;
    }
    frame.sequence = sequence.next(md.sequence);
    // Pipeline handlers fill SensorTimestamp from the V4L2 buffer time, CLOCK_MONOTONIC.
    const std::optional<std::int64_t> stamp =
        request->metadata().get(lc::controls::SensorTimestamp);
    frame.timestamp =
        std::chrono::nanoseconds(stamp ? *stamp : static_cast<std::int64_t>(md.timestamp));
    if (frames.size() == kMaxQueuedFrames) frames.pop_front();
    frames.push_back(std::move(frame));
  }

  // libcamera's completion thread.
  void onRequestCompleted(lc::Request* request) {
    {
      const std::lock_guard lock(mutex);
      if (request->status() == lc::Request::RequestComplete) takeFrame(request);
      request->reuse(lc::Request::ReuseBuffers);
      if (running && config && config->trigger != TriggerMode::Software) {
        setControls(request->controls());
        if (camera->queueRequest(request) != 0) error = "cannot requeue a request";
      } else {
        idle.push_back(request);
      }
    }
    ready.notify_all();
  }
};

LibcameraCamera::LibcameraCamera(std::string name, std::string id)
    : impl_(std::make_unique<Impl>()) {
  impl_->name = std::move(name);
  impl_->id = std::move(id);
  impl_->manager = sharedManager();
  impl_->camera = impl_->manager->get(impl_->id);
  const auto cameras = impl_->manager->cameras();
  if (!impl_->camera && isIndex(impl_->id)) {
    const auto index = static_cast<std::size_t>(std::stoi(impl_->id));
    if (index < cameras.size()) impl_->camera = cameras[index];
  }
  if (!impl_->camera) {
    std::string list;
    for (const auto& c : cameras)
      list += (list.empty() ? "" : ", ") + c->id();
    impl_->fail("no such camera (libcamera sees: " + (list.empty() ? "none" : list) + ")");
  }
  if (impl_->camera->acquire() != 0) impl_->fail("cannot acquire the camera (in use?)");
}

LibcameraCamera::~LibcameraCamera() {
  try {
    stop();
  } catch (const std::exception&) {
    // The camera is released below either way.
  }
  impl_->camera->release();
}

std::string LibcameraCamera::name() const {
  return impl_->name;
}

const LibcameraNegotiated& LibcameraCamera::negotiated() const {
  return impl_->negotiated;
}

CameraControls LibcameraCamera::controls() const {
  return impl_->negotiated.controls;
}

void LibcameraCamera::configure(const CameraConfig& config) {
  Impl& m = *impl_;
  if (m.running) m.fail("configure while started");
  m.negotiated = LibcameraNegotiated{};
  m.configuration = m.camera->generateConfiguration({lc::StreamRole::Raw});
  if (!m.configuration || m.configuration->empty()) m.fail("offers no raw stream");
  lc::StreamConfiguration& sc = m.configuration->at(0);

  std::vector<MonoFormat> offered;
  std::vector<lc::PixelFormat> pixel_formats;
  std::string all;
  for (const lc::PixelFormat& f : sc.formats().pixelformats()) {
    all += (all.empty() ? "" : ", ") + f.toString();
    if (auto mono = libcameraMonoFormat(f.toString())) {
      offered.push_back(*mono);
      pixel_formats.push_back(f);
    }
  }
  const std::optional<std::size_t> choice = chooseMonoFormat(offered, config.bit_depth);
  if (!choice) {
    m.fail(
        "offers no monochrome raw format (R8, R10, R12, R16, R10_CSI2P, R12_CSI2P); it "
        "offers " +
        (all.empty() ? std::string("none") : all));
  }
  sc.pixelFormat = pixel_formats[*choice];
  if (config.width > 0 && config.height > 0) {
    sc.size =
        lc::Size(static_cast<unsigned int>(config.width), static_cast<unsigned int>(config.height));
  }
  sc.bufferCount = std::max(sc.bufferCount, kMinBuffers);
  const lc::CameraConfiguration::Status status = m.configuration->validate();
  if (status == lc::CameraConfiguration::Invalid) m.fail("the configuration is invalid");
  if (sc.pixelFormat != pixel_formats[*choice]) {
    m.fail("asked for " + offered[*choice].name + ", the camera adjusted it to " +
           sc.pixelFormat.toString());
  }
  if ((config.width > 0 && sc.size.width != static_cast<unsigned int>(config.width)) ||
      (config.height > 0 && sc.size.height != static_cast<unsigned int>(config.height))) {
    m.fail("asked for " + std::to_string(config.width) + "x" + std::to_string(config.height) +
           ", the camera adjusted it to " + sc.size.toString());
  }
  if (const int r = m.camera->configure(m.configuration.get()); r != 0) {
    m.fail(std::string("cannot configure: ") + std::generic_category().message(-r));
  }
  m.negotiated.format = offered[*choice];
  m.negotiated.width = static_cast<int>(sc.size.width);
  m.negotiated.height = static_cast<int>(sc.size.height);
  m.negotiated.stride = sc.stride;
  if (offered[*choice].bits != config.bit_depth) {
    m.negotiated.notes.push_back("bit depth " + std::to_string(config.bit_depth) +
                                 " not offered: " + offered[*choice].name + " gives " +
                                 std::to_string(offered[*choice].bits) + " bits");
  }

  const lc::ControlInfoMap& controls = m.camera->controls();
  auto range = [&controls](const lc::ControlId& id) -> std::optional<lc::ControlInfo> {
    const auto it = controls.find(id.id());
    if (it == controls.end()) return std::nullopt;
    return it->second;
  };
  m.has_ae = range(lc::controls::AeEnable).has_value();
  m.exposure.reset();
  m.gain.reset();
  const auto exposure = range(lc::controls::ExposureTime);
  if (config.exposure_us > 0) {
    if (!exposure) m.fail("has no ExposureTime control to set exposure_us");
    const std::optional<double> lo = bound<std::int32_t>(exposure->min());
    const std::optional<double> hi = bound<std::int32_t>(exposure->max());
    const ClampedValue v = clampValue(config.exposure_us, lo, hi);
    m.exposure = static_cast<std::int32_t>(std::lround(v.value));
    m.negotiated.exposure_us = *m.exposure;
    m.negotiated.controls.exposure_us = libcameraControl(*m.exposure, lo, hi);
    if (v.clamped) {
      m.negotiated.notes.push_back("exposure " + std::to_string(config.exposure_us) +
                                   " µs clamped to " + std::to_string(*m.exposure) + " µs");
    }
  } else if (exposure) {
    // Left to the camera: its default is all that is known before a frame's metadata.
    m.negotiated.controls.exposure_us = libcameraControl(
        bound<std::int32_t>(exposure->def()).value_or(0.0), bound<std::int32_t>(exposure->min()),
        bound<std::int32_t>(exposure->max()));
  }
  if (const auto info = range(lc::controls::AnalogueGain)) {
    const std::optional<double> lo = bound<float>(info->min());
    const std::optional<double> hi = bound<float>(info->max());
    const ClampedValue v = clampValue(config.gain, lo, hi);
    m.gain = static_cast<float>(v.value);
    m.negotiated.gain = v.value;
    m.negotiated.controls.gain = libcameraControl(*m.gain, lo, hi);
    if (v.clamped) {
      m.negotiated.notes.push_back("gain " + std::to_string(config.gain) + " clamped to " +
                                   std::to_string(v.value));
    }
  } else if (config.gain != 1.0) {
    m.fail("has no AnalogueGain control to set gain");
  } else {
    m.negotiated.controls.gain = {1.0, 1.0, 1.0};
  }
  m.config = config;
}

void LibcameraCamera::start() {
  Impl& m = *impl_;
  if (m.running) return;
  if (!m.config) m.fail("start before configure");
  lc::Stream* stream = m.configuration->at(0).stream();
  m.allocator = std::make_unique<lc::FrameBufferAllocator>(m.camera);
  if (m.allocator->allocate(stream) < 0) m.fail("cannot allocate frame buffers");
  try {
    for (const auto& buffer : m.allocator->buffers(stream)) {
      std::unique_ptr<lc::Request> request = m.camera->createRequest();
      if (!request || request->addBuffer(stream, buffer.get()) != 0) {
        m.fail("cannot create a request");
      }
      const lc::FrameBuffer::Plane& plane = buffer->planes().front();
      try {
        m.maps.emplace(buffer.get(),
                       MemoryMap(plane.fd.get(), plane.length, static_cast<off_t>(plane.offset),
                                 false, "camera '" + m.name + "' buffer"));
      } catch (const std::system_error& e) {
        m.fail(e.what());
      }
      m.setControls(request->controls());
      m.requests.push_back(std::move(request));
    }
    m.camera->requestCompleted.connect(impl_.get(), &Impl::onRequestCompleted);
    lc::ControlList initial(lc::controls::controls);
    m.setControls(initial);
    {
      const std::lock_guard lock(m.mutex);
      m.frames.clear();
      m.idle.clear();
      m.error.reset();
      m.sequence = SequenceCounter{};
      m.running = true;
    }
    if (const int r = m.camera->start(&initial); r != 0) {
      m.fail(std::string("cannot start: ") + std::generic_category().message(-r));
    }
    const std::lock_guard lock(m.mutex);
    for (const auto& request : m.requests) {
      if (m.config->trigger == TriggerMode::Software) {
        m.idle.push_back(request.get());
      } else if (m.camera->queueRequest(request.get()) != 0) {
        m.fail("cannot queue a request");
      }
    }
  } catch (...) {
    stop();
    throw;
  }
}

void LibcameraCamera::stop() {
  Impl& m = *impl_;
  if (!m.allocator) return;
  bool was_running = false;
  {
    const std::lock_guard lock(m.mutex);
    was_running = m.running;
    m.running = false;
  }
  if (was_running) m.camera->stop();  // completes every queued request as cancelled
  m.camera->requestCompleted.disconnect(impl_.get());
  const std::lock_guard lock(m.mutex);
  m.idle.clear();
  m.frames.clear();
  m.requests.clear();
  m.maps.clear();
  m.allocator.reset();
}

void LibcameraCamera::requestFrame() {
  Impl& m = *impl_;
  if (!m.config || m.config->trigger != TriggerMode::Software) {
    m.fail("requestFrame needs trigger = \"software\"");
  }
  const std::lock_guard lock(m.mutex);
  if (!m.running) m.fail("requestFrame before start");
  if (m.idle.empty()) m.fail("busy: every request is in flight, frame request refused");
  lc::Request* request = m.idle.back();
  m.idle.pop_back();
  m.setControls(request->controls());
  if (m.camera->queueRequest(request) != 0) {
    m.idle.push_back(request);
    m.fail("cannot queue a request");
  }
}

std::optional<Frame> LibcameraCamera::waitFrame(std::chrono::nanoseconds timeout) {
  Impl& m = *impl_;
  std::unique_lock lock(m.mutex);
  if (!m.running) m.fail("waitFrame before start");
  m.ready.wait_for(lock, timeout, [&m] { return !m.frames.empty() || m.error.has_value(); });
  if (m.error) {
    const std::string what = *m.error;
    m.error.reset();
    m.fail(what);
  }
  if (m.frames.empty()) return std::nullopt;
  Frame f = std::move(m.frames.front());
  m.frames.pop_front();
  return f;
}

}  // namespace cylscan::drivers
