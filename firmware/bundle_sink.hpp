// SPDX-License-Identifier: Apache-2.0
// Saving the raw frames of a scan as a capture bundle (docs/formats.md), with the
// executed angles; optional, since the streaming fold needs no frames kept.
// The bundle's capture.json is written last (commit), so an interrupted scan
// never leaves a bundle that reads as complete.
#pragma once

#include <filesystem>
#include <memory>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "firmware/frame_sink.hpp"
#include "firmware/scan_plan.hpp"
#include "formats/capture_bundle.hpp"

namespace cylscan::firmware {

// The top-level sets are main's; a camera whose angles differ (a ring plan's
// cameras facing the other half in sweep 1) gets the extension "camera_sets",
// and a ring plan writes "plan": "ring" and "ring": its RingLayout
// ({start_deg, sweep2_start_deg, step_deg, step_steps, frames, noise_gain,
// cameras: {name: first sweep's set}, margins_deg}).
class BundleSink final : public FrameSink {
 public:
  BundleSink(const std::filesystem::path& dir, const ScanPlan& plan,
             const std::vector<std::string>& cameras, nlohmann::json extra);
  void onFrame(std::string_view camera, FringeSet set, int k, double stage_deg,
               const cv::Mat& image) override;
  void commit();

 private:
  formats::CaptureBundleWriter writer_;
};

// A ring layout as JSON (capture.json's "ring", `cylscan scan --json`).
nlohmann::json ringLayoutJson(const RingLayout& ring);

// Hands every frame to several sinks, in order.
class TeeSink final : public FrameSink {
 public:
  void add(FrameSink& sink) { sinks_.push_back(&sink); }
  void onFrame(std::string_view camera, FringeSet set, int k, double stage_deg,
               const cv::Mat& image) override {
    for (FrameSink* sink : sinks_)
      sink->onFrame(camera, set, k, stage_deg, image);
  }

 private:
  std::vector<FrameSink*> sinks_;
};

}  // namespace cylscan::firmware
