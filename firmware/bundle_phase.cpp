// SPDX-License-Identifier: Apache-2.0
#include "firmware/bundle_phase.hpp"

#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "firmware/stopwatch.hpp"
#include "formats/input_error.hpp"

namespace cylscan::firmware {
namespace {

algo::FringeSetGeometry geometryOf(const formats::FringeSetInfo& set) {
  return {set.period_deg, set.stage_deg};
}

// The significant bits of the frames: 8 for 8-bit PNG; for 16-bit PNG the
// option when given, else the writer's `bit_depth` field (12-bit sensors store
// counts unscaled), else 16.
int bitDepthOf(const formats::CaptureBundleReader& bundle, const cv::Mat& first, int option) {
  if (first.depth() == CV_8U) return 8;
  if (option > 0) return option;
  const auto& extra = bundle.info().extra;
  if (auto it = extra.find("bit_depth"); it != extra.end()) {
    if (!it->is_number_integer() || it->get<int>() < 9 || it->get<int>() > 16) {
      throw formats::InputError(bundle.dir() / "capture.json",
                                "bit_depth must be an integer from 9 to 16 for 16-bit frames");
    }
    return it->get<int>();
  }
  return 16;
}

algo::PhaseOptions engineOptions(const formats::CaptureBundleReader& bundle, const cv::Mat& first,
                                 const BundlePhaseOptions& options) {
  algo::PhaseOptions engine_options;
  engine_options.bit_depth = bitDepthOf(bundle, first, options.bit_depth);
  engine_options.min_modulation = options.min_modulation;
  engine_options.fixed_point = !options.reference;
  engine_options.order_reference_rad = options.order_reference_rad;
  return engine_options;
}

// Streams the frames of `camera`'s set into `fold` as they are read (none is
// kept); `first` is frame 0 of the set, already read. A fold's
// std::invalid_argument is an InputError naming the frame.
template <typename Fold, typename Timings>
void foldSet(const formats::CaptureBundleReader& bundle, const std::string& camera, FringeSet set,
             const cv::Mat& first, Stopwatch& watch, Timings& out, Fold&& fold) {
  const int n = bundle.frameCount(camera, set);
  for (int k = 0; k < n; ++k) {
    watch.lapMs();
    const cv::Mat frame = k == 0 && !first.empty() ? first : bundle.readFrame(camera, set, k);
    out.read_ms += watch.lapMs();
    try {
      fold(k, frame);
    } catch (const std::invalid_argument& e) {
      throw formats::InputError(bundle.framePath(camera, set, k), e.what());
    }
    out.fold_ms += watch.lapMs();
  }
}

// The camera's own sets: its "camera_sets" entry (a ring scan's cameras facing
// the other half), else the top-level ones.
algo::PhaseEngine makeEngine(const formats::CaptureBundleReader& bundle, const std::string& camera,
                             cv::Size size, const algo::PhaseOptions& options) {
  const formats::CaptureInfo& info = bundle.info();
  try {
    return algo::PhaseEngine(size, geometryOf(info.setOf(camera, FringeSet::High)),
                             geometryOf(info.setOf(camera, FringeSet::Low)), options);
  } catch (const std::invalid_argument& e) {  // includes ShiftSolveError
    throw formats::InputError(bundle.dir() / "capture.json", e.what());
  }
}

}  // namespace

void requireCamera(const formats::CaptureBundleReader& bundle, const std::string& camera) {
  if (!bundle.hasCamera(camera)) {
    throw formats::InputError(bundle.dir() / "capture.json",
                              "no camera '" + camera + "' in cameras");
  }
}

BundlePhase computeBundlePhase(const formats::CaptureBundleReader& bundle,
                               const std::string& camera, const BundlePhaseOptions& options) {
  requireCamera(bundle, camera);
  if (const std::optional<FringeSet> only = onlySetOf(bundle, camera)) {
    throw formats::InputError(bundle.dir() / "capture.json",
                              "camera '" + camera + "' has only the " +
                                  std::string(toString(*only)) +
                                  " set; the absolute phase needs both \"high\" and \"low\"");
  }
  BundlePhase out;
  Stopwatch watch;
  const cv::Mat first = bundle.readFrame(camera, FringeSet::High, 0);
  out.read_ms += watch.lapMs();
  out.size = first.size();

  const algo::PhaseOptions engine_options = engineOptions(bundle, first, options);
  out.bit_depth = engine_options.bit_depth;
  algo::PhaseEngine engine = makeEngine(bundle, camera, out.size, engine_options);

  // Streaming: each frame is folded in as soon as it is read; none is kept.
  for (const auto set : kFringeSets) {
    foldSet(bundle, camera, set, set == FringeSet::High ? first : cv::Mat(), watch, out,
            [&](int k, const cv::Mat& frame) { engine.fold(set, k, frame); });
  }
  watch.lapMs();
  out.maps = engine.finalize();
  out.finalize_ms = watch.lapMs();
  return out;
}

std::optional<FringeSet> onlySetOf(const formats::CaptureBundleReader& bundle,
                                   const std::string& camera) {
  requireCamera(bundle, camera);
  const formats::CaptureInfo& info = bundle.info();
  if (!info.hasSetOf(camera, FringeSet::Low)) return FringeSet::High;
  if (!info.hasSetOf(camera, FringeSet::High)) return FringeSet::Low;
  return std::nullopt;
}

BundleSetPhase computeBundleSetPhase(const formats::CaptureBundleReader& bundle,
                                     const std::string& camera, FringeSet set,
                                     const BundlePhaseOptions& options) {
  requireCamera(bundle, camera);
  BundleSetPhase out;
  out.set = set;
  Stopwatch watch;
  const cv::Mat first = bundle.readFrame(camera, set, 0);
  out.read_ms += watch.lapMs();
  out.size = first.size();

  const algo::PhaseOptions engine_options = engineOptions(bundle, first, options);
  out.bit_depth = engine_options.bit_depth;
  std::optional<algo::OneSetPhase> engine;
  try {
    engine.emplace(out.size, set, geometryOf(bundle.info().setOf(camera, set)), engine_options);
  } catch (const std::invalid_argument& e) {  // includes ShiftSolveError
    throw formats::InputError(bundle.dir() / "capture.json", e.what());
  }
  foldSet(bundle, camera, set, first, watch, out,
          [&](int k, const cv::Mat& frame) { engine->fold(k, frame); });
  watch.lapMs();
  out.maps = engine->finalize();
  out.finalize_ms = watch.lapMs();
  return out;
}

}  // namespace cylscan::firmware
