// SPDX-License-Identifier: Apache-2.0
#include "tools/sim_dataset.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <set>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "drivers/sim/calibration_targets.hpp"
#include "drivers/sim/ring_head.hpp"
#include "formats/atomic_file.hpp"
#include "formats/capture_bundle.hpp"
#include "formats/checkerboard_set.hpp"
#include "formats/images.hpp"
#include "formats/stereo_calibration.hpp"
#include "tools/sim_capture.hpp"
#include "tools/sim_scenes.hpp"

namespace cylscan::tools {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using sim::Vec3;

// The checkerboard set: each pose one still of main and aux under the scene's
// ambient light, kept only when OpenCV finds every corner at the truth.
class BoardSet {
 public:
  explicit BoardSet(VirtualCapture& capture) : capture_(capture), head_(capture.head()) {}

  // One pair per scene of `stills`: one board each, all of the same size (boardStills).
  void write(const fs::path& dir, const std::vector<sim::Scene>& stills, json& truth) {
    const auto& proto = std::get<sim::Checkerboard>(stills.front().objects.front().shape);
    fs::create_directories(dir / "main");
    fs::create_directories(dir / "aux");
    formats::writeCheckerboardInfo(dir, {proto.cols, proto.rows, proto.square_mm});
    for (std::size_t i = 0; i < stills.size(); ++i) {
      const auto& board = std::get<sim::Checkerboard>(stills[i].objects.front().shape);
      const auto images = capture_.still(stills[i], {"main", "aux"});
      checkCorners(images[0], board, "main", i);
      checkCorners(images[1], board, "aux", i);
      const std::string id =
          formats::frameFileName(static_cast<int>(i), static_cast<int>(stills.size()));
      formats::writePng(dir / "main" / (id + ".png"), images[0]);
      formats::writePng(dir / "aux" / (id + ".png"), images[1]);
      truth[id] = {{"center", vecJson(board.center)}, {"rotation", matrixJson(board.rotation)}};
    }
    boards_ = static_cast<int>(stills.size());
  }

  int boards() const { return boards_; }
  double cornerError() const { return corner_error_; }

 private:
  // Every board image must be usable: OpenCV finds the corners, at the truth.
  void checkCorners(const cv::Mat& image, const sim::Checkerboard& board, const char* camera,
                    std::size_t pose) {
    cv::Mat eight = image;
    const int bits = head_.cameraModel(camera).params().bit_depth;
    if (image.depth() != CV_8U) image.convertTo(eight, CV_8U, 255.0 / ((1 << bits) - 1));
    std::vector<cv::Point2f> found;
    const std::string where = std::string(camera) + " board " + std::to_string(pose);
    if (!cv::findChessboardCorners(eight, {board.cols, board.rows}, found)) {
      throw std::runtime_error("simulate: OpenCV does not find the corners of " + where);
    }
    cv::cornerSubPix(eight, found, {5, 5}, {-1, -1},
                     {cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-3});
    const sim::CameraModel& cam = head_.cameraModel(camera);
    const auto truth = board.corners();
    double forward = 0, backward = 0;
    for (std::size_t i = 0; i < truth.size(); ++i) {
      const auto a = cam.project(truth[i]), b = cam.project(truth[truth.size() - 1 - i]);
      forward = std::max(forward, std::hypot(a->x() - found[i].x, a->y() - found[i].y));
      backward = std::max(backward, std::hypot(b->x() - found[i].x, b->y() - found[i].y));
    }
    corner_error_ = std::max(corner_error_, std::min(forward, backward));
  }

