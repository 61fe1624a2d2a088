// SPDX-License-Identifier: Apache-2.0
#include "firmware/reconstruction.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <optional>
#include <span>
#include <sstream>
#include <stdexcept>
#include <string>

#include <opencv2/imgproc.hpp>

#include "algo/numbers.hpp"
#include "formats/file_reading.hpp"
#include "formats/input_error.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;
using algo::kNaNf;

bool finite3(const cv::Vec3f& p) {
  return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]);
}

}  // namespace

std::optional<double> orderReference(const algo::QuasiCalibrationInfo& calibration) {
  if (!std::isfinite(calibration.order_centre_rad)) return std::nullopt;
  return calibration.order_centre_rad;
}

std::optional<std::string> orderDriftWarning(const std::string& camera,
                                             const algo::OrderResidual& scan,
                                             const algo::QuasiCalibrationInfo& calibration) {
  const std::optional<double> reference = orderReference(calibration);
  if (!reference || scan.samples == 0) return std::nullopt;
  const double drift = std::remainder(scan.centre_rad - *reference, 2 * std::numbers::pi);
  if (std::abs(drift) <= kOrderDriftWarnRad) return std::nullopt;
  std::ostringstream text;
  text.precision(3);
  text << camera << ": the order-residual centre moved " << drift << " rad from its calibration's ("
       << *reference
       << " rad): the low fringe set moved against the high one since calibration (start "
          "angles changed, the cylinder re-mounted or a slot half moved, steps lost between "
          "the sets, stage backlash). Orders are still numbered as calibrated, but the fused "
          "phase and depth are biased: check the head and calibrate again";
  return text.str();
}

const cv::Mat& absolutePhase(const algo::PhaseMaps& maps, PhaseSource choice) {
  return choice == PhaseSource::High ? maps.absolute : maps.fused;
}

algo::QuasiCalibration readQuasiCalibration(const fs::path& file) {
  const std::string bytes = formats::readFileContents(file, kMaxCalibrationFileBytes);
  try {
    return algo::QuasiCalibration::deserialize(
        std::as_bytes(std::span<const char>(bytes.data(), bytes.size())));
  } catch (const std::invalid_argument& e) {
    throw formats::InputError(file, e.what());
  }
}

formats::PointCloud cloudOfMaps(const cv::Mat& xyz, const cv::Mat& texture) {
  formats::PointCloud cloud;
  cloud.property_names = {"intensity", "u", "v"};
  cloud.properties.resize(3);
  for (int v = 0; v < xyz.rows; ++v) {
    const auto* row = xyz.ptr<cv::Vec3f>(v);
    const float* intensity = texture.ptr<float>(v);
    for (int u = 0; u < xyz.cols; ++u) {
      const cv::Vec3f& p = row[u];
      if (!finite3(p)) continue;
      cloud.xyz.insert(cloud.xyz.end(), {p[0], p[1], p[2]});
      cloud.properties[0].push_back(intensity[u]);
      cloud.properties[1].push_back(static_cast<float>(u));
      cloud.properties[2].push_back(static_cast<float>(v));
    }
  }
  return cloud;
}

void transformCloud(formats::PointCloud& cloud, const formats::CameraPose& pose) {
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    float* p = &cloud.xyz[3 * i];
    const std::array<double, 3> x = pose.apply({p[0], p[1], p[2]});
    for (std::size_t c = 0; c < 3; ++c)
      p[c] = static_cast<float>(x[c]);
  }
}

formats::PointCloud mergeCameraClouds(const std::vector<CameraCloud>& clouds,
                                      const formats::HeadExtrinsics* head) {
  if (head == nullptr) {
    if (clouds.size() > 1) {
      throw std::invalid_argument("merging the clouds of " + std::to_string(clouds.size()) +
                                  " cameras needs the head's extrinsics (head.json)");
    }
    if (clouds.size() == 1 && clouds.front().camera != "main") {
      throw std::invalid_argument("the cloud of camera '" + clouds.front().camera +
                                  "' alone is not in the head frame without head.json");
    }
  }
  formats::PointCloud merged;
  for (std::size_t i = 0; i < clouds.size(); ++i) {
    const CameraCloud& part = clouds[i];
    if (head == nullptr) {
      formats::appendCameraCloud(merged, part.cloud, i, part.camera);
      continue;
    }
    if (!head->hasCamera(part.camera)) {
      throw std::invalid_argument("head.json has no pose for camera '" + part.camera + "'");
    }
    formats::PointCloud moved = part.cloud;
    transformCloud(moved, head->pose(part.camera));
    formats::appendCameraCloud(merged, moved, i, part.camera);
  }
  if (clouds.empty()) {
    merged.property_names = {"intensity", "u", "v", std::string(formats::kCameraProperty)};
    merged.properties.assign(4, {});
    merged.property_types = {formats::PlyScalar::Float32, formats::PlyScalar::Float32,
                             formats::PlyScalar::Float32, formats::PlyScalar::UInt8};
  }
  return merged;
}

cv::Mat depthOfMap(const cv::Mat& xyz) {
  cv::Mat depth(xyz.size(), CV_32F);
  for (int v = 0; v < xyz.rows; ++v) {
    const auto* row = xyz.ptr<cv::Vec3f>(v);
    float* out = depth.ptr<float>(v);
    for (int u = 0; u < xyz.cols; ++u)
      out[u] = finite3(row[u]) ? row[u][2] : kNaNf;
  }
  return depth;
}

cv::Mat previewOfMap(const cv::Mat& map) {
  if (map.type() != CV_32FC1) throw std::invalid_argument("previewOfMap: the map must be CV_32FC1");
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  cv::Mat valid(map.size(), CV_8U);
  for (int v = 0; v < map.rows; ++v) {
    const float* row = map.ptr<float>(v);
    std::uint8_t* ok = valid.ptr<std::uint8_t>(v);
    for (int u = 0; u < map.cols; ++u) {
      ok[u] = std::isfinite(row[u]) ? 255 : 0;
      if (ok[u]) {
        lo = std::min(lo, static_cast<double>(row[u]));
        hi = std::max(hi, static_cast<double>(row[u]));
      }
    }
  }
  cv::Mat grey(map.size(), CV_8U, cv::Scalar(0));
  if (lo <= hi) {
    const double scale = hi > lo ? 255.0 / (hi - lo) : 0.0;
    for (int v = 0; v < map.rows; ++v) {
      const float* row = map.ptr<float>(v);
      std::uint8_t* out = grey.ptr<std::uint8_t>(v);
      for (int u = 0; u < map.cols; ++u)
        if (std::isfinite(row[u])) out[u] = cv::saturate_cast<std::uint8_t>((row[u] - lo) * scale);
    }
  }
  cv::Mat colour;
  cv::applyColorMap(grey, colour, cv::COLORMAP_TURBO);
  cv::Mat out(map.size(), CV_8UC3, cv::Scalar::all(0));
  colour.copyTo(out, valid);
  return out;
}

cv::Mat texturePreview(const cv::Mat& texture, int bit_depth) {
  const double full = std::ldexp(1.0, std::clamp(bit_depth, 1, 16)) - 1.0;
  cv::Mat out;
  texture.convertTo(out, CV_8U, 255.0 / full);
  return out;
}

}  // namespace cylscan::firmware
