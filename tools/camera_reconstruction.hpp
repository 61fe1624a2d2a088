// SPDX-License-Identifier: Apache-2.0
// Shared by `reconstruct --calib-dir` and `calibrate-head` (the 360° head): each
// calibrated camera of a capture bundle reconstructed with its own
// quasi-calibration (DIR/<camera>.qcal) on its own fringe sets.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "firmware/bundle_phase.hpp"
#include "formats/capture_bundle.hpp"

namespace cylscan::tools {

struct CameraReconstruction {
  std::string camera;
  cv::Mat xyz;      // CV_32FC3 in the camera's own frame, NaN where invalid
  cv::Mat texture;  // CV_32F counts
  PhaseSource phase = PhaseSource::Fused;
  double phase_valid_fraction = 0;
  std::vector<std::string> warnings;  // firmware::orderDriftWarning's
  double phase_ms = 0;
  double reconstruct_ms = 0;
};

// DIR/<camera>.qcal.
std::filesystem::path calibrationFileOf(const std::filesystem::path& calib_dir,
                                        const std::string& camera);

// The cameras of the bundle that have a calibration in `calib_dir`, in the
// bundle's order. InputError naming the directory when it is not one.
std::vector<std::string> calibratedCameras(const formats::CaptureBundleReader& bundle,
                                           const std::filesystem::path& calib_dir);

// `camera` of the bundle by `calib_file`; `phase` empty = the calibration's own
// phase, else "high"/"fused", which must be the calibration's (InputError
// naming the file). InputError also when the image sizes differ.
CameraReconstruction reconstructCamera(const formats::CaptureBundleReader& bundle,
                                       const std::string& camera,
                                       const std::filesystem::path& calib_file,
                                       const std::string& phase = "");

}  // namespace cylscan::tools