  VirtualCapture& capture_;
  sim::VirtualHead& head_;
  int boards_ = 0;
  double corner_error_ = 0;
};

// The checkerboard stills: the board's targets (scenes/calibration/boardNN.toml)
// in order, then, past the last file, the generator's poses for this head
// from that index on. board/sim's files are the generator's first poses for
// its head (tests/sim/calibration_targets_test.cpp), so there the sequence
// simply goes on; a board without files gets the generator's alone.
std::vector<sim::Scene> boardStills(const fs::path& dir, int count, const sim::VirtualHead& head) {
  std::vector<sim::Scene> scenes = sim::loadCalibrationScenes(dir, "board");
  const auto shipped = static_cast<int>(scenes.size());
  if (count <= shipped) {
    scenes.resize(static_cast<std::size_t>(count));
  } else {
    const auto poses =
        sim::calibrationBoardPoses(head.cameraModel("main"), head.cameraModel("aux"), count);
    for (int i = shipped; i < count; ++i)
      scenes.push_back(sim::calibrationScene(poses[static_cast<std::size_t>(i)], i));
  }
  const sim::Checkerboard* first = nullptr;
  for (int i = 0; i < count; ++i) {
    const sim::Scene& s = scenes[static_cast<std::size_t>(i)];
    const auto* board =
        s.objects.size() == 1 ? std::get_if<sim::Checkerboard>(&s.objects.front().shape) : nullptr;
    if (first == nullptr) first = board;
    if (board == nullptr || board->cols != first->cols || board->rows != first->rows ||
        board->square_mm != first->square_mm) {
      const std::string stem = sim::calibrationSceneStem("board", i);
      throw std::invalid_argument(
          (i < shipped ? (dir / (stem + ".toml")).string() : "generated target " + stem) +
          ": a checkerboard target must be one checkerboard, of the same size as board00's");
    }
  }
  return scenes;
}

// The calibration planes: the first `count` of the board's targets
// (scenes/calibration/planeNN.toml). Asked for more than it has, `count`
// generated planes spread over the working range instead: a spread set
// depends on its count, so the shipped one cannot begin a larger one.
std::vector<sim::Scene> planeScenes(const fs::path& dir, int count) {
  std::vector<sim::Scene> scenes = sim::loadCalibrationScenes(dir, "plane");
  if (static_cast<int>(scenes.size()) < count) {
    scenes.clear();
    const auto poses = sim::calibrationPlanePoses(count);
    for (int i = 0; i < count; ++i)
      scenes.push_back(sim::calibrationScene(poses[static_cast<std::size_t>(i)], i));
    return scenes;
  }
  scenes.resize(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i) {
    const sim::Scene& s = scenes[static_cast<std::size_t>(i)];
    if (s.objects.size() != 1 || !std::holds_alternative<sim::Plane>(s.objects.front().shape)) {
      throw std::invalid_argument(
          (dir / (sim::calibrationSceneStem("plane", i) + ".toml")).string() +
          ": a plane target must be one plane");
    }
  }
  return scenes;
}

// The true stereo calibration of main and aux (docs/formats.md, stereo calibration).
formats::StereoCalibration stereoTruth(const sim::VirtualHead& head) {
  const sim::CameraModel& main = head.cameraModel("main");
  const sim::CameraModel& aux = head.cameraModel("aux");
  auto k = [](const sim::CameraParams& p) {
    return cv::Matx33d(p.fx, 0, p.cx, 0, p.fy, p.cy, 0, 0, 1);
  };
  formats::StereoCalibration c;
  c.image_width = main.width();
  c.image_height = main.height();
  c.camera_matrix_main = k(main.params());
  c.dist_coeffs_main = {main.params().k1, main.params().k2, 0, 0, 0};
  c.camera_matrix_aux = k(aux.params());
  c.dist_coeffs_aux = {aux.params().k1, aux.params().k2, 0, 0, 0};
  // X_aux = R X_main + T with R = R_aux←main, T = −R C_aux (main is the frame).
  const sim::Mat3 r = aux.rotationCamFromMain() * main.rotationCamFromMain().transpose();
  const Vec3 t = -aux.rotationCamFromMain() * (aux.centre() - main.centre());
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j)
      c.R(i, j) = r(i, j);
    c.T[i] = t[i];
  }
  return c;
}

}  // namespace

