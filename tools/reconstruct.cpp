// SPDX-License-Identifier: Apache-2.0
// cylscan reconstruct: the point cloud (docs/formats.md, point clouds) of a
// capture bundle, by the quasi-calibration of the main camera (default,
// --calib) or by the phase-based stereo of main and aux (--method stereo
// --stereo, the paper's SV method, for comparison). Both write the same PLY
// layout: x y z (mm, main camera frame), intensity (the texture, counts), u v
// (the main pixel). With --calib-dir (the 360° head): every calibrated camera
// of the bundle on its own sets, merged into the head frame by --head
// head.json, with a uchar `camera` property (comment lines name the cameras).
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "algo/phase_stereo.hpp"
#include "algo/quasi_calibration.hpp"
#include "firmware/bundle_phase.hpp"
#include "firmware/stereo_geometry.hpp"
#include "firmware/stopwatch.hpp"
#include "formats/capture_bundle.hpp"
#include "formats/file_reading.hpp"
#include "formats/head_extrinsics.hpp"
#include "formats/images.hpp"
#include "formats/input_error.hpp"
#include "formats/point_cloud.hpp"
#include "formats/stereo_calibration.hpp"
#include "tools/camera_reconstruction.hpp"
#include "tools/cloud_output.hpp"
#include "tools/commands.hpp"

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
  // The 360° head: every camera with DIR/<camera>.qcal, merged in
  // the head frame by head.json; optionally each camera's own cloud.
  std::string calib_dir;
  std::string head;
  std::string per_camera;
};

