// Shared by reconstruct and scan: the quasi-calibration file, and the point
// cloud and depth map of an xyz map.
#pragma once

#include <filesystem>

#include <opencv2/core.hpp>

#include "algo/quasi_calibration.hpp"
#include "formats/point_cloud.hpp"

namespace cylscan::tools {

// The calibration file; InputError naming it when it is unreadable, corrupt,
// truncated or too large.
algo::QuasiCalibration readQuasiCalibration(const std::filesystem::path& file);

// The cloud of every finite point of an xyz map (CV_32FC3, NaN invalid) with
// the properties intensity (from `texture`, CV_32F counts), u and v.
formats::PointCloud cloudOfMaps(const cv::Mat& xyz, const cv::Mat& texture);

// Z of an xyz map, NaN where any coordinate is not finite (CV_32F).
cv::Mat depthOfMap(const cv::Mat& xyz);

}  // namespace cylscan::tools