void writeDataset(const SimulateRequest& request, const drivers::BoardProfile& profile,
                  const firmware::ScanOptions& options, const firmware::ScanPlan& plan,
                  const json& bundle_extra, const json& truth_extra, SimClock::time_point started) {
  std::vector<sim::Scene> tests = testScenes();
  std::set<std::string> names;
  for (const auto& s : tests)
    names.insert(s.name);
  for (const std::string& file : request.scenes) {
    sim::Scene s = sim::loadScene(file);
    if (!names.insert(s.name).second) {
      throw std::invalid_argument(file + ": scene name '" + s.name + "' is already used");
    }
    tests.push_back(std::move(s));
  }
  const StudyScenes study = studyScenes(request);
  for (const auto& s : study.scenes) {
    if (!names.insert(s.name).second) {
      throw std::invalid_argument("simulate: study scene name '" + s.name + "' is already used");
    }
  }
  const sim::HeadConfig& config = profile.sim->head;
  if (config.cameras.size() < 2 || config.cameras[1].name != "aux") {
    throw std::invalid_argument(
        profile.file.string() +
        ": simulate needs a virtual head with the cameras 'main' and 'aux'");
  }

  VirtualCapture capture(profile, options);
  sim::VirtualHead& head = capture.head();
  const fs::path out(request.out);
  fs::create_directories(out);
  json truth = {{"scenes", json::object()}, {"calib", json::object()}, {"board", json::object()}};

  const fs::path targets = sim::calibrationScenesDir(profile.file.parent_path());
  BoardSet boards(capture);
  boards.write(out / "board", boardStills(targets, request.boards, head), truth["board"]);

  const sim::CameraParams& main_params = config.cameras.front();
  const auto bundleExtra = [&](const sim::Scene& s) {
    json extra = {{"device", "cylscan virtual head"},
                  {"board", profile.name},
                  {"mode", firmware::toString(options.mode)},
                  {"scene", s.name},
                  {"seed", request.seed},
                  {"exposure_us", main_params.exposure_us}};
    if (main_params.bit_depth > 8) extra["bit_depth"] = main_params.bit_depth;
    extra.update(bundle_extra);
    return extra;
  };
  const auto scan = [&](const fs::path& dir, const sim::Scene& s,
                        const std::vector<std::string>& cameras) {
    capture.scanBundle(dir, s, plan, cameras, bundleExtra(s));
  };

  const int poses = request.poses;
  const std::vector<sim::Scene> planes = planeScenes(targets, poses);
  for (int i = 0; i < poses; ++i) {
    sim::Scene s = planes[static_cast<std::size_t>(i)];
    s.name = "pose" + formats::frameFileName(i, poses);
    scan(out / "calib" / s.name, s, {"main", "aux"});
    truth["calib"][s.name] = truthOf(s);
  }
  for (const sim::Scene& s : tests) {
    scan(out / "test" / s.name, s, {"main"});
    truth["scenes"][s.name] = truthOf(s);
  }
  // After every default scene, so a dataset without study scenes is unchanged.
  for (const sim::Scene& s : study.scenes) {
    scan(out / "test" / s.name, s, {"main", "aux"});
    truth["scenes"][s.name] = truthOf(s);
  }
  if (!study.scenes.empty()) truth["study"] = study.index;

  const auto& proj = head.projector().params();
  const auto azimuths = sim::workingVolumeAzimuthDeg(head.cameraModel("main"), head.projector());
  const auto startDeg = [&](const firmware::SetPlan& set) {
    return static_cast<double>(set.positions.front()) / plan.steps_per_deg;
  };
  const int frames = static_cast<int>(plan.high.positions.size());
  truth["acquisition"] = {{"frames", frames},
                          {"high_start_deg", startDeg(plan.high)},
                          {"low_start_deg", startDeg(plan.low)},
                          {"steps_per_deg", plan.steps_per_deg},
                          {"azimuth_range_deg", {azimuths[0], azimuths[1]}},
                          {"projector_axis_origin_mm", proj.axis_origin_mm},
                          {"board", profile.file.string()},
                          {"seed", request.seed},
                          {"noise_scale", config.noise.scale}};
  truth["acquisition"].update(bundle_extra);
  truth["acquisition"].update(truth_extra);
  formats::writeStereoCalibration(out / "stereo_truth.yaml", stereoTruth(head));
  formats::writeFileAtomically(out / "truth.json", truth.dump(2) + "\n");

  const double seconds = std::chrono::duration<double>(SimClock::now() - started).count();
  const sim::CameraModel& main = head.cameraModel("main");
  if (request.json) {
    json names_json = json::array();
    for (const auto& s : tests)
      names_json.push_back(s.name);
    std::cout << json{{"out", out.string()},
                      {"board", profile.file.string()},
                      {"width", main.width()},
                      {"height", main.height()},
                      {"frames", frames},
                      {"seed", request.seed},
                      {"noise", request.noise},
                      {"board_pairs", boards.boards()},
                      {"board_corner_error_px", boards.cornerError()},
                      {"calib_poses", poses},
                      {"test_scenes", names_json},
                      {"study_scenes", study.scenes.size()},
                      {"fringe_frames_rendered", capture.triggers()},
                      {"high_start_deg", startDeg(plan.high)},
                      {"low_start_deg", startDeg(plan.low)},
                      {"azimuth_range_deg", {azimuths[0], azimuths[1]}},
                      {"seconds", seconds}}
                     .dump()
              << "\n";
  } else {
    std::cout << "simulate: " << boards.boards() << " board pairs (corners within "
              << boards.cornerError() << " px), " << poses << " calibration bundles, "
              << tests.size() << " test scenes, " << study.scenes.size() << " study scenes ("
              << main.width() << "x" << main.height() << ", N=" << frames << ", noise "
              << request.noise << ", seed " << request.seed << ") in " << seconds << " s -> "
              << out.string() << "\n";
  }
}