// Which inputs each method takes; a wrong combination is a usage error.
void checkMethodOptions(const ReconstructRequest& request) {
  if (!request.calib_dir.empty()) {
    if (request.method != "quasi")
      throw std::invalid_argument("reconstruct: --calib-dir belongs to --method quasi");
    if (!request.calib.empty())
      throw std::invalid_argument("reconstruct: --calib and --calib-dir exclude each other");
    if (!request.depth.empty())
      throw std::invalid_argument("reconstruct: --depth is one camera's; not with --calib-dir");
    return;
  }
  if (!request.head.empty() || !request.per_camera.empty())
    throw std::invalid_argument("reconstruct: --head and --per-camera belong to --calib-dir");
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
PhaseSource phaseForCalibration(const ReconstructRequest& request,
                                const algo::QuasiCalibration& calib) {
  const PhaseSource recorded = calib.info().phase_source;
  if (request.phase.empty()) return recorded;
  const PhaseSource asked = parsePhaseSource(request.phase);
  if (asked != recorded) {
    throw formats::InputError(request.calib,
                              "calibrated on the " + std::string(toString(recorded)) +
                                  " phase, but --phase " + request.phase + " was asked");
  }
  return asked;
}

struct Reconstruction {
  cv::Mat xyz;  // CV_32FC3 on the main grid, NaN where invalid
  cv::Mat texture;
  PhaseSource phase = PhaseSource::Fused;
  double phase_valid_fraction = 0;
  std::vector<std::string> warnings;
  double phase_ms = 0;
  double reconstruct_ms = 0;
};

Reconstruction reconstructQuasi(const ReconstructRequest& request,
                                const formats::CaptureBundleReader& bundle) {
  const algo::QuasiCalibration calib = readQuasiCalibration(request.calib);
  firmware::requireCamera(bundle, "main");
  try {
    calib.requireImageSize(bundle.frameSize("main"));
  } catch (const std::invalid_argument& e) {
    throw formats::InputError(
        request.calib, std::string(e.what()) + " (" + (bundle.dir() / "main").string() + ")");
  }
  Reconstruction out;
  out.phase = phaseForCalibration(request, calib);
  firmware::Stopwatch watch;
  firmware::BundlePhaseOptions phase_options;
  phase_options.order_reference_rad = firmware::orderReference(calib.info());
  const firmware::BundlePhase main = firmware::computeBundlePhase(bundle, "main", phase_options);
  out.phase_ms = watch.lapMs();
  if (auto warning = firmware::orderDriftWarning("main", main.maps.order_residual, calib.info()))
    out.warnings.push_back(std::move(*warning));
  out.xyz = calib.evaluate(firmware::absolutePhase(main.maps, out.phase));
  out.reconstruct_ms = watch.lapMs();
  out.texture = main.maps.texture;
  out.phase_valid_fraction = main.maps.valid_fraction;
  return out;
}

Reconstruction reconstructStereo(const ReconstructRequest& request,
                                 const formats::CaptureBundleReader& bundle) {
  const formats::StereoCalibration stereo = formats::readStereoCalibration(request.stereo);
  firmware::requireCamera(bundle, "main");
  firmware::requireCamera(bundle, "aux");
  for (const char* camera : {"main", "aux"}) {
    firmware::requireStereoImageSize(request.stereo, stereo, bundle.frameSize(camera),
                                     bundle.dir() / camera);
  }
  Reconstruction out;
  out.phase = request.phase.empty() ? PhaseSource::Fused : parsePhaseSource(request.phase);
  firmware::Stopwatch watch;
  const firmware::BundlePhase main = firmware::computeBundlePhase(bundle, "main");
  // Stereo matches equal phases: aux numbers its orders about main's centre.
  firmware::BundlePhaseOptions aux_options;
  if (main.maps.order_residual.samples > 0)
    aux_options.order_reference_rad = main.maps.order_residual.centre_rad;
  const firmware::BundlePhase aux = firmware::computeBundlePhase(bundle, "aux", aux_options);
  out.phase_ms = watch.lapMs();
  const algo::PhaseStereo matcher(firmware::toStereoGeometry(stereo));
  out.xyz = matcher
                .reconstruct(firmware::absolutePhase(main.maps, out.phase),
                             firmware::absolutePhase(aux.maps, out.phase))
                .xyz;
  out.reconstruct_ms = watch.lapMs();
  out.texture = main.maps.texture;
  out.phase_valid_fraction = main.maps.valid_fraction;
  return out;
}

// Every calibrated camera of the bundle, merged into the head frame.
void runMerged(const ReconstructRequest& request) {
  firmware::Stopwatch total;
  const formats::CaptureBundleReader bundle(request.bundle);
  const std::vector<std::string> cameras = calibratedCameras(bundle, request.calib_dir);
  if (cameras.empty()) {
    throw formats::InputError(request.calib_dir, "no <camera>.qcal for any camera of " +
                                                     (bundle.dir() / "capture.json").string());
  }
  std::optional<formats::HeadExtrinsics> head;
  if (!request.head.empty()) {
    head = formats::readHeadExtrinsics(request.head);
    for (const std::string& camera : cameras) {
      if (!head->hasCamera(camera))
        throw formats::InputError(request.head, "no pose for camera '" + camera + "'");
    }
  } else if (cameras.size() > 1 || cameras.front() != "main") {
    throw std::invalid_argument(
        "reconstruct: " + std::to_string(cameras.size()) +
        " calibrated cameras (or one that is not main) need --head head.json");
  }
  if (!request.per_camera.empty()) fs::create_directories(request.per_camera);
  std::vector<firmware::CameraCloud> clouds;
  nlohmann::json per_camera = nlohmann::json::array();
  for (const std::string& camera : cameras) {
    const CameraReconstruction r = reconstructCamera(
        bundle, camera, calibrationFileOf(request.calib_dir, camera), request.phase);
    formats::PointCloud cloud = cloudOfMaps(r.xyz, r.texture);
    nlohmann::json entry = {{"camera", camera},
                            {"phase", toString(r.phase)},
                            {"points", cloud.size()},
                            {"phase_valid_fraction", r.phase_valid_fraction},
                            {"warnings", r.warnings}};
    for (const std::string& warning : r.warnings)
      std::cerr << "warning: " << warning << "\n";
    if (!request.per_camera.empty()) {
      const fs::path file = fs::path(request.per_camera) / ("cloud-" + camera + ".ply");
      formats::writePly(file, cloud);
      entry["out"] = file.string();
    }
    per_camera.push_back(entry);
    clouds.push_back({camera, std::move(cloud)});
  }
  const formats::PointCloud merged = firmware::mergeCameraClouds(clouds, head ? &*head : nullptr);
  formats::writePly(request.out, merged);
  if (request.json) {
    std::cout << nlohmann::json{{"method", "quasi"},
                                {"frame", "main"},
                                {"cameras", per_camera},
                                {"points", merged.size()},
                                {"timings_ms", {{"total", total.elapsedMs()}}},
                                {"out", request.out}}
                     .dump()
              << "\n";
    return;
  }
  std::cout << "reconstruct (quasi, " << cameras.size() << " camera"
            << (cameras.size() == 1 ? "" : "s") << ", head frame): " << merged.size()
            << " points -> " << request.out << "\n";
  for (const auto& entry : per_camera) {
    std::cout << "  " << entry["camera"].get<std::string>() << ": "
              << entry["points"].get<std::size_t>() << " points\n";
  }
}

void runReconstruct(const ReconstructRequest& request) {
  firmware::Stopwatch total;
  checkMethodOptions(request);
  if (!request.calib_dir.empty()) {
    if (!request.phase.empty()) parsePhaseSource(request.phase);
    runMerged(request);
    return;
  }
  if (!request.phase.empty()) parsePhaseSource(request.phase);
  const formats::CaptureBundleReader bundle(request.bundle);
  const Reconstruction r = request.method == "quasi" ? reconstructQuasi(request, bundle)
                                                     : reconstructStereo(request, bundle);
  firmware::Stopwatch watch;
  const formats::PointCloud cloud = cloudOfMaps(r.xyz, r.texture);
  formats::writePly(request.out, cloud);
  if (!request.depth.empty()) formats::writeFloatTiff(request.depth, depthOfMap(r.xyz));
  const double write_ms = watch.lapMs();
  const double pixels = r.xyz.total();
  for (const std::string& warning : r.warnings)
    std::cerr << "warning: " << warning << "\n";
  if (request.json) {
    nlohmann::json summary = {{"method", request.method},
                              {"phase", toString(r.phase)},
                              {"width", r.xyz.cols},
                              {"height", r.xyz.rows},
                              {"points", cloud.size()},
                              {"point_fraction", static_cast<double>(cloud.size()) / pixels},
                              {"phase_valid_fraction", r.phase_valid_fraction},
                              {"warnings", r.warnings},
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
  cmd->add_option("--calib-dir", request->calib_dir,
                  "360° head: a directory of <camera>.qcal; every calibrated camera of the "
                  "bundle, merged in the head frame (PLY with a uchar camera property)");
  cmd->add_option("--head", request->head,
                  "the head's extrinsics (head.json; needed with --calib-dir when more than "
                  "main is calibrated)");
  cmd->add_option(
      "--per-camera", request->per_camera,
      "with --calib-dir: also write OUTDIR/cloud-<camera>.ply, each in its camera's frame");
  cmd->add_flag("--json", request->json, "print the summary as one JSON object");
  cmd->callback([request] { runReconstruct(*request); });
}

}  // namespace cylscan::tools
