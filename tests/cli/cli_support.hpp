// SPDX-License-Identifier: Apache-2.0
// Helpers for tests that run the `cylscan` program as a user would.
#pragma once

#include "tests/support/run_tool.hpp"
#include "tests/support/temp_dir.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "formats/capture_bundle.hpp"

namespace cylscan::test {

using test_support::runTool;
using test_support::ToolResult;

using test_support::TempDir;

// A synthetic bundle of the `main` camera whose absolute phase Φ (in radians of
// the high set) is known: Φ rises across the image through all nine fringe
// orders, with a block of pixels offset by several periods (an isolated
// object with a depth step).
struct SyntheticBundle {
  cv::Mat absolute;  // CV_64F, the truth
};

inline double stepQuantised(double deg) {
  return std::round(deg / 0.004) * 0.004;
}

// `cameras`: every camera gets the same frames (e.g. {"main", "aux"}).
inline SyntheticBundle writeSyntheticBundle(const std::filesystem::path& dir, cv::Size size,
                                            int frames = 12,
                                            const std::vector<std::string>& cameras = {"main"}) {
  constexpr double kTwoPi = 6.283185307179586;
  constexpr double kHigh = 5.0, kLow = 5.625;
  SyntheticBundle truth;
  truth.absolute.create(size, CV_64F);
  for (int v = 0; v < size.height; ++v) {
    for (int u = 0; u < size.width; ++u) {
      // 0.3 .. 0.3 + 8π: orders 0-4; the object adds 4.3 periods (orders 4-8),
      // and everything stays inside the equivalent period (18π).
      double phi = 0.3 + (4.0 * kTwoPi) * u / size.width;
      const bool object = u > size.width / 4 && u < size.width / 2 && v > size.height / 3;
      if (object) phi += 4.3 * kTwoPi;  // a step of several periods
      truth.absolute.at<double>(v, u) = phi;
    }
  }
  formats::CaptureInfo info;
  info.cameras = cameras;
  info.high.period_deg = kHigh;
  info.low.period_deg = kLow;
  for (int k = 0; k < frames; ++k) {
    info.high.stage_deg.push_back(stepQuantised(12.0 + k * kHigh / frames));
    info.low.stage_deg.push_back(stepQuantised(12.0 - 180.0 + k * kLow / frames));
  }
  formats::CaptureBundleWriter writer(dir, info);
  for (const auto set : kFringeSets) {
    const auto& s = info.set(set);
    for (int k = 0; k < frames; ++k) {
      const double delta = kTwoPi * (s.stage_deg[k] - s.stage_deg[0]) / s.period_deg;
      cv::Mat frame(size, CV_8U);
      for (int v = 0; v < size.height; ++v) {
        for (int u = 0; u < size.width; ++u) {
          // The projector azimuth of this pixel, relative to the common zero.
          const double azimuth = truth.absolute.at<double>(v, u) * kHigh / kTwoPi;
          const double phi = kTwoPi * azimuth / s.period_deg;
          frame.at<std::uint8_t>(v, u) =
              cv::saturate_cast<std::uint8_t>(120.0 + 90.0 * std::cos(phi - delta));
        }
      }
      for (const auto& camera : cameras)
        writer.writeFrame(camera, set, k, frame);
    }
  }
  writer.commit();
  return truth;
}

// Turns a bundle into one recorded with a single fringe set (the one-set
// extension, read only by `cylscan phase`): `set` leaves capture.json's "sets",
// and its frame directories go.
inline void removeFringeSet(const std::filesystem::path& dir, FringeSet set) {
  const std::filesystem::path json_path = dir / "capture.json";
  nlohmann::json capture = nlohmann::json::parse(std::ifstream(json_path));
  const std::string name(toString(set));
  capture["sets"].erase(name);
  for (const auto& camera : capture["cameras"])
    std::filesystem::remove_all(dir / camera.get<std::string>() / name);
  std::ofstream(json_path, std::ios::trunc) << capture.dump();
}

}  // namespace cylscan::test
