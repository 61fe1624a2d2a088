// SPDX-License-Identifier: Apache-2.0
// The phase engine run over one camera of a capture bundle, frames streamed
// from disk one at a time (none is kept): the calibration solve's plane poses
// and the command line's bundles.
#pragma once

#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "algo/one_set_phase.hpp"
#include "algo/phase_engine.hpp"
#include "firmware/reconstruction.hpp"
#include "formats/capture_bundle.hpp"

namespace cylscan::firmware {

struct BundlePhaseOptions {
  int bit_depth = 0;           // 16-bit frames: 0 = capture.json bit_depth, else 16
  double min_modulation = -1;  // counts; -1 = the engine's default
  bool reference = false;      // the double reference path instead of fixed point
  // The centre the orders are numbered about (algo::PhaseOptions::order_reference_rad).
  std::optional<double> order_reference_rad;
};

struct BundlePhase {
  algo::PhaseMaps maps;
  cv::Size size;
  int bit_depth = 8;  // as resolved for the frames
  double read_ms = 0;
  double fold_ms = 0;
  double finalize_ms = 0;
};

// The phase of a one-set bundle (formats::SetsRequired::OneOrBoth): the
// wrapped phase of the set it has, nothing absolute.
struct BundleSetPhase {
  FringeSet set = FringeSet::High;
  algo::OneSetMaps maps;
  cv::Size size;
  int bit_depth = 8;  // as resolved for the frames
  double read_ms = 0;
  double fold_ms = 0;
  double finalize_ms = 0;
};

// Runs the engine over all frames of `camera`, with the camera's own sets
// (formats::CaptureInfo::setOf: a ring scan's "camera_sets"). InputError naming capture.json
// when the camera is missing, lacks a set or the angles are unusable, naming the
// frame when a frame is bad.
BundlePhase computeBundlePhase(const formats::CaptureBundleReader& bundle,
                               const std::string& camera, const BundlePhaseOptions& options = {});

// The one set `camera` has when the bundle lacks the other (a reader with
// formats::SetsRequired::OneOrBoth); nullopt when it has both. InputError
// naming capture.json for a camera the bundle does not have.
std::optional<FringeSet> onlySetOf(const formats::CaptureBundleReader& bundle,
                                   const std::string& camera);

// The wrapped phase of `camera`'s set `set` alone, with the same fold and the
// same errors as computeBundlePhase; options.order_reference_rad is unused.
BundleSetPhase computeBundleSetPhase(const formats::CaptureBundleReader& bundle,
                                     const std::string& camera, FringeSet set,
                                     const BundlePhaseOptions& options = {});

// InputError naming capture.json unless the bundle has `camera`.
void requireCamera(const formats::CaptureBundleReader& bundle, const std::string& camera);

}  // namespace cylscan::firmware
