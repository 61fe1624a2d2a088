// SPDX-License-Identifier: Apache-2.0
#include "drivers/sim/calibration_targets.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <set>
#include <stdexcept>
#include <system_error>

namespace cylscan::sim {

namespace fs = std::filesystem;

Checkerboard BoardPose::board() const {
  Checkerboard b;
  b.center = center;
  b.rotation = rotationFromVectorDeg(rotation_deg);
  return b;
}

namespace {

// Whether the board faces the camera within `max_view_deg` (its normal to the
// direction of the camera's centre).
bool faces(const CameraModel& cam, const Checkerboard& b, double max_view_deg) {
  const Vec3 towards = (cam.centre() - b.center).normalized();
  return std::abs(towards.dot(b.rotation.col(2))) > std::cos(max_view_deg * kDeg);
}

// Whether every point's pixel centre lies more than `margin` pixels inside
// the image (from the outermost pixel centres).
bool centresInside(const CameraModel& cam, const std::vector<Vec3>& points, double margin) {
  for (const Vec3& p : points) {
    const auto px = cam.project(p);
    if (!px || px->x() <= margin || px->y() <= margin || px->x() >= cam.width() - 1 - margin ||
        px->y() >= cam.height() - 1 - margin) {
      return false;
    }
  }
  return true;
}

// Whether every point lies more than `fraction` of the width inside the
// image, measured from its edges: the same at any resolution of the same
// field of view (CameraModel::scaledTo), unlike a margin from the outermost
// pixel centres, which would shift by half a pixel.
bool inside(const CameraModel& cam, const std::vector<Vec3>& points, double fraction) {
  const double margin = fraction * cam.width();
  for (const Vec3& p : points) {
    const auto px = cam.project(p);
    if (!px) return false;
    const double x = px->x() + 0.5, y = px->y() + 0.5;  // from the image's corner
    if (x <= margin || y <= margin || x >= cam.width() - margin || y >= cam.height() - margin) {
      return false;
    }
  }
  return true;
}

// The spread poses that begin the sequence (board00 … board63 on board/sim).
std::vector<BoardPose> spreadBoardPoses(const CameraModel& main, const CameraModel& aux,
                                        int count) {
  std::vector<BoardPose> poses;
  const double margin = 0.04 * main.width();
  for (int i = 0; static_cast<int>(poses.size()) < count && i < 400; ++i) {
    BoardPose pose;
    const double z = 530 + 110 * std::fmod(i * 0.618034, 1.0);
    pose.center = Vec3(14 * std::sin(i * 1.7), 10 * std::cos(i * 2.3), z);
    pose.rotation_deg = {22 * std::sin(i * 2.1), 25 * std::sin(i * 1.3 + 0.7),
                         10 * std::sin(i * 0.9 + 0.3)};
    const Checkerboard b = pose.board();
    const auto corners = b.corners();
    if (faces(main, b, 50) && faces(aux, b, 50) && centresInside(main, corners, margin) &&
        centresInside(aux, corners, margin)) {
      poses.push_back(pose);
    }
  }
  return poses;
}

// The tilted poses that follow them, for the intrinsics of narrow lenses
// (~16° across). Seen nearly face-on, a board's image barely changes when the
// focal length and the distance change together; a view tilted by 30–60° to
// a camera shows the perspective that tells them apart, so these poses pin f
// down several times faster per view than the spread ones. (The principal
// point gains less: over so narrow a field it trades mostly against the
// tangential distortion p1, p2, which only more views average down.) Each
// board is tilted by 40–55° from the bisector of its directions to the two
// cameras, about an axis in its plane that turns by 135° (+ 11° every eight
// boards) from one board to the next, so the tilts take both signs about x
// and y and each camera sees some boards steeper than the other does. Depths
// run over 520–640 mm. Kept when the board faces both cameras within
// kTiltedMaxViewDeg and its whole checkered area (one square beyond the
// inner corners) lies more than 2 % of the width inside both images.
std::vector<BoardPose> tiltedBoardPoses(const CameraModel& main, const CameraModel& aux,
                                        int count) {
  std::vector<BoardPose> poses;
  for (int i = 0; static_cast<int>(poses.size()) < count && i < 400; ++i) {
    const double z = 520 + 120 * std::fmod(0.5 + i * 0.618034, 1.0);
    const Vec3 center(25 * std::sin(i * 1.3), 15 * std::sin(i * 2.9 + 1.0), z);
    // The untilted board faces along the bisector (its z axis away from the
    // cameras), its x axis horizontal.
    const Vec3 ahead =
        -((main.centre() - center).normalized() + (aux.centre() - center).normalized())
             .normalized();
    Mat3 facing;
    facing.col(0) = Vec3(0, 1, 0).cross(ahead).normalized();
    facing.col(1) = ahead.cross(facing.col(0));
    facing.col(2) = ahead;
    // Every eighth pose the azimuths step by 11° so that the 135° cycle does
    // not repeat the same eight directions.
    const int cycle = i / 8;
    const double azimuth = (135.0 * i + 11.0 * cycle) * kDeg;
    const double tilt = (40 + 15 * std::fmod(i * 0.381966, 1.0)) * kDeg;
    const Mat3 r =
        facing *
        Eigen::AngleAxisd(tilt, Vec3(std::cos(azimuth), std::sin(azimuth), 0)).toRotationMatrix();
    BoardPose pose;
    pose.center = center;
    pose.rotation_deg = rotationVectorDeg(r);
    Checkerboard area = pose.board();
    area.cols += 2;
    area.rows += 2;
    const auto outline = area.corners();
    const Checkerboard b = pose.board();
    if (faces(main, b, kTiltedMaxViewDeg) && faces(aux, b, kTiltedMaxViewDeg) &&
        inside(main, outline, 0.02) && inside(aux, outline, 0.02)) {
      poses.push_back(pose);
    }
  }
  return poses;
}

}  // namespace

std::vector<BoardPose> calibrationBoardPoses(const CameraModel& main, const CameraModel& aux,
                                             int count) {
  std::vector<BoardPose> poses = spreadBoardPoses(main, aux, std::min(count, kSpreadBoards));
  if (static_cast<int>(poses.size()) == std::min(count, kSpreadBoards) && count > kSpreadBoards) {
    const auto tilted = tiltedBoardPoses(main, aux, count - kSpreadBoards);
    poses.insert(poses.end(), tilted.begin(), tilted.end());
  }
  if (static_cast<int>(poses.size()) < count) {
    throw std::runtime_error("could not place " + std::to_string(count) +
                             " checkerboard poses in view of both cameras (" +
                             std::to_string(poses.size()) + " fit)");
  }
  return poses;
}

std::vector<PlanePose> calibrationPlanePoses(int count) {
  std::vector<PlanePose> poses;
  for (int i = 0; i < count; ++i) {
    const double z = count == 1 ? 580.0 : 540.0 + 80.0 * i / (count - 1);
    const double rx = 10 * std::sin(i * 2.4 + 0.5), ry = 12 * std::sin(i * 1.7 + 1.1);
    const Mat3 r = rotationFromVectorDeg({rx, 0, 0}) * rotationFromVectorDeg({0, ry, 0});
    poses.push_back({Vec3(0, 0, z), (r * Vec3(0, 0, -1)).normalized()});
  }
  return poses;
}

std::string calibrationSceneStem(std::string_view kind, int index) {
  if (index < 0 || index > 99) {
    throw std::invalid_argument("calibration target " + std::to_string(index) +
                                " is outside 0..99");
  }
  return std::string(kind) + (index < 10 ? "0" : "") + std::to_string(index);
}

fs::path calibrationScenesDir(const fs::path& board_dir) {
  return board_dir / "scenes" / "calibration";
}

Scene calibrationScene(const BoardPose& pose, int index) {
  Scene s;
  s.name = calibrationSceneStem("board", index);
  s.ambient = kBoardAmbient;
  s.objects.push_back({"board", pose.board()});  // the default albedo: the board has its own pair
  return s;
}

Scene calibrationScene(const PlanePose& pose, int index) {
  Scene s;
  s.name = calibrationSceneStem("plane", index);
  s.ambient = kPlaneAmbient;
  s.objects.push_back({"plane", Plane{pose.point, pose.normal, std::nullopt}, kPlaneAlbedo});
  return s;
}

namespace {

// The shortest decimal that reads back to the same double.
std::string shortest(double v) {
  if (!std::isfinite(v)) throw std::invalid_argument("calibration target: a number is not finite");
  char buf[64];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  if (ec != std::errc()) throw std::logic_error("calibration target: cannot format a number");
  return std::string(buf, end);
}

// The same as a TOML float (TOML reads "12" as an integer).
std::string tomlNumber(double v) {
  std::string s = shortest(v);
  if (s.find_first_of(".e") == std::string::npos) s += ".0";
  return s;
}

std::string tomlVec(const Vec3& v) {
  return "[" + tomlNumber(v.x()) + ", " + tomlNumber(v.y()) + ", " + tomlNumber(v.z()) + "]";
}

}  // namespace

std::string calibrationSceneToml(const BoardPose& pose, int index) {
  const std::string stem = calibrationSceneStem("board", index), nn = stem.substr(5);
  const Checkerboard b = pose.board();
  std::string t;
  t += "# Calibration target of the virtual head: checkerboard pose " + nn + ", " +
       std::to_string(b.cols) + " × " + std::to_string(b.rows) + " inner\n";
  t += "# corners of " + shortest(b.square_mm) + " mm, lit by ambient light only. " +
       "`cylscan simulate` renders it\n";
  t += "# as checkerboard pair " + nn + " of its dataset, cylscand's calibration session\n";
  t += "# with {\"scene\": \"calibration/" + stem + ".toml\"}. Written by `cylscan simulate\n";
  t += "# --write-calibration-scenes` (docs/formats.md, \"Calibration targets\").\n";
  t += "# Main camera frame, mm; rotation_deg is a rotation vector in degrees.\n";
  t += "name = \"" + stem + "\"\n";
  t += "ambient = " + tomlNumber(kBoardAmbient) + "\n\n";
  t += "[[object]]\ntype = \"checkerboard\"\nname = \"board\"\n";
  t += "cols = " + std::to_string(b.cols) + "\n";
  t += "rows = " + std::to_string(b.rows) + "\n";
  t += "square_mm = " + tomlNumber(b.square_mm) + "\n";
  t += "center = " + tomlVec(pose.center) + "\n";
  t += "rotation_deg = " + tomlVec(toVec(pose.rotation_deg)) + "\n";
  return t;
}

std::string calibrationSceneToml(const PlanePose& pose, int index) {
  const std::string stem = calibrationSceneStem("plane", index), nn = stem.substr(5);
  std::string t;
  t += "# Calibration target of the virtual head: plane pose " + nn + ", an unbounded white\n";
  t += "# plane facing the cameras, scanned with the projector. `cylscan simulate`\n";
  t += "# renders it as calibration bundle pose" + nn + " of its dataset, cylscand's\n";
  t += "# calibration session with {\"scene\": \"calibration/" + stem + ".toml\"}. Written by\n";
  t += "# `cylscan simulate --write-calibration-scenes` (docs/formats.md,\n";
  t += "# \"Calibration targets\"). Main camera frame, mm.\n";
  t += "name = \"" + stem + "\"\n";
  t += "ambient = " + tomlNumber(kPlaneAmbient) + "\n\n";
  t += "[[object]]\ntype = \"plane\"\nname = \"plane\"\n";
  t += "point = " + tomlVec(pose.point) + "\n";
  t += "normal = " + tomlVec(pose.normal) + "\n";
  t += "albedo = " + tomlNumber(kPlaneAlbedo) + "\n";
  return t;
}

std::vector<Scene> loadCalibrationScenes(const fs::path& dir, std::string_view kind) {
  std::set<int> numbers;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const std::size_t k = kind.size();
    if (name.size() == k + 7 && name.compare(0, k, kind) == 0 &&
        name.compare(k + 2, 5, ".toml") == 0 && std::isdigit(static_cast<unsigned char>(name[k])) &&
        std::isdigit(static_cast<unsigned char>(name[k + 1]))) {
      numbers.insert(std::stoi(name.substr(k, 2)));
    }
  }
  std::vector<Scene> scenes;
  for (int i = 0; i < static_cast<int>(numbers.size()); ++i) {
    const std::string stem = calibrationSceneStem(kind, i);
    if (!numbers.contains(i)) {
      throw std::invalid_argument(dir.string() + ": " + stem +
                                  ".toml is missing (the targets are numbered from 00 on, "
                                  "without gaps)");
    }
    scenes.push_back(loadScene(dir / (stem + ".toml")));
  }
  return scenes;
}

}  // namespace cylscan::sim
