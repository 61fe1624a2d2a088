// SPDX-License-Identifier: Apache-2.0
// Same seed, same bytes (whatever the thread count); another seed, other noise.
#include <gtest/gtest.h>

#include "sim_test_support.hpp"

namespace cylscan::sim {
namespace {

using namespace std::chrono_literals;

std::vector<cv::Mat> acquire(std::uint64_t seed, int threads) {
  HeadConfig c = test::smallHead(160, 128, 1.0);
  c.render.threads = threads;
  VirtualHead head(c, test::planeScene(), seed);
  test::LineDriver lines(head);
  drivers::Camera& cam = head.camera("main");
  cam.configure({});
  cam.start();
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 3; ++k) {
    lines.move(50);
    lines.pulseTrigger();
    frames.push_back(cam.waitFrame(1s)->image);
  }
  return frames;
}

double maxDiff(const std::vector<cv::Mat>& a, const std::vector<cv::Mat>& b) {
  double d = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    d = std::max(d, cv::norm(a[i], b[i], cv::NORM_INF));
  return d;
}

TEST(Determinism, SameSeedSameBytes) {
  EXPECT_EQ(maxDiff(acquire(42, 1), acquire(42, 1)), 0.0);
  EXPECT_EQ(maxDiff(acquire(42, 1), acquire(42, 2)), 0.0);
}

TEST(Determinism, OtherSeedOtherNoise) {
  const auto a = acquire(42, 2), b = acquire(43, 2);
  EXPECT_GT(maxDiff(a, b), 0.0);
  // Only the noise differs: the means agree closely.
  EXPECT_NEAR(cv::mean(a[0])[0], cv::mean(b[0])[0], 0.1);
}

TEST(Determinism, SuccessiveFramesHaveIndependentNoise) {
  HeadConfig c = test::smallHead(160, 128, 1.0);
  VirtualHead head(c, test::planeScene(), 9);
  test::LineDriver lines(head);
  drivers::Camera& cam = head.camera("main");
  cam.configure({});
  cam.start();
  lines.pulseTrigger();
  const cv::Mat a = cam.waitFrame(1s)->image;
  lines.pulseTrigger();
  const cv::Mat b = cam.waitFrame(1s)->image;
  cv::Mat diff;
  cv::subtract(a, b, diff, cv::noArray(), CV_64F);
  cv::Scalar mean, sd;
  cv::meanStdDev(diff, mean, sd);
  // Shot noise ≈ sqrt(electrons) at full noise scale: a few counts, uncorrelated.
  EXPECT_GT(sd[0], 1.0);
  EXPECT_NEAR(mean[0], 0.0, 0.1);
}

}  // namespace
}  // namespace cylscan::sim
