// SPDX-License-Identifier: Apache-2.0
// The stereo calibration file (docs/formats.md, stereo calibration file):
// OpenCV FileStorage YAML.
#pragma once

#include <filesystem>

#include <opencv2/core.hpp>

namespace cylscan::formats {

struct StereoCalibration {
  int image_width = 0;
  int image_height = 0;
  cv::Matx33d camera_matrix_main;
  cv::Vec<double, 5> dist_coeffs_main;  // k1 k2 p1 p2 k3
  cv::Matx33d camera_matrix_aux;
  cv::Vec<double, 5> dist_coeffs_aux;
  cv::Matx33d R;  // X_aux = R * X_main + T
  cv::Vec3d T;    // mm
};

StereoCalibration readStereoCalibration(const std::filesystem::path& file);  // InputError
void writeStereoCalibration(const std::filesystem::path& file, const StereoCalibration& calib);

}  // namespace cylscan::formats
