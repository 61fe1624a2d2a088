// SPDX-License-Identifier: Apache-2.0
// Where the acquisition loop hands each frame as it arrives: the phase engine
// (streaming: no scan holds its frames), the capture bundle writer, a preview.
#pragma once

#include <string_view>

#include <opencv2/core.hpp>

#include "formats/capture_bundle.hpp"

namespace cylscan::firmware {

class FrameSink {
 public:
  virtual ~FrameSink() = default;
  // Frame k of a set from `camera`, exposed at the executed stage angle
  // `stage_deg`. `set` is the camera's own set (ScanPlan::setOf: with a ring
  // plan, a camera facing the low half in sweep 1 gets its low set first).
  // Frames of one set all come before the other set's.
  virtual void onFrame(std::string_view camera, FringeSet set, int k, double stage_deg,
                       const cv::Mat& image) = 0;
};

}  // namespace cylscan::firmware
