#include "tools/cloud_output.hpp"

#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>

#include "formats/file_reading.hpp"
#include "formats/input_error.hpp"

namespace cylscan::tools {
namespace {

namespace fs = std::filesystem;
constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
// The largest calibration the format allows (2^25 pixels × 57 bytes) and a bit.
constexpr std::uintmax_t kMaxCalibrationBytes = (std::uintmax_t{1} << 25) * 57 + 4096;

}  // namespace

algo::QuasiCalibration readQuasiCalibration(const fs::path& file) {
  const std::string bytes = formats::readFileContents(file, kMaxCalibrationBytes);
  try {
    return algo::QuasiCalibration::deserialize(
        std::as_bytes(std::span<const char>(bytes.data(), bytes.size())));
  } catch (const std::invalid_argument& e) {
    throw formats::InputError(file, e.what());
  }
}

// The cloud of every finite point of an xyz map (CV_32FC3, NaN invalid).
formats::PointCloud cloudOfMaps(const cv::Mat& xyz, const cv::Mat& texture) {
  formats::PointCloud cloud;
  cloud.property_names = {"intensity", "u", "v"};
  cloud.properties.resize(3);
  for (int v = 0; v < xyz.rows; ++v) {
    const auto* row = xyz.ptr<cv::Vec3f>(v);
    const float* intensity = texture.ptr<float>(v);
    for (int u = 0; u < xyz.cols; ++u) {
      const cv::Vec3f& p = row[u];
      if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) continue;
      cloud.xyz.insert(cloud.xyz.end(), {p[0], p[1], p[2]});
      cloud.properties[0].push_back(intensity[u]);
      cloud.properties[1].push_back(static_cast<float>(u));
      cloud.properties[2].push_back(static_cast<float>(v));
    }
  }
  return cloud;
}

// Z of an xyz map, NaN where any coordinate is not finite.
cv::Mat depthOfMap(const cv::Mat& xyz) {
  cv::Mat depth(xyz.size(), CV_32F);
  for (int v = 0; v < xyz.rows; ++v) {
    const auto* row = xyz.ptr<cv::Vec3f>(v);
    float* out = depth.ptr<float>(v);
    for (int u = 0; u < xyz.cols; ++u) {
      const cv::Vec3f& p = row[u];
      const bool finite = std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]);
      out[u] = finite ? p[2] : kNaNf;
    }
  }
  return depth;
}

}  // namespace cylscan::tools
