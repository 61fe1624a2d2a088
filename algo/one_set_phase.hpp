// SPDX-License-Identifier: Apache-2.0
// The wrapped phase of a single fringe set, without unwrapping: what a bundle
// recorded with one pattern set gives (docs/formats.md, capture bundle). The
// least squares, the fold and the atan2 are PhaseEngine's own, so the maps
// equal the engine's maps of that set bit for bit (fixed-point path) or to
// double rounding (reference path); only the texture differs, being this
// set's A instead of the mean of both sets'.
#pragma once

#include <memory>
#include <opencv2/core.hpp>

#include "algo/fringe_set.hpp"
#include "algo/phase_engine.hpp"

namespace cylscan::algo {

struct OneSetMaps {
  cv::Mat wrapped;     // CV_32FC1, φ of the set in radians in [0, 2π)
  cv::Mat modulation;  // CV_32FC1, B in counts
  cv::Mat texture;     // CV_32FC1, A of the set in counts
  // CV_8UC1, InvalidReason bits: kLowModulation and kSaturated only (no order
  // is taken, so none can be inconsistent); 0 = valid.
  cv::Mat invalid;
  double valid_fraction = 0;
};

class OneSetPhase {
 public:
  // `set` names the set in messages and in fold's errors. Throws as PhaseEngine's
  // constructor does (ShiftSolveError naming the set, std::invalid_argument).
  OneSetPhase(cv::Size size, FringeSet set, const FringeSetGeometry& geometry,
              const PhaseOptions& options = {});
  ~OneSetPhase();
  OneSetPhase(OneSetPhase&&) noexcept;
  OneSetPhase& operator=(OneSetPhase&&) noexcept;
  OneSetPhase(const OneSetPhase&) = delete;
  OneSetPhase& operator=(const OneSetPhase&) = delete;

  // As PhaseEngine::fold for frame k of the set: each frame exactly once, in any order.
  void fold(int k, const cv::Mat& frame);
  OneSetMaps finalize() const;  // std::logic_error if frames are missing

  FringeSet set() const;
  int frameCount() const;
  const PhaseOptions& options() const;  // with every default resolved

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cylscan::algo
