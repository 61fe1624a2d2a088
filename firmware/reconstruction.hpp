// SPDX-License-Identifier: Apache-2.0
// From a scan's phase maps to its outputs, shared by `cylscan scan`,
// `cylscan reconstruct` and the daemon: the quasi-calibration file, the
// choice of absolute phase (fused or high), the point cloud and depth map of
// an xyz map, and colour-mapped previews of phase and depth.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "algo/phase_engine.hpp"
#include "algo/quasi_calibration.hpp"
#include "formats/head_extrinsics.hpp"
#include "formats/point_cloud.hpp"

namespace cylscan::firmware {

// The map of `maps` for the choice (CV_32F, NaN where invalid); shares the data.
const cv::Mat& absolutePhase(const algo::PhaseMaps& maps, PhaseSource choice);

// The order-residual centre a calibration was made with, when it records one:
// the reference its scans number their orders about.
std::optional<double> orderReference(const algo::QuasiCalibrationInfo& calibration);

// How far a scan's order-residual centre may move from its calibration's
// before the scan warns: π/4.
// - What moves it: only the low set against the high set (R times the low
//   set's phase offset, 10 rad per degree on a 5°/5.625° cylinder). Homing
//   error moves both sets alike and leaves it; its own noise is the spread
//   over √samples, about 1e-3 rad.
// - π/4 is 0.078° of the low set: two full steps of a 1/16-microstepped 45:1
//   stage. A start angle changed, a slot half moved, steps lost between the
//   sets or backlash that grew show well before the centre nears ±π from the
//   calibration's, where the numbering would flip by one order.
// - The fused phase moves with the low set, so such a drift also biases depth.
inline constexpr double kOrderDriftWarnRad = 0.7853981633974483;

// The warning for `camera` when its scan's centre moved more than
// kOrderDriftWarnRad from the calibration's; nullopt when it did not, or when
// either centre is unknown.
std::optional<std::string> orderDriftWarning(const std::string& camera,
                                             const algo::OrderResidual& scan,
                                             const algo::QuasiCalibrationInfo& calibration);

// The largest quasi-calibration the format allows (2^25 pixels × 57 bytes) and a bit.
inline constexpr std::uintmax_t kMaxCalibrationFileBytes = (std::uintmax_t{1} << 25) * 57 + 4096;

// The calibration file; InputError naming it when it is unreadable, corrupt,
// truncated or too large.
algo::QuasiCalibration readQuasiCalibration(const std::filesystem::path& file);

// The cloud of every finite point of an xyz map (CV_32FC3, NaN invalid) with
// the properties intensity (from `texture`, CV_32F counts), u and v.
formats::PointCloud cloudOfMaps(const cv::Mat& xyz, const cv::Mat& texture);

// ---------------------------------------------------------------- 360° head

// One camera's cloud in its own frame (cloudOfMaps of its xyz map).
struct CameraCloud {
  std::string camera;
  formats::PointCloud cloud;
};

// X ← R·X + T for every point of the cloud (its extra properties unchanged).
void transformCloud(formats::PointCloud& cloud, const formats::CameraPose& pose);

// The merged cloud in the head frame (= main's, so a cloud as docs/formats.md,
// point clouds, describes it): each camera's cloud mapped by its pose in
// `head`, appended in the order of `clouds` with its index in a uchar `camera`
// property and a `comment camera <i> <name>` line.
// `head` may be null only when the clouds are one camera's, which must then be
// the head frame's camera (`main`); std::invalid_argument naming the camera
// otherwise, and when a camera has no pose in `head`.
formats::PointCloud mergeCameraClouds(const std::vector<CameraCloud>& clouds,
                                      const formats::HeadExtrinsics* head);

// Z of an xyz map, NaN where any coordinate is not finite (CV_32F).
cv::Mat depthOfMap(const cv::Mat& xyz);

// A colour-mapped preview (CV_8UC3, BGR) of a CV_32F map: the finite values
// stretched from their minimum to their maximum over the turbo colour map,
// non-finite pixels black. An all-invalid map is all black.
cv::Mat previewOfMap(const cv::Mat& map);
// The same as a texture preview: CV_8UC1, counts scaled by 255 / (2^bit_depth − 1).
cv::Mat texturePreview(const cv::Mat& texture, int bit_depth);

}  // namespace cylscan::firmware
