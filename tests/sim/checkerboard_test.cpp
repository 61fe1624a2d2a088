// SPDX-License-Identifier: Apache-2.0
// The rendered checkerboards are found by OpenCV, at their true corners.
#include <gtest/gtest.h>

#include <iostream>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "sim_test_support.hpp"

namespace cylscan::sim {
namespace {

using namespace std::chrono_literals;

TEST(Checkerboard, FoundByOpenCvAtTheTrueCorners) {
  HeadConfig config = test::smallHead(500, 400, 1.0);
  Checkerboard board;
  board.center = Vec3(5, -4, 575);
  board.rotation = rotationFromVectorDeg({12, -18, 6});
  Scene scene;
  scene.ambient = 0.7;
  scene.objects.push_back({"board", board, 0.8});
  VirtualHead head(config, scene, 3);
  test::LineDriver lines(head);
  lines.light->set(false);  // uniformly lit by the ambient light, no fringes
  for (const char* name : {"main", "aux"})
    head.camera(name).configure({}), head.camera(name).start();
  lines.pulseTrigger();
  for (const char* name : {"main", "aux"}) {
    const auto frame = head.camera(name).waitFrame(1s);
    ASSERT_TRUE(frame);
    std::vector<cv::Point2f> found;
    ASSERT_TRUE(cv::findChessboardCorners(frame->image, {board.cols, board.rows}, found)) << name;
    cv::cornerSubPix(frame->image, found, {5, 5}, {-1, -1},
                     {cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-3});
    const CameraModel& cam = head.cameraModel(name);
    const auto truth = board.corners();
    ASSERT_EQ(found.size(), truth.size());
    // OpenCV may order the grid from either end.
    auto error = [&](bool reversed) {
      double worst = 0;
      for (std::size_t i = 0; i < truth.size(); ++i) {
        const auto p = cam.project(truth[reversed ? truth.size() - 1 - i : i]);
        worst = std::max(worst, std::hypot(p->x() - found[i].x, p->y() - found[i].y));
      }
      return worst;
    };
    const double worst = std::min(error(false), error(true));
    std::cout << "[ corners ] " << name << ": max error " << worst << " px\n";
    EXPECT_LT(worst, 0.5) << name;
  }
}

TEST(Checkerboard, OwnProjectionAgreesWithOpenCv) {
  // The virtual camera's projection code is its own; OpenCV's model with the
  // same numbers (k1, k2, p = 0, k3 = 0) must give the same pixels.
  const HeadConfig config = defaultHeadConfig();
  for (const CameraParams& p : config.cameras) {
    const CameraModel cam(p);
    const Checkerboard board;
    std::vector<cv::Point3d> object;
    for (const Vec3& c : board.corners())
      object.emplace_back(c.x(), c.y(), c.z());
    const Mat3 r = cam.rotationCamFromMain();
    const Vec3 t = -r * cam.centre();
    cv::Matx33d rm;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j)
        rm(i, j) = r(i, j);
    }
    cv::Vec3d rvec;
    cv::Rodrigues(rm, rvec);
    std::vector<cv::Point2d> expected;
    cv::projectPoints(object, rvec, cv::Vec3d(t.x(), t.y(), t.z()),
                      cv::Matx33d(p.fx, 0, p.cx, 0, p.fy, p.cy, 0, 0, 1),
                      std::vector<double>{p.k1, p.k2, 0, 0, 0}, expected);
    for (std::size_t i = 0; i < object.size(); ++i) {
      const auto px = cam.project(board.corners()[i]);
      ASSERT_TRUE(px);
      EXPECT_NEAR(px->x(), expected[i].x, 1e-6);
      EXPECT_NEAR(px->y(), expected[i].y, 1e-6);
      // And the ray back through that pixel reaches the corner.
      const Vec3 d = cam.rayDirection(px->x(), px->y());
      const Vec3 to = (board.corners()[i] - cam.centre()).normalized();
      EXPECT_LT((d - to).norm(), 1e-9);
    }
  }
}

}  // namespace
}  // namespace cylscan::sim