void writeCalibrationScenes(const SimulateRequest& request, const drivers::BoardProfile& profile) {
  const sim::HeadConfig& config = profile.sim->head;
  const auto model = [&](const std::string& name) {
    for (const sim::CameraParams& c : config.cameras)
      if (c.name == name) return sim::CameraModel(c);
    throw std::invalid_argument(profile.file.string() + ": the virtual head has no camera '" +
                                name + "' to place checkerboards for");
  };
  const auto boards = sim::calibrationBoardPoses(model("main"), model("aux"), request.boards);
  const auto planes = sim::calibrationPlanePoses(request.poses);
  const fs::path out(request.out);
  fs::create_directories(out);
  for (std::size_t i = 0; i < boards.size(); ++i) {
    const int n = static_cast<int>(i);
    formats::writeFileAtomically(out / (sim::calibrationSceneStem("board", n) + ".toml"),
                                 sim::calibrationSceneToml(boards[i], n));
  }
  for (std::size_t i = 0; i < planes.size(); ++i) {
    const int n = static_cast<int>(i);
    formats::writeFileAtomically(out / (sim::calibrationSceneStem("plane", n) + ".toml"),
                                 sim::calibrationSceneToml(planes[i], n));
  }
  if (request.json) {
    std::cout << json{{"out", out.string()},
                      {"board", profile.file.string()},
                      {"boards", boards.size()},
                      {"planes", planes.size()}}
                     .dump()
              << "\n";
  } else {
    std::cout << "simulate: " << boards.size() << " checkerboard and " << planes.size()
              << " plane targets for the head of " << profile.file.string() << " -> "
              << out.string() << "\n";
  }
}

}  // namespace cylscan::tools
