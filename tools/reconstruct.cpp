// cylscan reconstruct: the point cloud (spec §4) of a capture bundle, by the
// quasi-calibration of the main camera (default, --calib) or by the
// phase-based stereo of main and aux (--method stereo --stereo, the paper's
// SV method, for comparison). Both write the same PLY layout: x y z (mm, main
// camera frame), intensity (the texture, counts), u v (the main pixel).
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "algo/phase_stereo.hpp"
#include "algo/quasi_calibration.hpp"
#include "formats/capture_bundle.hpp"
#include "formats/file_reading.hpp"
#include "formats/images.hpp"
#include "formats/input_error.hpp"
#include "formats/point_cloud.hpp"
#include "formats/stereo_calibration.hpp"
#include "tools/bundle_phase.hpp"
#include "tools/cloud_output.hpp"
#include "tools/commands.hpp"
#include "tools/stereo_geometry.hpp"
#include "tools/stopwatch.hpp"

namespace cylscan::tools {
namespace {

namespace fs = std::filesystem;

struct ReconstructRequest {
  std::string bundle;
  std::string out;
  std::string method = "quasi";
  std::string calib;
  std::string stereo;
  std::string depth;
  std::string phase;  // empty: the calibration's own (quasi), fused (stereo)
  bool json = false;
};

// Which inputs each method takes; a wrong combination is a usage error.
void checkMethodOptions(const ReconstructRequest& request) {
  if (request.method == "quasi") {
    if (request.calib.empty())
      throw std::invalid_argument("reconstruct: --method quasi needs --calib CALIB");
    if (!request.stereo.empty()) {
      throw std::invalid_argument("reconstruct: --stereo belongs to --method stereo, not quasi");
    }
  } else if (request.method == "stereo") {
    if (request.stereo.empty()) {
      throw std::invalid_argument("reconstruct: --method stereo needs --stereo stereo.yaml");
    }
    if (!request.calib.empty()) {
      throw std::invalid_argument("reconstruct: --calib belongs to --method quasi, not stereo");
    }
  } else {
    throw std::invalid_argument("reconstruct: --method must be quasi or stereo, not '" +
                                request.method + "'");
  }
}

// The polynomials take the phase they were fitted on; another one is refused.
PhaseChoice phaseForCalibration(const ReconstructRequest& request,
                                const algo::QuasiCalibration& calib) {
  const PhaseChoice recorded = firmware::phaseChoiceOf(calib.info().phase_source);
  if (request.phase.empty()) return recorded;
  const PhaseChoice asked = parsePhaseChoice(request.phase);
  if (asked != recorded) {
    throw formats::InputError(request.calib, "calibrated on the " + toString(recorded) +
                                                 " phase, but --phase " + request.phase +
                                                 " was asked");
  }
  return asked;
}

struct Reconstruction {
  cv::Mat xyz;  // CV_32FC3 on the main grid, NaN where invalid
  cv::Mat texture;
  PhaseChoice phase = PhaseChoice::kFused;
  double phase_valid_fraction = 0;
  double phase_ms = 0;
  double reconstruct_ms = 0;
};

Reconstruction reconstructQuasi(const ReconstructRequest& request,
                                const formats::CaptureBundleReader& bundle) {
  const algo::QuasiCalibration calib = readQuasiCalibration(request.calib);
  requireCamera(bundle, "main");
  try {
    calib.requireImageSize(bundle.frameSize("main"));
  } catch (const std::invalid_argument& e) {
    throw formats::InputError(
        request.calib, std::string(e.what()) + " (" + (bundle.dir() / "main").string() + ")");
  }
  Reconstruction out;
  out.phase = phaseForCalibration(request, calib);
  Stopwatch watch;
  const BundlePhase main = computeBundlePhase(bundle, "main");
  out.phase_ms = watch.lapMs();
  out.xyz = calib.evaluate(absolutePhase(main.maps, out.phase));
  out.reconstruct_ms = watch.lapMs();
  out.texture = main.maps.texture;
  out.phase_valid_fraction = main.maps.valid_fraction;
  return out;
}

Reconstruction reconstructStereo(const ReconstructRequest& request,
                                 const formats::CaptureBundleReader& bundle) {
  const formats::StereoCalibration stereo = formats::readStereoCalibration(request.stereo);
  requireCamera(bundle, "main");
  requireCamera(bundle, "aux");
  for (const char* camera : {"main", "aux"}) {
    requireStereoImageSize(request.stereo, stereo, bundle.frameSize(camera), bundle.dir() / camera);
  }
  Reconstruction out;
  out.phase = request.phase.empty() ? PhaseChoice::kFused : parsePhaseChoice(request.phase);
  Stopwatch watch;
  const BundlePhase main = computeBundlePhase(bundle, "main");
  const BundlePhase aux = computeBundlePhase(bundle, "aux");
  out.phase_ms = watch.lapMs();
  const algo::PhaseStereo matcher(toStereoGeometry(stereo));
  out.xyz =
      matcher.reconstruct(absolutePhase(main.maps, out.phase), absolutePhase(aux.maps, out.phase))
          .xyz;
  out.reconstruct_ms = watch.lapMs();
  out.texture = main.maps.texture;
  out.phase_valid_fraction = main.maps.valid_fraction;
  return out;
}

void runReconstruct(const ReconstructRequest& request) {
  Stopwatch total;
  checkMethodOptions(request);
  if (!request.phase.empty()) parsePhaseChoice(request.phase);
  const formats::CaptureBundleReader bundle(request.bundle);
  const Reconstruction r = request.method == "quasi" ? reconstructQuasi(request, bundle)
                                                     : reconstructStereo(request, bundle);
  Stopwatch watch;
  const formats::PointCloud cloud = cloudOfMaps(r.xyz, r.texture);
  formats::writePly(request.out, cloud);
  if (!request.depth.empty()) formats::writeFloatTiff(request.depth, depthOfMap(r.xyz));
  const double write_ms = watch.lapMs();
  const double pixels = r.xyz.total();
  if (request.json) {
    nlohmann::json summary = {{"method", request.method},
                              {"phase", toString(r.phase)},
                              {"width", r.xyz.cols},
                              {"height", r.xyz.rows},
                              {"points", cloud.size()},
                              {"point_fraction", static_cast<double>(cloud.size()) / pixels},
                              {"phase_valid_fraction", r.phase_valid_fraction},
                              {"timings_ms",
                               {{"phase", r.phase_ms},
                                {"reconstruct", r.reconstruct_ms},
                                {"write", write_ms},
                                {"total", total.elapsedMs()}}},
                              {"out", request.out}};
    if (!request.depth.empty()) summary["depth"] = request.depth;
    std::cout << summary.dump() << "\n";
  } else {
    std::cout << "reconstruct (" << request.method << ", " << toString(r.phase)
              << " phase): " << cloud.size() << " points of " << r.xyz.cols << "x" << r.xyz.rows
              << " pixels -> " << request.out << "\n";
  }
}

}  // namespace

void addReconstructCommand(CLI::App& app) {
  auto request = std::make_shared<ReconstructRequest>();
  CLI::App* cmd = app.add_subcommand("reconstruct", "point cloud of a capture bundle");
  cmd->add_option("bundle", request->bundle, "capture bundle directory")->required();
  cmd->add_option("--out", request->out, "point cloud to write (binary PLY)")->required();
  cmd->add_option("--method", request->method,
                  "quasi (default: the quasi-calibration, main camera only) or stereo (SV)")
      ->check(CLI::IsMember({"quasi", "stereo"}));
  cmd->add_option("--calib", request->calib, "quasi-calibration file (--method quasi)");
  cmd->add_option("--stereo", request->stereo, "stereo calibration file (--method stereo)");
  cmd->add_option("--depth", request->depth,
                  "also write the depth map Z (32-bit float TIFF, NaN where invalid)");
  cmd->add_option("--phase", request->phase,
                  "high or fused (default: the calibration's; fused for stereo)")
      ->check(CLI::IsMember({"high", "fused"}));
  cmd->add_flag("--json", request->json, "print the summary as one JSON object");
  cmd->callback([request] { runReconstruct(*request); });
}

}  // namespace cylscan::tools
