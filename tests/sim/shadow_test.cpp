// SPDX-License-Identifier: Apache-2.0
// Projector shadows and camera occlusion: a sphere in front of a plane.
#include <gtest/gtest.h>

#include <cmath>

#include "sim_test_support.hpp"

namespace cylscan::sim {
namespace {

using namespace std::chrono_literals;

// Does the segment p→q pass through the sphere (centre c, radius r)?
bool segmentHitsSphere(const Vec3& p, const Vec3& q, const Vec3& c, double r) {
  const Vec3 d = q - p;
  const double t = std::clamp((c - p).dot(d) / d.squaredNorm(), 0.0, 1.0);
  return (p + t * d - c).norm() < r;
}

TEST(Shadows, TheSphereShadowsThePlaneWhereGeometrySays) {
  HeadConfig config = test::smallHead(200, 160, 0.0);
  const Vec3 centre(10, 0, 540);
  const double radius = 40;
  Scene scene = test::planeScene(650);
  scene.objects.push_back({"ball", Sphere{centre, radius}, 0.8});
  VirtualHead head(config, scene);
  const auto g = head.pixelGeometry("main");
  const Vec3 source = head.projector().sourcePosition();
  int shadow = 0, lit = 0, sphere = 0, disagree = 0, near_edge = 0;
  for (int v = 0; v < g->height; ++v) {
    for (int u = 0; u < g->width; ++u) {
      const cv::Vec3d p = g->points.at<cv::Vec3d>(v, u);
      const Vec3 x(p[0], p[1], p[2]);
      const std::uint8_t f = g->flags.at<std::uint8_t>(v, u);
      ASSERT_TRUE(f & PixelGeometry::kHit);
      if (std::abs(x.z() - 650) > 1e-6) {  // occlusion: the camera sees the sphere first
        EXPECT_NEAR((x - centre).norm(), radius, 1e-6);
        ++sphere;
        continue;
      }
      const bool expected = segmentHitsSphere(x, source, centre, radius);
      const bool got = f & PixelGeometry::kShadow;
      // Pixels whose shadow ray grazes the sphere are ambiguous to 1e-3 mm.
      const Vec3 d = source - x;
      const double t = std::clamp((centre - x).dot(d) / d.squaredNorm(), 0.0, 1.0);
      if (std::abs((x + t * d - centre).norm() - radius) < 1e-3) {
        ++near_edge;
        continue;
      }
      disagree += expected != got;
      (got ? shadow : lit) += 1;
      EXPECT_EQ(got, !(f & PixelGeometry::kLit));
    }
  }
  EXPECT_EQ(disagree, 0);
  EXPECT_GT(shadow, 500);  // the projector is 120 mm to the right: a visible shadow
  EXPECT_GT(sphere, 2000);
  EXPECT_GT(lit, 5000);
  EXPECT_LT(near_edge, 10);

  // In the frames, shadowed plane pixels only get ambient light.
  test::LineDriver lines(head);
  drivers::Camera& cam = head.camera("main");
  cam.configure({});
  cam.start();
  lines.pulseTrigger();
  const cv::Mat frame = cam.waitFrame(1s)->image;
  const double ambient_counts = 0.03 * 0.8 * 255;
  for (int v = 0; v < g->height; ++v) {
    for (int u = 0; u < g->width; ++u) {
      if (g->flags.at<std::uint8_t>(v, u) & PixelGeometry::kShadow) {
        EXPECT_NEAR(frame.at<std::uint8_t>(v, u), ambient_counts, 1.0);
      }
    }
  }
}

TEST(Shadows, OutsideTheVerticalExtentIsDark) {
  HeadConfig config = test::smallHead(200, 160, 0.0);
  config.projector.elevation_min_deg = -2;
  config.projector.elevation_max_deg = 2;
  VirtualHead head(config, test::planeScene(580));
  const auto g = head.pixelGeometry("main");
  // Rows far from the horizon are unlit, the middle rows lit.
  EXPECT_FALSE(g->flags.at<std::uint8_t>(5, 100) & PixelGeometry::kLit);
  EXPECT_FALSE(g->flags.at<std::uint8_t>(155, 100) & PixelGeometry::kLit);
  EXPECT_TRUE(g->flags.at<std::uint8_t>(80, 100) & PixelGeometry::kLit);
  EXPECT_FALSE(g->flags.at<std::uint8_t>(5, 100) & PixelGeometry::kShadow);
}

}  // namespace
}  // namespace cylscan::sim
