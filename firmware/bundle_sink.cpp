// SPDX-License-Identifier: Apache-2.0
#include "firmware/bundle_sink.hpp"

#include <algorithm>

namespace cylscan::firmware {
namespace {}  // namespace

nlohmann::json ringLayoutJson(const RingLayout& ring) {
  nlohmann::json first = nlohmann::json::object();
  nlohmann::json margins = nlohmann::json::object();
  for (const RingCamera& c : ring.cameras) {
    first[c.camera] = toString(c.first_sweep_set);
    margins[c.camera] = {{"window", c.window_margin_deg}, {"half", c.half_margin_deg}};
  }
  return {{"start_deg", ring.start_deg},
          {"sweep2_start_deg", ring.sweep2_start_deg},
          {"step_deg", ring.step_deg},
          {"step_steps", ring.step_steps},
          {"frames", ring.frames},
          {"noise_gain", {{"high", ring.noise_gain_high}, {"low", ring.noise_gain_low}}},
          {"cameras", std::move(first)},
          {"margins_deg", std::move(margins)}};
}

namespace {

formats::CaptureInfo infoOf(const ScanPlan& plan, const std::vector<std::string>& cameras,
                            nlohmann::json extra) {
  formats::CaptureInfo info;
  info.cameras = cameras;
  // The top-level sets are main's (docs/formats.md); a camera whose angles differ
  // (a ring plan's cameras facing the other half) carries its own.
  auto setOf = [&](std::string_view camera, FringeSet id) {
    return formats::FringeSetInfo{plan.periodDeg(id), plan.anglesDeg(camera, id)};
  };
  info.high = setOf("main", FringeSet::High);
  info.low = setOf("main", FringeSet::Low);
  extra["steps_per_deg"] = plan.steps_per_deg;
  extra["stage_steps"] = {{"high", plan.motionSetOf("main", FringeSet::High).positions},
                          {"low", plan.motionSetOf("main", FringeSet::Low).positions}};
  for (const std::string& camera : cameras) {
    formats::CameraSets own{setOf(camera, FringeSet::High), setOf(camera, FringeSet::Low)};
    if (own.high.stage_deg == info.high.stage_deg && own.low.stage_deg == info.low.stage_deg)
      continue;
    info.camera_sets[camera] = std::move(own);
    for (const FringeSet id : kFringeSets) {
      extra["camera_sets"][camera][std::string(toString(id))]["stage_steps"] =
          plan.motionSetOf(camera, id).positions;
    }
  }
  if (plan.ring) {
    extra["plan"] = "ring";
    extra["ring"] = ringLayoutJson(*plan.ring);
  }
  info.extra = std::move(extra);
  return info;
}

}  // namespace

BundleSink::BundleSink(const std::filesystem::path& dir, const ScanPlan& plan,
                       const std::vector<std::string>& cameras, nlohmann::json extra)
    : writer_(dir, infoOf(plan, cameras, std::move(extra))) {}

void BundleSink::onFrame(std::string_view camera, FringeSet set, int k, double /*stage_deg*/,
                         const cv::Mat& image) {
  writer_.writeFrame(camera, set, k, image);
}

void BundleSink::commit() {
  writer_.commit();
}

}  // namespace cylscan::firmware
