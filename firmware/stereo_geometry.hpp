// SPDX-License-Identifier: Apache-2.0
// The stereo calibration file (docs/formats.md, stereo calibration file) as
// the algorithms' geometry, and back.
#pragma once

#include <filesystem>

#include <opencv2/core.hpp>

#include "algo/geometry.hpp"
#include "algo/phase_stereo.hpp"
#include "formats/stereo_calibration.hpp"

namespace cylscan::firmware {

algo::PinholeCamera mainCamera(const formats::StereoCalibration& calib);
algo::PinholeCamera auxCamera(const formats::StereoCalibration& calib);
algo::StereoGeometry toStereoGeometry(const formats::StereoCalibration& calib);
formats::StereoCalibration toStereoCalibration(const algo::StereoGeometry& geometry);

// InputError naming `stereo_file` unless the calibration was made for images
// of `size` (`images` says where those images come from, for the message).
void requireStereoImageSize(const std::filesystem::path& stereo_file,
                            const formats::StereoCalibration& calib, cv::Size size,
                            const std::filesystem::path& images);

}  // namespace cylscan::firmware
