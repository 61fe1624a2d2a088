// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/live_hub.hpp"

#include <algorithm>
#include <condition_variable>
#include <optional>
#include <utility>

namespace cylscan::firmware {

struct LiveHub::Slot {
  LiveViewRequest request;
  std::uint64_t since = 0;  // the captures begun before it came

  std::mutex mutex;
  std::condition_variable cv;
  std::optional<LiveFrame> newest;
  std::uint64_t sequence = 0;
  std::string end_reason;  // non-empty once ended
  int end_status = 0;
};

namespace {

class HubStream final : public LiveStream {
 public:
  explicit HubStream(std::shared_ptr<LiveHub::Slot> slot) : slot_(std::move(slot)) {}

  std::optional<LiveFrame> next(std::chrono::milliseconds timeout) override {
    std::unique_lock lock(slot_->mutex);
    slot_->cv.wait_for(lock, timeout,
                       [&] { return slot_->newest.has_value() || !slot_->end_reason.empty(); });
    std::optional<LiveFrame> out = std::move(slot_->newest);
    slot_->newest.reset();
    return out;
  }
  bool ended() const override {
    std::lock_guard lock(slot_->mutex);
    return !slot_->end_reason.empty() && !slot_->newest;
  }
  std::string endReason() const override {
    std::lock_guard lock(slot_->mutex);
    return slot_->end_reason;
  }
  int endStatus() const override {
    std::lock_guard lock(slot_->mutex);
    return slot_->end_status;
  }

 private:
  std::shared_ptr<LiveHub::Slot> slot_;
};

void endSlot(LiveHub::Slot& slot, int status, const std::string& reason) {
  std::lock_guard lock(slot.mutex);
  if (slot.end_reason.empty()) {
    slot.end_reason = reason;
    slot.end_status = status;
  }
  slot.cv.notify_all();
}

}  // namespace

LiveHub::LiveHub() = default;

LiveHub::~LiveHub() {
  try {
    end(503, "the daemon is stopping");
  } catch (...) {  // no stream is left waiting: each holds its slot, not the hub
  }
}

std::unique_ptr<LiveStream> LiveHub::subscribe(const LiveViewRequest& request) {
  auto slot = std::make_shared<Slot>();
  slot->request = request;
  std::lock_guard lock(mutex_);
  slot->since = captures_;
  slots_.push_back(slot);
  return std::make_unique<HubStream>(std::move(slot));
}

std::vector<std::shared_ptr<LiveHub::Slot>> LiveHub::liveSlotsLocked() const {
  std::erase_if(slots_, [](const std::weak_ptr<Slot>& w) { return w.expired(); });
  std::vector<std::shared_ptr<Slot>> out;
  for (const auto& w : slots_) {
    auto slot = w.lock();
    if (!slot) continue;
    std::lock_guard lock(slot->mutex);
    if (slot->end_reason.empty()) out.push_back(std::move(slot));
  }
  return out;
}

std::vector<std::string> LiveHub::watched(const std::vector<std::string>& all) const {
  std::lock_guard lock(mutex_);
  const auto slots = liveSlotsLocked();
  std::vector<std::string> out;
  for (const std::string& camera : all) {
    const bool wanted = std::any_of(slots.begin(), slots.end(), [&](const auto& slot) {
      return slot->request.camera == camera;
    });
    if (wanted) out.push_back(camera);
  }
  return out;
}

bool LiveHub::anyWatched() const {
  std::lock_guard lock(mutex_);
  return !liveSlotsLocked().empty();
}

std::uint64_t LiveHub::beginCapture() {
  std::lock_guard lock(mutex_);
  return ++captures_;
}

void LiveHub::deliver(std::uint64_t capture, const std::string& camera, const cv::Mat& frame,
                      int bit_depth) {
  std::vector<std::shared_ptr<Slot>> slots;
  {
    std::lock_guard lock(mutex_);
    for (auto& slot : liveSlotsLocked()) {
      if (slot->request.camera == camera && slot->since < capture) slots.push_back(std::move(slot));
    }
  }
  if (slots.empty()) return;
  // Each variant (plain, overlaid) is measured and encoded once.
  std::optional<LivePicture> variants[2];
  try {
    for (const auto& slot : slots) {
      const int v = slot->request.saturation_overlay ? 1 : 0;
      if (!variants[v]) variants[v] = livePicture(frame, bit_depth, v == 1, encoder_);
    }
  } catch (const std::exception& e) {
    end(503, std::string("the camera's frame cannot be shown: ") + e.what(), camera);
    return;
  }
  for (const auto& slot : slots) {
    const LivePicture& picture = *variants[slot->request.saturation_overlay ? 1 : 0];
    std::lock_guard lock(slot->mutex);
    LiveFrame out;
    out.sequence = ++slot->sequence;
    out.jpeg = picture.jpeg;
    out.focus = picture.measures.focus;
    out.saturated = picture.measures.saturated;
    slot->newest = std::move(out);
    slot->cv.notify_all();
  }
}

void LiveHub::end(int status, const std::string& reason, const std::string& camera) {
  std::vector<std::shared_ptr<Slot>> slots;
  {
    std::lock_guard lock(mutex_);
    slots = liveSlotsLocked();
  }
  for (const auto& slot : slots) {
    if (camera.empty() || slot->request.camera == camera) endSlot(*slot, status, reason);
  }
}

}  // namespace cylscan::firmware
