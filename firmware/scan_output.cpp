// SPDX-License-Identifier: Apache-2.0
#include "firmware/scan_output.hpp"

#include <stdexcept>
#include <system_error>
#include <utility>

#include "common/vocabulary.hpp"
#include "formats/images.hpp"
#include "formats/point_cloud.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;

std::string unusableMessage(const std::string& camera, const fs::path& file,
                            const std::string& reason) {
  if (camera.empty()) {
    return "the installed head extrinsics " + file.string() +
           " are unusable (install them again): " + reason;
  }
  return "the installed calibration " + file.string() +
         " is unusable (install it again): " + reason;
}

// A writer's error about a temporary file, told of the file it stands for.
class OutputFileError : public std::system_error {
 public:
  OutputFileError(std::error_code code, std::string message)
      : std::system_error(code), message_(std::move(message)) {}
  const char* what() const noexcept override { return message_.c_str(); }

 private:
  std::string message_;
};

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  for (std::size_t at = text.find(from); at != std::string::npos;
       at = text.find(from, at + to.size()))
    text.replace(at, from.size(), to);
  return text;
}

// Files written under temporary names beside their own and renamed into
// place together by commit(). Until then, destroying it removes the
// temporaries and the directories made for them, so a failure part-way
// leaves nothing. A failure during commit() itself (a rename: the file
// system going away) leaves the files renamed before it.
class StagedFiles {
 public:
  explicit StagedFiles(fs::path dir) : dir_(std::move(dir)) {}
  ~StagedFiles() { rollback(); }
  StagedFiles(const StagedFiles&) = delete;
  StagedFiles& operator=(const StagedFiles&) = delete;

  // Writes the file `name` (relative to the directory) by `write(path)` to
  // its temporary; errors name the file, not the temporary.
  template <typename Write>
  void write(const std::string& name, Write&& write) {
    const fs::path target = dir_ / name;
    const fs::path temporary =
        target.parent_path() / ("." + target.filename().string() + ".partial");
    staged_.push_back({temporary, target});
    try {
      write(temporary);
    } catch (const std::system_error& e) {
      throw OutputFileError(e.code(), replaced(e.what(), temporary.string(), target.string()));
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(replaced(e.what(), temporary.string(), target.string()));
    }
  }

  // The directory `name` (relative to the directory), made unless it exists.
  void makeDirectory(const std::string& name) {
    if (fs::create_directory(dir_ / name)) made_.push_back(dir_ / name);
  }

  void commit() {
    for (const Staged& file : staged_)
      fs::rename(file.temporary, file.target);
    staged_.clear();
    made_.clear();
  }

 private:
  struct Staged {
    fs::path temporary, target;
  };

  void rollback() noexcept {
    std::error_code ec;
    for (const Staged& file : staged_)
      fs::remove(file.temporary, ec);
    for (auto it = made_.rbegin(); it != made_.rend(); ++it)
      fs::remove(*it, ec);  // only when empty: another writer's files stay
  }

  fs::path dir_;
  std::vector<Staged> staged_;
  std::vector<fs::path> made_;
};

// One scan's outputs being written: the options, the calibrations, the
// files staged so far and the result.
class OutputWriter {
 public:
  OutputWriter(PhaseSink& phase, const ScanCalibrations& calibrations,
               const ScanOutputOptions& options, const fs::path& dir)
      : phase_(phase), calibrations_(calibrations), options_(options), staged_(dir) {}

