// SPDX-License-Identifier: Apache-2.0
// The live view's subscribers and the pictures they get. The head's worker
// asks which cameras are watched, takes one exposure of them, and hands each
// frame here; every subscriber that was waiting before that exposure began
// gets it as a JPEG (measured and overlaid as it asked, each variant encoded
// once). A subscriber keeps only the newest picture, so a slow client skips
// pictures and never holds up the head.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "firmware/daemon/head_service.hpp"
#include "firmware/live_picture.hpp"

namespace cylscan::firmware {

class LiveHub {
 public:
  LiveHub();
  ~LiveHub();  // ends every stream ("the daemon is stopping")
  LiveHub(const LiveHub&) = delete;
  LiveHub& operator=(const LiveHub&) = delete;

  // A new subscriber of `request.camera`; the caller checked the camera.
  std::unique_ptr<LiveStream> subscribe(const LiveViewRequest& request);

  // The cameras someone is waiting on, each once, in the order of `all`.
  std::vector<std::string> watched(const std::vector<std::string>& all) const;
  bool anyWatched() const;

  // Marks the start of one exposure: its pictures go to the subscribers
  // there are now, not to those that come while it is taken.
  std::uint64_t beginCapture();
  // One camera's frame of the capture `capture` (from beginCapture). A
  // frame that cannot be encoded ends that camera's streams with the reason.
  void deliver(std::uint64_t capture, const std::string& camera, const cv::Mat& frame,
               int bit_depth);
  // Ends the streams of `camera` (all cameras when empty) with `reason` and
  // its HTTP status (LiveStream::endStatus).
  void end(int status, const std::string& reason, const std::string& camera = {});

  // One subscriber's state, shared with its stream.
  struct Slot;

 private:
  std::vector<std::shared_ptr<Slot>> liveSlotsLocked() const;

  mutable std::mutex mutex_;
  mutable std::vector<std::weak_ptr<Slot>> slots_;
  std::uint64_t captures_ = 0;
  JpegEncoder encoder_;  // used by deliver() only, on the worker
};

}  // namespace cylscan::firmware
