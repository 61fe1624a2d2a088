#include "firmware/bundle_sink.hpp"

namespace cylscan::firmware {
namespace {

formats::CaptureInfo infoOf(const ScanPlan& plan, const std::vector<std::string>& cameras,
                            nlohmann::json extra) {
  formats::CaptureInfo info;
  info.cameras = cameras;
  info.high = {plan.high.period_deg, plan.anglesDeg(formats::FringeSetId::High)};
  info.low = {plan.low.period_deg, plan.anglesDeg(formats::FringeSetId::Low)};
  extra["steps_per_deg"] = plan.steps_per_deg;
  extra["stage_steps"] = {{"high", plan.high.positions}, {"low", plan.low.positions}};
  info.extra = std::move(extra);
  return info;
}

}  // namespace

BundleSink::BundleSink(const std::filesystem::path& dir, const ScanPlan& plan,
                       const std::vector<std::string>& cameras, nlohmann::json extra)
    : writer_(dir, infoOf(plan, cameras, std::move(extra))) {}

void BundleSink::onFrame(std::string_view camera, formats::FringeSetId set, int k,
                         double /*stage_deg*/, const cv::Mat& image) {
  writer_.writeFrame(camera, set, k, image);
}

void BundleSink::commit() {
  writer_.commit();
}

}  // namespace cylscan::firmware
