// SPDX-License-Identifier: Apache-2.0
// The virtual cameras' optics: pinhole with radial distortion (k1, k2), pose in
// the main camera frame, and the sensor (full well, read noise, bit depth).
#pragma once

#include <array>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "drivers/sim/geometry.hpp"

namespace cylscan::sim {

struct CameraParams {
  std::string name = "main";
  int width = 1000;
  int height = 800;
  double fx = 3478.26, fy = 3478.26;  // 12 mm lens, 3.45 µm pixels
  double cx = 499.5, cy = 399.5;
  double k1 = 0.0, k2 = 0.0;  // x_d = x (1 + k1 r² + k2 r⁴), as OpenCV with p1 = p2 = k3 = 0
  std::array<double, 3> position_mm{0.0, 0.0, 0.0};  // camera centre, main frame
  std::array<double, 3> rotation_deg{0.0, 0.0,
                                     0.0};  // rotation vector: camera axes in the main frame
  // Sensor and timing.
  int bit_depth = 8;  // 8, 10, 12 or 16 significant bits (more than 8: stored in 16 bits)
  double exposure_us = 10000.0;
  double gain = 1.0;  // counts per (full well / max count) electrons
  // What the sensor accepts (an IMX273-like industrial sensor: tens of µs up,
  // 24 dB of analogue gain): the camera clamps a configured value into them.
  double exposure_min_us = 20.0;
  double exposure_max_us = 200000.0;
  double gain_min = 1.0;
  double gain_max = 16.0;
  double full_well_e = 10500.0;
  double read_noise_e = 2.3;
  double trigger_latency_us = 20.0;  // trigger edge → start of exposure
  double readout_us = 8000.0;        // end of exposure → frame delivered
  double frame_rate_hz = 30.0;       // free-running mode
  // The sensor's response: counts = full scale · (linear / full scale)^gamma
  // (1: linear; an 8-bit camera left in an sRGB-like mode is near 0.45).
  double response_gamma = 1.0;
  // Rolling shutter: row v starts its exposure v · line_time_us after row 0
  // (0: a global shutter). Under continuous motion each row sees the pattern
  // at its own stage angle.
  double line_time_us = 0.0;

  bool operator==(const CameraParams&) const = default;
};

// Throws std::invalid_argument naming the parameter when a value is impossible.
void validate(const CameraParams& params);

// Rotation vector (deg) of a camera at `position` looking at `target`, image x
// horizontal (perpendicular to the main y axis), then rolled about its axis.
std::array<double, 3> lookAtRotationDeg(const Vec3& position, const Vec3& target, double roll_deg);

class CameraModel {
 public:
  explicit CameraModel(const CameraParams& params);

  const CameraParams& params() const { return params_; }
  int width() const { return params_.width; }
  int height() const { return params_.height; }

  Vec3 centre() const { return centre_; }
  const Mat3& rotationCamFromMain() const { return r_cam_main_; }
  Vec3 toCamera(const Vec3& x_main) const { return r_cam_main_ * (x_main - centre_); }

  // Pixel coordinates (OpenCV: pixel centres at integers) of a main-frame
  // point; nullopt when the point is behind the camera.
  std::optional<Eigen::Vector2d> project(const Vec3& x_main) const;
  // Unit direction in the main frame of the ray through pixel (u, v).
  Vec3 rayDirection(double u, double v) const;
  // rayDirection() of every pixel centre, row-major (computed once, thread-safe).
  const std::vector<Vec3>& pixelRays() const;
  // Normalised undistorted coordinates of a pixel (inverse of the distortion).
  Eigen::Vector2d undistort(double u, double v) const;

  // The same camera at another resolution with the same field of view.
  CameraParams scaledTo(int width, int height) const;

 private:
  CameraParams params_;
  Vec3 centre_;
  Mat3 r_cam_main_;
  struct RayCache {
    std::once_flag once;
    std::vector<Vec3> rays;
  };
  std::shared_ptr<RayCache> ray_cache_ = std::make_shared<RayCache>();
};

}  // namespace cylscan::sim
