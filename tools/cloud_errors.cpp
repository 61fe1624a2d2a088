// SPDX-License-Identifier: Apache-2.0
#include "tools/cloud_errors.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "formats/input_error.hpp"
#include "formats/point_cloud.hpp"

namespace cylscan::tools {
namespace {

const std::vector<float>& property(const formats::PointCloud& cloud, const std::string& name,
                                   const std::filesystem::path& ply) {
  const auto& names = cloud.property_names;
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end()) throw formats::InputError(ply, "has no '" + name + "' property");
  return cloud.properties[static_cast<std::size_t>(it - names.begin())];
}

}  // namespace

CloudErrors cloudErrors(const std::filesystem::path& ply, const SceneTruth& truth, cv::Size grid) {
  const formats::PointCloud cloud = formats::readPly(ply);
  const std::vector<float>& u = property(cloud, "u", ply);
  const std::vector<float>& v = property(cloud, "v", ply);
  CloudErrors out;
  out.map_mm = cv::Mat(grid, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d p(cloud.xyz[3 * i], cloud.xyz[3 * i + 1], cloud.xyz[3 * i + 2]);
    if (!p.allFinite()) continue;
    const double d = truth.signedDistance(p);
    out.values_mm.push_back(d);
    const long col = std::lround(u[i]), row = std::lround(v[i]);
    if (col < 0 || row < 0 || col >= grid.width || row >= grid.height) {
      throw formats::InputError(ply, "point " + std::to_string(i) + " has (u, v) outside the " +
                                         std::to_string(grid.width) + "x" +
                                         std::to_string(grid.height) + " image");
    }
    out.map_mm.at<float>(static_cast<int>(row), static_cast<int>(col)) = static_cast<float>(d);
  }
  return out;
}

std::size_t countFarther(const std::vector<double>& values_mm, double threshold_mm) {
  return static_cast<std::size_t>(std::count_if(
      values_mm.begin(), values_mm.end(), [&](double d) { return std::abs(d) > threshold_mm; }));
}

}  // namespace cylscan::tools
