// SPDX-License-Identifier: Apache-2.0
// cylscan phase: absolute phase maps of one camera of a capture bundle
// (docs/formats.md, command line); for a bundle with one set, that set's
// wrapped phase alone.
#include <cmath>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "algo/phase_engine.hpp"
#include "firmware/bundle_phase.hpp"
#include "firmware/scan_output.hpp"
#include "firmware/stopwatch.hpp"
#include "formats/capture_bundle.hpp"
#include "formats/images.hpp"
#include "tools/commands.hpp"

namespace cylscan::tools {
namespace {

namespace fs = std::filesystem;

// Texture in the frames' own depth: 8-bit PNG for 8-bit frames, else 16-bit.
cv::Mat textureInFrameDepth(const cv::Mat& texture, int bit_depth) {
  cv::Mat out;
  texture.convertTo(out, bit_depth <= 8 ? CV_8U : CV_16U);  // rounds and saturates
  return out;
}

double meanOverValid(const cv::Mat& values, const cv::Mat& invalid) {
  return cv::mean(values, invalid == 0)[0];
}

struct PhaseRequest {
  std::string bundle;
  std::string out;
  std::string camera = "main";
  int bit_depth = 0;
  double min_modulation = -1;
  bool reference = false;
  bool json = false;
};

// Why a one-set bundle gives no absolute phase, for the text and the JSON summary.
std::string oneSetNote(FringeSet set) {
  return "no absolute phase: the bundle has only the " + std::string(toString(set)) +
         " set, and unwrapping needs both \"high\" and \"low\"";
}

// What both kinds of run print in their JSON summary.
struct PhaseRun {
  cv::Size size;
  int bit_depth = 8;
  double valid_fraction = 0;
  double mean_modulation = 0;  // NaN when no pixel is valid
  double read_ms = 0, fold_ms = 0, finalize_ms = 0, write_ms = 0, total_ms = 0;
  fs::path out;
};

nlohmann::json summaryOf(const PhaseRequest& request, const formats::CaptureBundleReader& bundle,
                         const PhaseRun& run) {
  return {{"camera", request.camera},
          {"width", run.size.width},
          {"height", run.size.height},
          {"bit_depth", run.bit_depth},
          {"path", request.reference ? "reference" : "fixed-point"},
          {"own_sets", bundle.info().hasOwnSets(request.camera)},
          {"valid_fraction", run.valid_fraction},
          {"mean_modulation", std::isfinite(run.mean_modulation) ? run.mean_modulation : 0.0},
          {"timings_ms",
           {{"read", run.read_ms},
            {"fold", run.fold_ms},
            {"finalize", run.finalize_ms},
            {"write", run.write_ms},
            {"total", run.total_ms}}},
          {"out", run.out.string()}};
}

// A bundle with one set: the wrapped phase, modulation and texture of that set;
// nothing absolute is written.
void runOneSetPhase(const PhaseRequest& request, const formats::CaptureBundleReader& bundle,
                    FringeSet set, const firmware::BundlePhaseOptions& options,
                    const firmware::Stopwatch& total) {
  const firmware::BundleSetPhase phase =
      firmware::computeBundleSetPhase(bundle, request.camera, set, options);
  const algo::OneSetMaps& maps = phase.maps;
  const std::string name(toString(set));

  firmware::Stopwatch write_watch;
  const fs::path out(request.out);
  fs::create_directories(out);
  formats::writeFloatTiff(out / ("wrapped_" + name + ".tiff"), maps.wrapped);
  formats::writeFloatTiff(out / ("modulation_" + name + ".tiff"), maps.modulation);
  formats::writePng(out / "texture.png", textureInFrameDepth(maps.texture, phase.bit_depth));
  formats::writePng(out / "invalid.png", maps.invalid);
  const double write_ms = write_watch.elapsedMs();

  const double mean_modulation = meanOverValid(maps.modulation, maps.invalid);
  if (request.json) {
    nlohmann::json summary =
        summaryOf(request, bundle,
                  {phase.size, phase.bit_depth, maps.valid_fraction, mean_modulation, phase.read_ms,
                   phase.fold_ms, phase.finalize_ms, write_ms, total.elapsedMs(), out});
    summary["sets"] = {name};
    summary["absolute"] = false;
    summary["note"] = oneSetNote(set);
    summary["frames"] = {{name, bundle.frameCount(request.camera, set)}};
    std::cout << summary.dump() << "\n";
  } else {
    std::cout << "phase: " << request.camera << " " << phase.size.width << "x" << phase.size.height
              << ", " << name << " set only, valid " << maps.valid_fraction * 100.0
              << " %, mean modulation " << mean_modulation << " counts, fold " << phase.fold_ms
              << " ms, finalize " << phase.finalize_ms << " ms -> " << out.string() << "\n"
              << "phase: " << oneSetNote(set) << "\n";
  }
}

void runPhase(const PhaseRequest& request) {
  firmware::Stopwatch total;
  // The one reader of the one-set extension (docs/formats.md): a bundle with a
  // single set still has a wrapped phase to give.
  const formats::CaptureBundleReader bundle(request.bundle, {}, formats::SetsRequired::OneOrBoth);
  firmware::BundlePhaseOptions options;
  options.bit_depth = request.bit_depth;
  options.min_modulation = request.min_modulation;
  options.reference = request.reference;
  if (const std::optional<FringeSet> only = firmware::onlySetOf(bundle, request.camera)) {
    runOneSetPhase(request, bundle, *only, options, total);
    return;
  }
  const firmware::BundlePhase phase = firmware::computeBundlePhase(bundle, request.camera, options);
  const algo::PhaseMaps& maps = phase.maps;

  firmware::Stopwatch write_watch;
  const fs::path out(request.out);
  fs::create_directories(out);
  formats::writeFloatTiff(out / "wrapped_high.tiff", maps.wrapped_high);
  formats::writeFloatTiff(out / "wrapped_low.tiff", maps.wrapped_low);
  formats::writeFloatTiff(out / "absolute.tiff", maps.absolute);
  formats::writeFloatTiff(out / "fused.tiff", maps.fused);
  formats::writeFloatTiff(out / "modulation_high.tiff", maps.modulation_high);
  formats::writePng(out / "texture.png", textureInFrameDepth(maps.texture, phase.bit_depth));
  formats::writePng(out / "invalid.png", maps.invalid);
  const double write_ms = write_watch.elapsedMs();

  const double mean_modulation = meanOverValid(maps.modulation_high, maps.invalid);
  if (request.json) {
    nlohmann::json summary =
        summaryOf(request, bundle,
                  {phase.size, phase.bit_depth, maps.valid_fraction, mean_modulation, phase.read_ms,
                   phase.fold_ms, phase.finalize_ms, write_ms, total.elapsedMs(), out});
    summary["sets"] = {"high", "low"};
    summary["absolute"] = true;
    summary["frames"] = {{"high", bundle.frameCount(request.camera, FringeSet::High)},
                         {"low", bundle.frameCount(request.camera, FringeSet::Low)}};
    summary["order_residual"] = firmware::orderResidualJson(maps.order_residual);
    std::cout << summary.dump() << "\n";
  } else {
    std::cout << "phase: " << request.camera << " " << phase.size.width << "x" << phase.size.height
              << ", valid " << maps.valid_fraction * 100.0 << " %, order residual centre "
              << maps.order_residual.centre_rad << " rad, spread " << maps.order_residual.spread_rad
              << " rad, bound " << maps.order_residual.bound_rad << " rad, mean modulation "
              << mean_modulation << " counts, fold " << phase.fold_ms << " ms, finalize "
              << phase.finalize_ms << " ms -> " << out.string() << "\n";
  }
}

}  // namespace

void addPhaseCommand(CLI::App& app) {
  auto request = std::make_shared<PhaseRequest>();
  CLI::App* cmd = app.add_subcommand(
      "phase", "absolute phase maps of one camera of a bundle (wrapped only for one set)");
  cmd->add_option("bundle", request->bundle, "capture bundle directory")->required();
  cmd->add_option("--out", request->out, "output directory")->required();
  cmd->add_option("--camera", request->camera, "camera name (default: main)");
  cmd->add_option("--bit-depth", request->bit_depth,
                  "significant bits of 16-bit frames (default: capture.json bit_depth, or 16)")
      ->check(CLI::Range(9, 16));
  cmd->add_option("--min-modulation", request->min_modulation,
                  "modulation threshold in counts (default: the engine's)");
  cmd->add_flag("--reference", request->reference,
                "use the double-precision reference path instead of the fixed-point one");
  cmd->add_flag("--json", request->json, "print the summary as one JSON object");
  cmd->callback([request] { runPhase(*request); });
}

}  // namespace cylscan::tools
