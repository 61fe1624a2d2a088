// SPDX-License-Identifier: Apache-2.0
#include "tools/camera_reconstruction.hpp"

#include <stdexcept>
#include <system_error>

#include "firmware/stopwatch.hpp"
#include "formats/input_error.hpp"
#include "tools/cloud_output.hpp"

namespace cylscan::tools {

namespace fs = std::filesystem;

fs::path calibrationFileOf(const fs::path& calib_dir, const std::string& camera) {
  return calib_dir / (camera + ".qcal");
}

std::vector<std::string> calibratedCameras(const formats::CaptureBundleReader& bundle,
                                           const fs::path& calib_dir) {
  std::error_code ec;
  if (!fs::is_directory(calib_dir, ec)) {
    throw formats::InputError(calib_dir, "not a directory of <camera>.qcal calibrations");
  }
  std::vector<std::string> cameras;
  for (const std::string& camera : bundle.info().cameras) {
    if (fs::exists(calibrationFileOf(calib_dir, camera), ec)) cameras.push_back(camera);
  }
  return cameras;
}

CameraReconstruction reconstructCamera(const formats::CaptureBundleReader& bundle,
                                       const std::string& camera, const fs::path& calib_file,
                                       const std::string& phase) {
  const algo::QuasiCalibration calib = readQuasiCalibration(calib_file);
  firmware::requireCamera(bundle, camera);
  try {
    calib.requireImageSize(bundle.frameSize(camera));
  } catch (const std::invalid_argument& e) {
    throw formats::InputError(
        calib_file, std::string(e.what()) + " (" + (bundle.dir() / camera).string() + ")");
  }
  CameraReconstruction out;
  out.camera = camera;
  const PhaseSource recorded = calib.info().phase_source;
  out.phase = recorded;
  if (!phase.empty() && parsePhaseSource(phase) != recorded) {
    throw formats::InputError(calib_file, "calibrated on the " + std::string(toString(recorded)) +
                                              " phase, but --phase " + phase + " was asked");
  }
  firmware::Stopwatch watch;
  firmware::BundlePhaseOptions phase_options;
  phase_options.order_reference_rad = firmware::orderReference(calib.info());
  const firmware::BundlePhase maps = firmware::computeBundlePhase(bundle, camera, phase_options);
  out.phase_ms = watch.lapMs();
  if (auto warning = firmware::orderDriftWarning(camera, maps.maps.order_residual, calib.info()))
    out.warnings.push_back(std::move(*warning));
  out.xyz = calib.evaluate(firmware::absolutePhase(maps.maps, out.phase));
  out.reconstruct_ms = watch.lapMs();
  out.texture = maps.maps.texture;
  out.phase_valid_fraction = maps.maps.valid_fraction;
  return out;
}

}  // namespace cylscan::tools
