// SPDX-License-Identifier: Apache-2.0
// The streaming reconstruction of a scan: one phase engine per camera, each
// frame folded as it arrives (the engine keeps 16 bytes a pixel, not frames),
// so a K-camera scan holds O(K × pixels).
#pragma once

#include <cstddef>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "algo/phase_engine.hpp"
#include "firmware/frame_sink.hpp"
#include "firmware/scan_plan.hpp"

namespace cylscan::firmware {

class PhaseSink final : public FrameSink {
 public:
  // An engine per camera, made at the camera's first frame (its size), for
  // that camera's executed angles of `plan` (ScanPlan::anglesDeg(camera, set):
  // with a ring plan each camera has its own) and the sets' periods. A
  // camera's frames of either set may come first. `plan` must outlive the sink.
  PhaseSink(const ScanPlan& plan, const algo::PhaseOptions& options);

  // std::logic_error when the frame's angle is not the plan's for that
  // camera's set; the engine's own errors pass through.
  void onFrame(std::string_view camera, FringeSet set, int k, double stage_deg,
               const cv::Mat& image) override;

  // The maps of a camera once every frame was folded; std::logic_error before.
  // `order_reference`: the order-residual centre of the calibration the maps
  // are used with (algo::PhaseOptions::order_reference_rad).
  algo::PhaseMaps finalize(std::string_view camera,
                           std::optional<double> order_reference = std::nullopt);
  algo::CompactPhase finalizeCompact(std::string_view camera,
                                     std::optional<double> order_reference = std::nullopt);
  int folded(std::string_view camera) const;
  cv::Size frameSize(std::string_view camera) const;  // the size of its frames
  // The engines' working state, all cameras (O(K × pixels): no frame is kept).
  std::size_t workingStateBytes() const;
  // A camera's engine options with every default resolved.
  const algo::PhaseOptions& options(std::string_view camera) const;
  // The geometry a camera's engine uses (its own angles, the set's period).
  algo::FringeSetGeometry geometry(std::string_view camera, FringeSet set) const;

 private:
  struct Camera {
    algo::FringeSetGeometry high, low;
    algo::PhaseEngine engine;
    int folded = 0;
  };
  Camera& camera(std::string_view name);
  const Camera& camera(std::string_view name) const;

  const ScanPlan& plan_;
  algo::PhaseOptions options_;
  std::map<std::string, Camera, std::less<>> cameras_;
};

}  // namespace cylscan::firmware
