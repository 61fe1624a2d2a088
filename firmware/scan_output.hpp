// SPDX-License-Identifier: Apache-2.0
// A scan's stored outputs, the step after the acquisition shared by the
// daemon and `cylscan scan`: from the phase the acquisition folded (a
// PhaseSink) and the calibrations to the files (main's point cloud and depth
// map, the previews, and for a 360° scan each camera's cloud and the cloud
// merged in the head frame) and the figures the scan reports about them.
//
// The files are written all or none: each under a temporary name first, then
// renamed into place once every one is written, so a failure part-way (a
// calibration that does not fit, a full disk) leaves none of them behind.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "algo/quasi_calibration.hpp"
#include "firmware/acquisition.hpp"
#include "firmware/phase_sink.hpp"
#include "firmware/reconstruction.hpp"
#include "formats/head_extrinsics.hpp"

namespace cylscan::firmware {

// An installed calibration (or head.json) that cannot be used: unreadable,
// corrupt, or made for another image size. The message names the file and
// says to install it again.
class UnusableCalibration : public ScanError {
 public:
  // `camera` empty: the head extrinsics.
  UnusableCalibration(std::string camera, const std::filesystem::path& file,
                      const std::string& reason);
  const std::string& camera() const { return camera_; }

 private:
  std::string camera_;
};

// A directory of installed calibrations: <camera>.qcal (cylscan calibrate)
// and head.json (cylscan calibrate-head), e.g. the daemon's DATA/calibration.
class CalibrationDir {
 public:
  explicit CalibrationDir(std::filesystem::path dir) : dir_(std::move(dir)) {}

  const std::filesystem::path& dir() const { return dir_; }
  // <camera>.qcal, whether or not it exists; std::invalid_argument for a
  // name that is not a camera name (common/vocabulary.hpp).
  std::filesystem::path calibrationFile(std::string_view camera) const;
  std::filesystem::path headFile() const { return dir_ / "head.json"; }

  // The camera's calibration checked against the camera's image size;
  // nullopt when none is installed, UnusableCalibration otherwise.
  std::optional<algo::QuasiCalibration> calibration(std::string_view camera,
                                                    cv::Size image_size) const;
  // The head extrinsics; nullopt when none are installed, UnusableCalibration
  // (camera empty) when they cannot be read.
  std::optional<formats::HeadExtrinsics> head() const;

 private:
  std::filesystem::path dir_;
};

// What the outputs are made with.
struct ScanCalibrations {
  // Main's, loaded and checked by the caller before the scan (the phase it
  // was fitted on decides the scan's; a bad one must stop the scan before the
  // head moves). nullopt: main is not calibrated.
  std::optional<algo::QuasiCalibration> main;
  // The other cameras' of a 360° scan and head.json, each read when its turn
  // comes (one calibration in memory besides main's). nullopt: none.
  std::optional<CalibrationDir> installed;
};

// Which files are written, named relative to the output directory (an
// absolute name is used as it is); an empty name is not written.
struct ScanOutputOptions {
  PhaseSource phase = PhaseSource::Fused;  // main's absolute phase
  int bit_depth = 8;                       // main's counts, for texture.png
  std::string cloud = "cloud.ply";         // main's cloud; a 360° scan's merged one
  std::string depth = "depth.tiff";        // main's depth map (float Z)
  bool previews = true;                    // texture.png, phase.png, depth.png
  // The cameras of a 360° scan (main first): each calibrated one's cloud in
  // clouds/<camera>.ply, and `cloud` merged from them in the head frame.
  // Empty: main alone.
  std::vector<std::string> ring_cameras;
};

// One camera of a 360° scan.
struct CameraOutput {
  std::string camera;
  bool calibrated = false;
  std::size_t points = 0;
  // When calibrated: the phase used, its valid fraction and the cloud's file.
  PhaseSource phase = PhaseSource::Fused;
  double phase_valid_fraction = 0.0;
  std::string file;
};

// What `cloud` of a 360° scan holds: nothing (no camera calibrated), main's
// points alone (head.json missing or lacking a calibrated camera), or every
// calibrated camera's.
enum class MergedCloud { kNone, kMain, kMerged };
std::string toString(MergedCloud cloud);
MergedCloud parseMergedCloud(const std::string& name);  // std::invalid_argument

struct RingOutput {
  std::vector<CameraOutput> cameras;  // every camera of the scan, in its order
  MergedCloud cloud = MergedCloud::kNone;
  std::string cloud_note;  // why the cloud is not merged; empty when it is
};

// What the outputs show of the scan.
struct OutputFigures {
  PhaseSource phase = PhaseSource::Fused;
  double phase_valid_fraction = 0.0;  // main's
  // Main's order residual: the low set's offset against the high set as the
  // residuals' centre, their spread and the bound the validity rule used.
  algo::OrderResidual order_residual;
  // The points of `cloud`: main's when calibrated; for a 360° scan always
  // (0 when no cloud was written).
  std::optional<std::size_t> points;
  std::optional<RingOutput> ring;  // a 360° scan's
};

// The order residual as the reports show it: centre_rad, spread_rad,
// bound_rad, samples.
nlohmann::json orderResidualJson(const algo::OrderResidual& residual);

struct ScanResult {
  // Written, by name: `cloud`, `depth`, texture.png, phase.png, depth.png,
  // then clouds/<camera>.ply in the cameras' order.
  std::vector<std::string> files;
  bool calibrated = false;  // main had a calibration
  OutputFigures figures;
  // What the scan should know of its phase: a calibrated camera's order
  // residual that moved from its calibration's (orderDriftWarning).
  std::vector<std::string> warnings;
};

// Writes the outputs of the scan whose frames `phase` folded into `dir`
// (empty: the working directory), all or none. Throws UnusableCalibration for an
// installed calibration that cannot be used, and the writers' errors
// (std::system_error naming the file).
ScanResult writeScanOutput(PhaseSink& phase, const ScanCalibrations& calibrations,
                           const ScanOutputOptions& options, const std::filesystem::path& dir);

}  // namespace cylscan::firmware
