// SPDX-License-Identifier: Apache-2.0
// The outputs shared by cylscan scan and the daemon: cloud and depth of an
// xyz map, and the colour-mapped previews (invalid black, valid coloured).
#include "firmware/reconstruction.hpp"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

namespace cylscan::firmware {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

TEST(Reconstruction, PreviewIsBlackWhereInvalidAndColouredElsewhere) {
  cv::Mat map(4, 5, CV_32F);
  for (int v = 0; v < map.rows; ++v)
    for (int u = 0; u < map.cols; ++u)
      map.at<float>(v, u) = static_cast<float>(u + 10 * v);
  map.at<float>(1, 2) = kNaN;
  map.at<float>(3, 4) = std::numeric_limits<float>::infinity();
  const cv::Mat preview = previewOfMap(map);
  ASSERT_EQ(preview.type(), CV_8UC3);
  ASSERT_EQ(preview.size(), map.size());
  for (int v = 0; v < map.rows; ++v)
    for (int u = 0; u < map.cols; ++u) {
      const cv::Vec3b c = preview.at<cv::Vec3b>(v, u);
      const bool black = c == cv::Vec3b(0, 0, 0);
      EXPECT_EQ(black, !std::isfinite(map.at<float>(v, u))) << u << "," << v;
    }
  // The extremes get the colour map's two ends: different colours.
  EXPECT_NE(preview.at<cv::Vec3b>(0, 0), preview.at<cv::Vec3b>(3, 3));
  // All invalid: all black, no failure.
  const cv::Mat none = previewOfMap(cv::Mat(3, 3, CV_32F, cv::Scalar(kNaN)));
  EXPECT_EQ(cv::countNonZero(none.reshape(1)), 0);
  EXPECT_THROW(previewOfMap(cv::Mat(3, 3, CV_8U)), std::invalid_argument);
}

TEST(Reconstruction, CloudAndDepthKeepOnlyFinitePoints) {
  cv::Mat xyz(2, 3, CV_32FC3, cv::Scalar(1, 2, 3));
  xyz.at<cv::Vec3f>(0, 1) = cv::Vec3f(kNaN, 2, 3);
  xyz.at<cv::Vec3f>(1, 2) = cv::Vec3f(4, 5, 6);
  cv::Mat texture(2, 3, CV_32F, cv::Scalar(100));
  const formats::PointCloud cloud = cloudOfMaps(xyz, texture);
  EXPECT_EQ(cloud.size(), 5u);
  EXPECT_EQ(cloud.property_names, (std::vector<std::string>{"intensity", "u", "v"}));
  EXPECT_FLOAT_EQ(cloud.xyz.back(), 6.0f);
  EXPECT_FLOAT_EQ(cloud.properties[1].back(), 2.0f);  // u of the last point
  const cv::Mat depth = depthOfMap(xyz);
  EXPECT_TRUE(std::isnan(depth.at<float>(0, 1)));
  EXPECT_FLOAT_EQ(depth.at<float>(1, 2), 6.0f);
  EXPECT_FLOAT_EQ(depth.at<float>(0, 0), 3.0f);
}

TEST(Reconstruction, PhaseSource) {
  EXPECT_EQ(parsePhaseSource("high"), PhaseSource::High);
  EXPECT_EQ(toString(parsePhaseSource("fused")), "fused");
  EXPECT_THROW(parsePhaseSource("low"), std::invalid_argument);
  // The values are stored in .qcal files, so they may never change.
  EXPECT_EQ(static_cast<std::uint32_t>(PhaseSource::High), 0u);
  EXPECT_EQ(static_cast<std::uint32_t>(PhaseSource::Fused), 1u);
}

}  // namespace
}  // namespace cylscan::firmware