  ScanResult write() {
    const algo::PhaseMaps maps = phase_.finalize(
        "main", calibrations_.main ? orderReference(calibrations_.main->info()) : std::nullopt);
    result_.calibrated = calibrations_.main.has_value();
    if (calibrations_.main) warnIfDrifted("main", maps, calibrations_.main->info());
    result_.figures.phase = options_.phase;
    result_.figures.phase_valid_fraction = maps.valid_fraction;
    result_.figures.order_residual = maps.order_residual;
    const bool ring = !options_.ring_cameras.empty();
    cv::Mat xyz, depth;
    if (calibrations_.main) {
      xyz = calibrations_.main->evaluate(absolutePhase(maps, options_.phase));
      if (!ring && !options_.cloud.empty()) {
        const formats::PointCloud cloud = cloudOfMaps(xyz, maps.texture);
        output(options_.cloud, [&](const fs::path& file) { formats::writePly(file, cloud); });
        result_.figures.points = cloud.size();
      }
      depth = depthOfMap(xyz);
      if (!options_.depth.empty())
        output(options_.depth, [&](const fs::path& file) { formats::writeFloatTiff(file, depth); });
    }
    if (options_.previews) {
      output("texture.png", [&](const fs::path& file) {
        formats::writePng(file, texturePreview(maps.texture, options_.bit_depth));
      });
      output("phase.png", [&](const fs::path& file) {
        formats::writePng(file, previewOfMap(absolutePhase(maps, options_.phase)));
      });
      if (!depth.empty()) {
        output("depth.png",
               [&](const fs::path& file) { formats::writePng(file, previewOfMap(depth)); });
      }
    }
    if (ring) result_.figures.ring = writeRing(maps, xyz);
    staged_.commit();
    return std::move(result_);
  }

 private:
  // Writes the file `name` by `write(path)` and lists it.
  template <typename Write>
  void output(const std::string& name, Write&& write) {
    staged_.write(name, std::forward<Write>(write));
    result_.files.push_back(name);
  }

  // Every camera's cloud in its own frame, and the merged cloud.
  RingOutput writeRing(const algo::PhaseMaps& main_maps, const cv::Mat& main_xyz) {
    const std::optional<formats::HeadExtrinsics> head =
        calibrations_.installed ? calibrations_.installed->head() : std::nullopt;
    RingOutput ring;
    std::vector<CameraCloud> clouds;
    for (const std::string& camera : options_.ring_cameras) {
      CameraOutput entry;
      entry.camera = camera;
      std::optional<CameraCloud> cloud = cameraCloud(camera, main_maps, main_xyz, entry);
      if (cloud) {
        staged_.makeDirectory("clouds");
        entry.file = "clouds/" + camera + ".ply";
        output(entry.file, [&](const fs::path& file) { formats::writePly(file, cloud->cloud); });
        clouds.push_back(std::move(*cloud));
      }
      ring.cameras.push_back(std::move(entry));
    }
    std::vector<CameraCloud> parts = mergedParts(std::move(clouds), head, ring);
    result_.figures.points = 0;
    if (parts.empty() || options_.cloud.empty()) return ring;
    const formats::PointCloud merged = mergeCameraClouds(parts, head ? &*head : nullptr);
    // Listed first, as main's cloud of a one-camera scan is.
    staged_.write(options_.cloud, [&](const fs::path& file) { formats::writePly(file, merged); });
    result_.files.insert(result_.files.begin(), options_.cloud);
    result_.figures.points = merged.size();
    return ring;
  }

  void warnIfDrifted(const std::string& camera, const algo::PhaseMaps& maps,
                     const algo::QuasiCalibrationInfo& calibration) {
    if (auto warning = orderDriftWarning(camera, maps.order_residual, calibration))
      result_.warnings.push_back(std::move(*warning));
  }

  // `camera`'s cloud when it is calibrated (main with the scan's phase, the
  // others each with its calibration's own), filling in `entry`.
  std::optional<CameraCloud> cameraCloud(const std::string& camera,
                                         const algo::PhaseMaps& main_maps, const cv::Mat& main_xyz,
                                         CameraOutput& entry) {
    std::optional<CameraCloud> out;
    if (camera == "main") {
      if (!calibrations_.main) return out;
      entry.phase = options_.phase;
      entry.phase_valid_fraction = main_maps.valid_fraction;
      out = CameraCloud{camera, cloudOfMaps(main_xyz, main_maps.texture)};
    } else {
      if (!calibrations_.installed) return out;
      const CalibrationDir& installed = *calibrations_.installed;
      std::error_code ec;
      if (!fs::exists(installed.calibrationFile(camera), ec)) return out;
      const std::optional<algo::QuasiCalibration> calib =
          installed.calibration(camera, phase_.frameSize(camera));
      if (!calib) return out;  // removed meanwhile
      const algo::PhaseMaps maps = phase_.finalize(camera, orderReference(calib->info()));
      warnIfDrifted(camera, maps, calib->info());
      entry.phase = calib->info().phase_source;
      entry.phase_valid_fraction = maps.valid_fraction;
      out = CameraCloud{
          camera, cloudOfMaps(calib->evaluate(absolutePhase(maps, entry.phase)), maps.texture)};
    }
    entry.calibrated = true;
    entry.points = out->cloud.size();
    return out;
  }

