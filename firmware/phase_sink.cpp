// SPDX-License-Identifier: Apache-2.0
#include "firmware/phase_sink.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace cylscan::firmware {

PhaseSink::PhaseSink(const ScanPlan& plan, const algo::PhaseOptions& options)
    : plan_(plan), options_(options) {}

algo::FringeSetGeometry PhaseSink::geometry(std::string_view camera, FringeSet set) const {
  return {plan_.periodDeg(set), plan_.anglesDeg(camera, set)};
}

const algo::PhaseOptions& PhaseSink::options(std::string_view camera) const {
  return this->camera(camera).engine.options();
}

PhaseSink::Camera& PhaseSink::camera(std::string_view name) {
  const auto it = cameras_.find(name);
  if (it == cameras_.end())
    throw std::invalid_argument("phase: no engine for camera '" + std::string(name) + "'");
  return it->second;
}

const PhaseSink::Camera& PhaseSink::camera(std::string_view name) const {
  const auto it = cameras_.find(name);
  if (it == cameras_.end())
    throw std::invalid_argument("phase: no engine for camera '" + std::string(name) + "'");
  return it->second;
}

void PhaseSink::onFrame(std::string_view name, FringeSet set, int k, double stage_deg,
                        const cv::Mat& image) {
  auto it = cameras_.find(name);
  if (it == cameras_.end()) {
    algo::FringeSetGeometry high = geometry(name, FringeSet::High);
    algo::FringeSetGeometry low = geometry(name, FringeSet::Low);
    algo::PhaseEngine engine(image.size(), high, low, options_);
    it = cameras_
             .emplace(std::string(name),
                      Camera{std::move(high), std::move(low), std::move(engine), 0})
             .first;
  }
  Camera& c = it->second;
  // The engine's weights come from the plan: a frame must be where it says.
  const auto& angles = (set == FringeSet::High ? c.high : c.low).stage_deg;
  const double planned = angles.at(static_cast<std::size_t>(k));
  if (std::abs(planned - stage_deg) > 0.5 / plan_.steps_per_deg) {
    throw std::logic_error("phase: camera '" + std::string(name) + "': frame " + std::to_string(k) +
                           " of the " + std::string(toString(set)) + " set was exposed at " +
                           std::to_string(stage_deg) + " deg, planned " + std::to_string(planned));
  }
  c.engine.fold(set, k, image);
  ++c.folded;
}

int PhaseSink::folded(std::string_view name) const {
  return camera(name).folded;
}

cv::Size PhaseSink::frameSize(std::string_view name) const {
  return camera(name).engine.size();
}

std::size_t PhaseSink::workingStateBytes() const {
  std::size_t bytes = 0;
  for (const auto& [name, c] : cameras_)
    bytes += c.engine.workingStateBytes();
  return bytes;
}

algo::PhaseMaps PhaseSink::finalize(std::string_view name, std::optional<double> order_reference) {
  algo::PhaseEngine& engine = camera(name).engine;
  engine.setOrderReference(order_reference);
  return engine.finalize();
}

algo::CompactPhase PhaseSink::finalizeCompact(std::string_view name,
                                              std::optional<double> order_reference) {
  algo::PhaseEngine& engine = camera(name).engine;
  engine.setOrderReference(order_reference);
  algo::CompactPhase out;
  engine.finalizeCompact(out);
  return out;
}

}  // namespace cylscan::firmware