  // The clouds that go into the merged cloud: all of them when head.json
  // places every camera besides main; else main's alone, and why.
  static std::vector<CameraCloud> mergedParts(std::vector<CameraCloud> clouds,
                                              const std::optional<formats::HeadExtrinsics>& head,
                                              RingOutput& ring) {
    std::string missing;
    for (const CameraCloud& c : clouds) {
      if (c.camera != "main" && (!head || !head->hasCamera(c.camera)))
        missing += (missing.empty() ? "" : ", ") + c.camera;
    }
    if (clouds.empty()) {
      ring.cloud = MergedCloud::kNone;
      ring.cloud_note = "no camera is calibrated (PUT /api/v1/calibration?camera=NAME)";
      return {};
    }
    if (missing.empty()) {
      ring.cloud = MergedCloud::kMerged;
      return clouds;
    }
    ring.cloud_note = (head ? "the installed head.json has no pose for "
                            : "no head extrinsics installed (PUT /api/v1/head) for ") +
                      missing + ": cloud.ply is main's alone";
    std::vector<CameraCloud> parts;
    for (CameraCloud& c : clouds) {
      if (c.camera == "main") parts.push_back(std::move(c));
    }
    ring.cloud = parts.empty() ? MergedCloud::kNone : MergedCloud::kMain;
    return parts;
  }

  PhaseSink& phase_;
  const ScanCalibrations& calibrations_;
  const ScanOutputOptions& options_;
  StagedFiles staged_;
  ScanResult result_;
};

}  // namespace

UnusableCalibration::UnusableCalibration(std::string camera, const fs::path& file,
                                         const std::string& reason)
    : ScanError(unusableMessage(camera, file, reason)), camera_(std::move(camera)) {}

fs::path CalibrationDir::calibrationFile(std::string_view camera) const {
  if (!isCameraName(camera))
    throw std::invalid_argument("not a camera name: '" + std::string(camera) + "'");
  return dir_ / (std::string(camera) + ".qcal");
}

std::optional<algo::QuasiCalibration> CalibrationDir::calibration(std::string_view camera,
                                                                  cv::Size image_size) const {
  const fs::path file = calibrationFile(camera);
  std::error_code ec;
  if (!fs::exists(file, ec)) return std::nullopt;
  try {
    algo::QuasiCalibration calib = readQuasiCalibration(file);
    calib.requireImageSize(image_size);
    return calib;
  } catch (const std::exception& e) {
    throw UnusableCalibration(std::string(camera), file, e.what());
  }
}

std::optional<formats::HeadExtrinsics> CalibrationDir::head() const {
  const fs::path file = headFile();
  std::error_code ec;
  if (!fs::exists(file, ec)) return std::nullopt;
  try {
    return formats::readHeadExtrinsics(file);
  } catch (const std::exception& e) {
    throw UnusableCalibration("", file, e.what());
  }
}

std::string toString(MergedCloud cloud) {
  switch (cloud) {
    case MergedCloud::kNone:
      return "none";
    case MergedCloud::kMain:
      return "main";
    case MergedCloud::kMerged:
      return "merged";
  }
  return "none";
}

MergedCloud parseMergedCloud(const std::string& name) {
  if (name == "none") return MergedCloud::kNone;
  if (name == "main") return MergedCloud::kMain;
  if (name == "merged") return MergedCloud::kMerged;
  throw std::invalid_argument("cloud must be none, main or merged, not '" + name + "'");
}

ScanResult writeScanOutput(PhaseSink& phase, const ScanCalibrations& calibrations,
                           const ScanOutputOptions& options, const fs::path& dir) {
  return OutputWriter(phase, calibrations, options, dir).write();
}

nlohmann::json orderResidualJson(const algo::OrderResidual& residual) {
  return {{"centre_rad", residual.centre_rad},
          {"spread_rad", residual.spread_rad},
          {"bound_rad", residual.bound_rad},
          {"samples", residual.samples},
          {"decided_by_neighbours", residual.decided_by_neighbours}};
}

}  // namespace cylscan::firmware
