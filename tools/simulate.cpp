// cylscan simulate: renders the dataset of spec §6 on the virtual head,
// driving it through its GPIO lines, clock and cameras as firmware would.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "drivers/board_profile.hpp"
#include "drivers/sim/head_config.hpp"
#include "drivers/sim/ring_head.hpp"
#include "drivers/sim/scene.hpp"
#include "drivers/sim/virtual_head.hpp"
#include "firmware/scan_plan.hpp"
#include "formats/atomic_file.hpp"
#include "formats/capture_bundle.hpp"
#include "formats/checkerboard_set.hpp"
#include "formats/images.hpp"
#include "formats/stereo_calibration.hpp"
#include "tools/commands.hpp"

namespace cylscan::tools {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using sim::Vec3;
using std::chrono::nanoseconds;
using WallClock = std::chrono::steady_clock;

struct SimulateRequest {
  std::string out;
  std::string head;
  int width = 0;
  int height = 0;
  int frames = 25;
  double noise = 1.0;
  std::uint64_t seed = 1;
  std::vector<std::string> scenes;
  int poses = 14;
  int boards = 14;
  int bit_depth = 0;
  // Scenes of `cylscan study` (rendered with main and aux; none by default).
  int sphere_poses = 0;
  int plane_poses = 0;
  int repeats = 0;
  bool quick = false;
  bool json = false;
  // The 360° head (board/sim360): --board DIR with --camera NAME (the
  // calibration dataset of direction NAME), --turntable (the extrinsics
  // dataset), or neither (a ring scan of the board's default scene).
  std::string board;
  std::string camera;
  bool turntable = false;
  bool frames_given = false;  // --frames overrides the profile's frames_high
};

json vec(const Vec3& v) {
  return json::array({v.x(), v.y(), v.z()});
}

json matrix(const sim::Mat3& m) {
  json rows = json::array();
  for (int r = 0; r < 3; ++r)
    rows.push_back({m(r, 0), m(r, 1), m(r, 2)});
  return rows;
}

json truthOf(const sim::SceneObject& o) {
  json t;
  if (const auto* s = std::get_if<sim::Sphere>(&o.shape)) {
    t = {{"type", "sphere"}, {"center", vec(s->center)}, {"radius", s->radius}};
  } else if (const auto* p = std::get_if<sim::Plane>(&o.shape)) {
    t = {{"type", "plane"}, {"point", vec(p->point)}, {"normal", vec(p->normal.normalized())}};
    if (p->extent) {
      t["extent"] = {(*p->extent)[0], (*p->extent)[1]};
      t["axis_u"] = vec(p->axisU());
    }
  } else if (const auto* b = std::get_if<sim::Box>(&o.shape)) {
    t = {{"type", "box"},
         {"center", vec(b->center)},
         {"size", vec(b->size)},
         {"rotation", matrix(b->rotation)}};
  } else if (const auto* c = std::get_if<sim::Checkerboard>(&o.shape)) {
    t = {{"type", "checkerboard"}, {"center", vec(c->center)}, {"rotation", matrix(c->rotation)},
         {"cols", c->cols},        {"rows", c->rows},          {"square_mm", c->square_mm}};
  } else if (const auto* m = std::get_if<sim::Mesh>(&o.shape)) {
    t = {{"type", "mesh"}, {"file", m->file}, {"triangles", m->mesh->triangles().size()}};
  }
  t["name"] = o.name;
  t["albedo"] = o.albedo;
  return t;
}

json truthOf(const sim::Scene& scene) {
  if (scene.objects.size() == 1) return truthOf(scene.objects.front());
  json objects = json::array();
  for (const auto& o : scene.objects)
    objects.push_back(truthOf(o));
  return {{"type", "composite"}, {"objects", objects}};
}

sim::SceneObject sphere(const std::string& name, const Vec3& c, double r) {
  return {name, sim::Sphere{c, r}, 0.8};
}

sim::SceneObject plane(const std::string& name, const Vec3& point, double rx_deg, double ry_deg) {
  const sim::Mat3 r =
      sim::rotationFromVectorDeg({rx_deg, 0, 0}) * sim::rotationFromVectorDeg({0, ry_deg, 0});
  return {name, sim::Plane{point, r * Vec3(0, 0, -1), std::nullopt}, 0.8};
}

sim::Scene scene(const std::string& name, std::vector<sim::SceneObject> objects,
                 double ambient = 0.03) {
  sim::Scene s;
  s.name = name;
  s.ambient = ambient;
  s.objects = std::move(objects);
  return s;
}

// The built-in test scenes: spheres of the paper's 50 mm radius, a plane and
// isolated objects with depth steps.
std::vector<sim::Scene> testScenes() {
  std::vector<sim::Scene> scenes;
  scenes.push_back(scene("sphere_1", {sphere("sphere", {0, 0, 580}, 50)}));
  scenes.push_back(scene("sphere_2", {sphere("sphere", {-25, 12, 555}, 50)}));
  scenes.push_back(scene("sphere_3", {sphere("sphere", {30, -15, 605}, 50)}));
  scenes.push_back(scene("plane", {plane("plane", {0, 0, 585}, -5, 8)}));
  sim::Box box{{35, -35, 575}, {40, 40, 40}, sim::rotationFromVectorDeg({0, 35, 0})};
  scenes.push_back(scene("objects", {sphere("sphere_a", {-45, -15, 550}, 30),
                                     sphere("sphere_b", {40, 25, 612}, 25),
                                     {"box", box, 0.75}}));
  return scenes;
}

// The scenes of the paper's experiments for `cylscan study`, with main and
// aux (so the SV method can be compared on the same frames), listed in
// truth.json under "study".
struct StudyScenes {
  std::vector<sim::Scene> scenes;
  json index = json::object();
};

std::string studyName(const std::string& prefix, int i, int n) {
  return prefix + formats::frameFileName(i, n);
}

// Sphere poses: the 50 mm sphere with its visible cap inside the working
// volume (front 540–570 mm, limb at the centre depth 590–620 mm), offsets
// spread over the field of view. Plane poses: depths 545–615 mm, tilts up to
// ±8° (x) and ±10° (y), other angles than the calibration poses. Repeats: two
// fixed poses of each, rendered R times (each scan has its own frame numbers,
// hence its own noise).
StudyScenes studyScenes(const SimulateRequest& request) {
  StudyScenes out;
  auto spread = [](int i, int n) { return n == 1 ? 0.5 : static_cast<double>(i) / (n - 1); };
  json spheres = json::array(), planes = json::array();
  for (int i = 0; i < request.sphere_poses; ++i) {
    const double t = spread(i, request.sphere_poses);
    const Vec3 c(22 * std::sin(i * 2.3 + 0.4), 12 * std::cos(i * 1.9 + 0.2), 590 + 30 * t);
    out.scenes.push_back(
        scene(studyName("sphere_pose", i, request.sphere_poses), {sphere("sphere", c, 50)}));
    spheres.push_back(out.scenes.back().name);
  }
  for (int i = 0; i < request.plane_poses; ++i) {
    const double z = 545 + 70 * spread(i, request.plane_poses);
    out.scenes.push_back(
        scene(studyName("plane_pose", i, request.plane_poses),
              {plane("plane", {0, 0, z}, 8 * std::sin(i * 1.3 + 0.9), 10 * std::sin(i * 2.9))}));
    planes.push_back(out.scenes.back().name);
  }
  json sphere_repeats = json::array(), plane_repeats = json::array();
  if (request.repeats > 0) {
    const Vec3 sphere_at[] = {{0, 0, 600}, {-18, 10, 612}};
    struct PlaneAt {
      double z, rx_deg, ry_deg;
    };
    const PlaneAt plane_at[] = {{580, 3, -4}, {605, -1, 2}};
    for (int pose = 0; pose < 2; ++pose) {
      json s = json::array(), p = json::array();
      const std::string tag = std::to_string(pose + 1) + "_r";
      for (int r = 0; r < request.repeats; ++r) {
        out.scenes.push_back(scene(studyName("sphere_repeat" + tag, r, request.repeats),
                                   {sphere("sphere", sphere_at[pose], 50)}));
        s.push_back(out.scenes.back().name);
      }
      const PlaneAt& at = plane_at[pose];
      for (int r = 0; r < request.repeats; ++r) {
        out.scenes.push_back(scene(studyName("plane_repeat" + tag, r, request.repeats),
                                   {plane("plane", {0, 0, at.z}, at.rx_deg, at.ry_deg)}));
        p.push_back(out.scenes.back().name);
      }
      sphere_repeats.push_back(s);
      plane_repeats.push_back(p);
    }
  }
  out.index = {{"sphere_poses", spheres},
               {"plane_poses", planes},
               {"sphere_repeats", sphere_repeats},
               {"plane_repeats", plane_repeats},
               {"cameras", {"main", "aux"}}};
  return out;
}

// Drives the virtual head as the firmware drives the hardware: step pulses
// with a trapezoidal speed profile, a trigger pulse per frame, frames from the
// cameras' driver interface.
class Rig {
 public:
  explicit Rig(sim::VirtualHead& head) : head_(head), clock_(head.clock()) {
    const sim::LinesConfig& l = head.config().lines;
    auto spec = [](const sim::LineConfig& c, const char* role) {
      drivers::LineSpec s;
      s.name = c.name;
      s.active_low = c.active_low;
      s.role = role;
      return s;
    };
    step_ = head.gpio().requestOutput(spec(l.step, "step"), false);
    dir_ = head.gpio().requestOutput(spec(l.dir, "dir"), true);
    enable_ = head.gpio().requestOutput(spec(l.enable, "enable"), true);
    trigger_ = head.gpio().requestOutput(spec(l.trigger, "trigger"), false);
    light_ = head.gpio().requestOutput(spec(l.light, "light"), false);
    fault_ = head.gpio().requestInput(spec(l.fault, "fault"));
    const sim::StageParams& s = head.config().stage;
    steps_per_deg_ = s.stepsPerDeg();
    position_ = head.stage().position();
    start_rate_ = 0.6 * s.start_speed_deg_s * steps_per_deg_;
    max_rate_ = 0.8 * s.max_speed_deg_s * steps_per_deg_;
    accel_ = 0.7 * s.max_accel_deg_s2 * steps_per_deg_;
  }

  double stepsPerDeg() const { return steps_per_deg_; }
  std::int64_t position() const { return position_; }
  void light(bool on) { light_->set(on); }

  void moveTo(std::int64_t target) {
    const std::int64_t delta = target - position_;
    if (delta == 0) return;
    dir_->set(delta > 0);
    nanoseconds t = clock_.now() + std::chrono::microseconds(5);  // direction setup time
    const std::int64_t n = std::abs(delta);
    for (std::int64_t i = 0; i < n; ++i) {
      const double up = std::sqrt(start_rate_ * start_rate_ + 2 * accel_ * static_cast<double>(i));
      const double down =
          std::sqrt(start_rate_ * start_rate_ + 2 * accel_ * static_cast<double>(n - 1 - i));
      const double rate = std::min({up, down, max_rate_});
      t += nanoseconds{std::llround(1e9 / rate)};
      clock_.sleepUntil(t);
      step_->set(true);
      clock_.sleepUntil(t + std::chrono::microseconds(2));
      step_->set(false);
    }
    position_ = target;
    clock_.sleepUntil(clock_.now() + std::chrono::milliseconds(150));  // settling
    if (fault_->get() || head_.stage().position() != position_) {
      throw std::runtime_error("simulate: the virtual stage lost steps (at " +
                               std::to_string(head_.stage().position()) + ", expected " +
                               std::to_string(position_) + ")");
    }
  }

  // One trigger pulse; the frames of `cameras`, in that order.
  std::vector<drivers::Frame> capture(const std::vector<std::string>& cameras) {
    trigger_->set(true);
    clock_.sleepUntil(clock_.now() + std::chrono::microseconds(10));
    trigger_->set(false);
    std::vector<drivers::Frame> frames;
    for (const std::string& name : cameras) {
      std::optional<drivers::Frame> f = head_.camera(name).waitFrame(std::chrono::seconds(1));
      if (!f) throw std::runtime_error("simulate: camera '" + name + "' timed out");
      auto& expected = sequence_[name];
      if (f->sequence != expected) {
        throw std::runtime_error("simulate: camera '" + name + "' lost a frame");
      }
      ++expected;
      frames.push_back(std::move(*f));
    }
    return frames;
  }

  void startCameras(const std::vector<std::string>& active, int bit_depth) {
    for (const std::string& name : head_.cameraNames()) {
      drivers::Camera& cam = head_.camera(name);
      cam.stop();
      if (std::find(active.begin(), active.end(), name) == active.end()) continue;
      drivers::CameraConfig config;
      config.bit_depth = bit_depth;
      config.trigger = drivers::TriggerMode::GpioPulse;
      cam.configure(config);
      cam.start();
    }
  }

 private:
  sim::VirtualHead& head_;
  drivers::Clock& clock_;
  std::unique_ptr<drivers::OutputLine> step_, dir_, enable_, trigger_, light_;
  std::unique_ptr<drivers::InputLine> fault_;
  double steps_per_deg_ = 0;
  double start_rate_ = 0, max_rate_ = 0, accel_ = 0;
  std::int64_t position_ = 0;
  std::map<std::string, std::uint64_t> sequence_;
};

// The fringe acquisition plan: executed step positions of every frame.
struct FringePlan {
  std::int64_t high_start = 0;  // steps
  std::int64_t low_start = 0;
  int frames = 25;
  std::vector<std::int64_t> high, low;
  double high_start_deg = 0, low_start_deg = 0;
  double azimuth_min = 0, azimuth_max = 0;
};

// Azimuth range (about the projector axis) of the main camera's field of view
// over the working depths 540–620 mm.
std::pair<double, double> azimuthRange(const sim::VirtualHead& head) {
  const sim::CameraModel& cam = head.cameraModel("main");
  double lo = 1e9, hi = -1e9;
  for (double z : {540.0, 620.0}) {
    for (int i = 0; i <= 20; ++i) {
      const double f = i / 20.0;
      const std::pair<double, double> border[] = {{f * (cam.width() - 1), 0},
                                                  {f * (cam.width() - 1), cam.height() - 1.0},
                                                  {0, f * (cam.height() - 1)},
                                                  {cam.width() - 1.0, f * (cam.height() - 1)}};
      for (const auto& [u, v] : border) {
        const Vec3 d = cam.rayDirection(u, v);
        const Vec3 p = cam.centre() + d * ((z - cam.centre().z()) / d.z());
        const double a = head.projector().azimuthDeg(p);
        lo = std::min(lo, a);
        hi = std::max(hi, a);
      }
    }
  }
  return {lo, hi};
}

FringePlan planFringes(const sim::VirtualHead& head, double steps_per_deg, int frames) {
  const sim::ProjectorParams& p = head.projector().params();
  const double eq =
      p.theta_high_deg * p.theta_low_deg / std::abs(p.theta_low_deg - p.theta_high_deg);
  FringePlan plan;
  plan.frames = frames;
  std::tie(plan.azimuth_min, plan.azimuth_max) = azimuthRange(head);
  if (plan.azimuth_max - plan.azimuth_min > eq - 2 * p.theta_low_deg) {
    throw std::invalid_argument("simulate: the field of view spans " +
                                std::to_string(plan.azimuth_max - plan.azimuth_min) +
                                " deg of azimuth, more than one equivalent period allows");
  }
  // Centre the field of view in the middle of the high half (β ≈ 90° + eq/2)
  // and of one equivalent period; the low set starts 180° earlier so both
  // phases are zero at the same azimuth.
  const double centre = (plan.azimuth_min + plan.azimuth_max) / 2;
  const double k = std::floor(90.0 / eq);
  const double start = sim::wrapDeg360(centre - (k * eq + eq / 2));
  plan.high_start = std::llround(start * steps_per_deg);
  plan.low_start = plan.high_start - std::llround(180.0 * steps_per_deg);
  if (plan.low_start < 0) plan.low_start += std::llround(360.0 * steps_per_deg);
  plan.high_start_deg = static_cast<double>(plan.high_start) / steps_per_deg;
  plan.low_start_deg = static_cast<double>(plan.low_start) / steps_per_deg;
  for (int i = 0; i < frames; ++i) {
    plan.high.push_back(plan.high_start +
                        std::llround(i * p.theta_high_deg / frames * steps_per_deg));
    plan.low.push_back(plan.low_start + std::llround(i * p.theta_low_deg / frames * steps_per_deg));
  }
  return plan;
}

class DatasetWriter {
 public:
  // `plan`: the fringe angles to use instead of the one-direction plan
  // (planFringes); `bundle_extra`: extension fields of every capture.json.
  DatasetWriter(const SimulateRequest& request, sim::VirtualHead& head,
                std::optional<FringePlan> plan = std::nullopt, json bundle_extra = json::object())
      : request_(request), head_(head), rig_(head), bundle_extra_(std::move(bundle_extra)) {
    const sim::CameraParams& main = head.config().cameras.front();
    bit_depth_ = main.bit_depth;
    plan_ = plan ? *plan : planFringes(head, rig_.stepsPerDeg(), request.frames);
  }

  void writeBoard(const fs::path& dir, nlohmann::json& truth) {
    const sim::Checkerboard proto;
    fs::create_directories(dir / "main");
    fs::create_directories(dir / "aux");
    formats::writeCheckerboardInfo(dir, {proto.cols, proto.rows, proto.square_mm});
    rig_.light(false);
    rig_.startCameras({"main", "aux"}, bit_depth_);
    const auto poses = boardPoses(request_.boards);
    for (std::size_t i = 0; i < poses.size(); ++i) {
      head_.setScene(scene("board", {{"board", poses[i], 0.8}}, 0.7));
      const auto frames = rig_.capture({"main", "aux"});
      checkCorners(frames[0].image, poses[i], "main", i);
      checkCorners(frames[1].image, poses[i], "aux", i);
      const std::string id =
          formats::frameFileName(static_cast<int>(i), static_cast<int>(poses.size()));
      formats::writePng(dir / "main" / (id + ".png"), frames[0].image);
      formats::writePng(dir / "aux" / (id + ".png"), frames[1].image);
      truth[id] = {{"center", vec(poses[i].center)}, {"rotation", matrix(poses[i].rotation)}};
    }
    boards_ = static_cast<int>(poses.size());
  }

  void writeBundle(const fs::path& dir, const sim::Scene& s, const std::vector<std::string>& cams) {
    head_.setScene(s);
    rig_.startCameras(cams, bit_depth_);
    rig_.light(true);
    formats::CaptureInfo info;
    info.cameras = cams;
    const sim::ProjectorParams& p = head_.projector().params();
    info.high.period_deg = p.theta_high_deg;
    info.low.period_deg = p.theta_low_deg;
    for (auto st : plan_.high)
      info.high.stage_deg.push_back(angle(st));
    for (auto st : plan_.low)
      info.low.stage_deg.push_back(angle(st));
    info.extra = {{"device", "cylscan virtual head"},
                  {"scene", s.name},
                  {"seed", request_.seed},
                  {"steps_per_deg", rig_.stepsPerDeg()},
                  {"stage_steps", {{"high", plan_.high}, {"low", plan_.low}}},
                  {"exposure_us", head_.config().cameras.front().exposure_us}};
    if (bit_depth_ > 8) info.extra["bit_depth"] = bit_depth_;
    info.extra.update(bundle_extra_);
    formats::CaptureBundleWriter writer(dir, info);
    for (const auto set : formats::kFringeSets) {
      const auto& steps = set == formats::FringeSetId::High ? plan_.high : plan_.low;
      for (std::size_t k = 0; k < steps.size(); ++k) {
        rig_.moveTo(steps[k]);
        const auto frames = rig_.capture(cams);
        for (std::size_t c = 0; c < cams.size(); ++c) {
          writer.writeFrame(cams[c], set, static_cast<int>(k), frames[c].image);
        }
        ++frames_;
      }
    }
    writer.commit();
  }

  const FringePlan& plan() const { return plan_; }
  int boards() const { return boards_; }
  double cornerError() const { return corner_error_; }
  int frames() const { return frames_; }

 private:
  double angle(std::int64_t steps) const { return static_cast<double>(steps) / rig_.stepsPerDeg(); }

  // Every board image must be usable: OpenCV finds the corners, at the truth.
  void checkCorners(const cv::Mat& image, const sim::Checkerboard& board, const char* camera,
                    std::size_t pose) {
    cv::Mat eight = image;
    if (image.depth() != CV_8U) image.convertTo(eight, CV_8U, 255.0 / ((1 << bit_depth_) - 1));
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

  // Board poses (deterministic), kept when every corner is well inside both images.
  std::vector<sim::Checkerboard> boardPoses(int count) const {
    std::vector<sim::Checkerboard> poses;
    const double margin = 0.04 * head_.cameraModel("main").width();
    for (int i = 0; static_cast<int>(poses.size()) < count && i < 400; ++i) {
      sim::Checkerboard b;
      const double z = 530 + 110 * std::fmod(i * 0.618034, 1.0);
      const double rx = 22 * std::sin(i * 2.1), ry = 25 * std::sin(i * 1.3 + 0.7);
      const double rz = 10 * std::sin(i * 0.9 + 0.3);
      b.center = Vec3(14 * std::sin(i * 1.7), 10 * std::cos(i * 2.3), z);
      b.rotation = sim::rotationFromVectorDeg({rx, ry, rz});
      bool inside = true;
      for (const char* name : {"main", "aux"}) {
        const sim::CameraModel& cam = head_.cameraModel(name);
        const Vec3 towards = (cam.centre() - b.center).normalized();
        inside = inside && std::abs(towards.dot(b.rotation.col(2))) > std::cos(50 * sim::kDeg);
        for (const Vec3& c : b.corners()) {
          const auto px = cam.project(c);
          inside = inside && px && px->x() > margin && px->y() > margin &&
                   px->x() < cam.width() - 1 - margin && px->y() < cam.height() - 1 - margin;
        }
      }
      if (inside) poses.push_back(b);
    }
    if (static_cast<int>(poses.size()) < count) {
      throw std::runtime_error("simulate: could not place " + std::to_string(count) +
                               " checkerboard poses in view");
    }
    return poses;
  }

  const SimulateRequest& request_;
  sim::VirtualHead& head_;
  Rig rig_;
  json bundle_extra_;
  FringePlan plan_;
  int bit_depth_ = 8;
  int boards_ = 0;
  int frames_ = 0;
  double corner_error_ = 0;
};

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

// --width/--height, --noise and --bit-depth applied to a head.
sim::HeadConfig applyRequest(sim::HeadConfig config, const SimulateRequest& request) {
  if (request.width > 0) config = sim::withResolution(config, request.width, request.height);
  config.noise.scale *= request.noise;
  if (request.bit_depth > 0) {
    for (auto& cam : config.cameras)
      cam.bit_depth = request.bit_depth;
  }
  return config;
}

// The spec §6 dataset on a head with the cameras main and aux. `fringe_plan`:
// the fringe angles when not the one-direction plan; `extra`: extension fields
// of every capture.json, also recorded in truth.json's "acquisition" with
// `truth_extra`.
void runDataset(const SimulateRequest& request, const sim::HeadConfig& config,
                std::optional<FringePlan> fringe_plan, const json& extra, const json& truth_extra,
                WallClock::time_point started) {
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

  sim::VirtualHead head(config, sim::Scene{}, request.seed);
  const fs::path out(request.out);
  fs::create_directories(out);
  DatasetWriter writer(request, head, std::move(fringe_plan), extra);
  json truth = {{"scenes", json::object()}, {"calib", json::object()}, {"board", json::object()}};

  writer.writeBoard(out / "board", truth["board"]);

  const int poses = request.poses;
  for (int i = 0; i < poses; ++i) {
    const double z = poses == 1 ? 580.0 : 540.0 + 80.0 * i / (poses - 1);
    const double rx = 10 * std::sin(i * 2.4 + 0.5), ry = 12 * std::sin(i * 1.7 + 1.1);
    const sim::SceneObject p = plane("plane", {0, 0, z}, rx, ry);
    const std::string id = "pose" + formats::frameFileName(i, poses);
    writer.writeBundle(out / "calib" / id, scene(id, {p}), {"main", "aux"});
    truth["calib"][id] = truthOf(p);
  }
  for (const sim::Scene& s : tests) {
    writer.writeBundle(out / "test" / s.name, s, {"main"});
    truth["scenes"][s.name] = truthOf(s);
  }
  // After every default scene, so a dataset without study scenes is unchanged.
  for (const sim::Scene& s : study.scenes) {
    writer.writeBundle(out / "test" / s.name, s, {"main", "aux"});
    truth["scenes"][s.name] = truthOf(s);
  }
  if (!study.scenes.empty()) truth["study"] = study.index;

  const FringePlan& plan = writer.plan();
  const auto& proj = head.projector().params();
  truth["acquisition"] = {{"frames", plan.frames},
                          {"high_start_deg", plan.high_start_deg},
                          {"low_start_deg", plan.low_start_deg},
                          {"steps_per_deg", head.config().stage.stepsPerDeg()},
                          {"azimuth_range_deg", {plan.azimuth_min, plan.azimuth_max}},
                          {"projector_axis_origin_mm", proj.axis_origin_mm},
                          {"seed", request.seed},
                          {"noise_scale", config.noise.scale}};
  truth["acquisition"].update(extra);
  truth["acquisition"].update(truth_extra);
  formats::writeStereoCalibration(out / "stereo_truth.yaml", stereoTruth(head));
  formats::writeFileAtomically(out / "truth.json", truth.dump(2) + "\n");

  const double seconds = std::chrono::duration<double>(WallClock::now() - started).count();
  const sim::CameraModel& main = head.cameraModel("main");
  if (request.json) {
    json names_json = json::array();
    for (const auto& s : tests)
      names_json.push_back(s.name);
    std::cout << json{{"out", out.string()},
                      {"width", main.width()},
                      {"height", main.height()},
                      {"frames", plan.frames},
                      {"seed", request.seed},
                      {"noise", request.noise},
                      {"board_pairs", writer.boards()},
                      {"board_corner_error_px", writer.cornerError()},
                      {"calib_poses", poses},
                      {"test_scenes", names_json},
                      {"study_scenes", study.scenes.size()},
                      {"fringe_frames_rendered", writer.frames()},
                      {"high_start_deg", plan.high_start_deg},
                      {"low_start_deg", plan.low_start_deg},
                      {"azimuth_range_deg", {plan.azimuth_min, plan.azimuth_max}},
                      {"seconds", seconds}}
                     .dump()
              << "\n";
  } else {
    std::cout << "simulate: " << writer.boards() << " board pairs (corners within "
              << writer.cornerError() << " px), " << poses << " calibration bundles, "
              << tests.size() << " test scenes, " << study.scenes.size() << " study scenes ("
              << main.width() << "x" << main.height() << ", N=" << plan.frames << ", noise "
              << request.noise << ", seed " << request.seed << ") in " << seconds << " s -> "
              << out.string() << "\n";
  }
}

// ---- The 360° head (--board, e.g. board/sim360) ------------------------------

// The extra turns of the extrinsics dataset with the target in front of main
// (they fix the turntable axis): as large as keeps all four 25 mm spheres of
// the target wholly in main's view (its 2 × 2 layout leaves ≈ 2.8° of room
// at either side; tests/sim/ring_head_test.cpp checks 5 px of margin).
constexpr double kExtraTurnDeg = 2.5;

struct RingSetup {
  drivers::BoardProfile profile;
  sim::HeadConfig head;  // the whole head, --width/--height/--noise/--bit-depth applied
  firmware::ScanPlan plan;
  std::vector<std::string> cameras;  // the profile's cameras (the head's names), main first
};

RingSetup ringSetup(const SimulateRequest& request) {
  RingSetup r;
  r.profile = drivers::loadBoardProfile(request.board);
  const std::string where = r.profile.file.string();
  if (!r.profile.sim)
    throw std::invalid_argument(where + ": the board has no virtual head ([sim])");
  if (r.profile.scan.plan != drivers::PlanKind::Ring) {
    throw std::invalid_argument(where + ": simulate --board needs [scan] plan = \"ring\"");
  }
  r.head = applyRequest(r.profile.sim->head, request);
  firmware::ScanOptions options = firmware::scanOptionsFrom(r.profile);
  if (request.frames_given) options.frames_high = options.frames_low = request.frames;
  r.plan = firmware::planScan(options, r.profile.stage);
  if (std::abs(r.plan.steps_per_deg - r.head.stage.stepsPerDeg()) > 1e-9) {
    throw std::invalid_argument(where + ": [stage] has " + std::to_string(r.plan.steps_per_deg) +
                                " steps/deg, the virtual head " +
                                std::to_string(r.head.stage.stepsPerDeg()));
  }
  if (r.plan.periodDeg(formats::FringeSetId::High) != r.head.projector.theta_high_deg ||
      r.plan.periodDeg(formats::FringeSetId::Low) != r.head.projector.theta_low_deg) {
    throw std::invalid_argument(where +
                                ": [scan] period_high_deg/period_low_deg differ from "
                                "the virtual head's slot periods");
  }
  for (const auto& cam : r.profile.cameras) {
    if (!cam.device.empty() && cam.device != cam.name) {
      throw std::invalid_argument(where + ": camera '" + cam.name +
                                  "': simulate --board needs device = its name");
    }
    r.cameras.push_back(cam.name);
  }
  return r;
}

// The ring layout as the firmware's bundles record it ("ring" in capture.json).
json ringJson(const firmware::ScanPlan& plan) {
  const firmware::RingLayout& r = *plan.ring;
  json cameras = json::object(), margins = json::object();
  for (const auto& c : r.cameras) {
    cameras[c.camera] = formats::toString(c.first_sweep_set);
    margins[c.camera] = {{"half", c.half_margin_deg}, {"window", c.window_margin_deg}};
  }
  return {{"start_deg", r.start_deg},
          {"sweep2_start_deg", r.sweep2_start_deg},
          {"step_deg", r.step_deg},
          {"step_steps", r.step_steps},
          {"frames", r.frames},
          {"cameras", cameras},
          {"margins_deg", margins},
          {"noise_gain", {{"high", r.noise_gain_high}, {"low", r.noise_gain_low}}}};
}

json poseJson(const sim::RigidMotion& m) {
  return {{"R", matrix(m.r)}, {"T", vec(m.t)}};
}

// --camera NAME: board/sim's dataset for the direction NAME, on the head
// re-expressed in NAME's frame, at the ring plan's angles of NAME's sets.
void runCameraDataset(const SimulateRequest& request, const RingSetup& setup,
                      WallClock::time_point started) {
  const std::string& name = request.camera;
  const auto it = std::find(setup.cameras.begin(), setup.cameras.end(), name);
  if (it == setup.cameras.end()) {
    throw std::invalid_argument("simulate: --camera '" + name + "' is not a camera of " +
                                setup.profile.file.string());
  }
  // Each direction its own noise (main's dataset keeps --seed): the cameras
  // share their intrinsics and aux's relative pose, so with one seed their
  // checkerboard images, hence their calibration errors, would be identical.
  SimulateRequest direction = request;
  direction.seed = request.seed + static_cast<std::uint64_t>(it - setup.cameras.begin());
  const sim::HeadConfig view = sim::headForCamera(setup.head, name);
  FringePlan f;
  f.frames = setup.plan.ring->frames;
  f.high = setup.plan.motionSetOf(name, formats::FringeSetId::High).positions;
  f.low = setup.plan.motionSetOf(name, formats::FringeSetId::Low).positions;
  f.high_start = f.high.front();
  f.low_start = f.low.front();
  f.high_start_deg = static_cast<double>(f.high_start) / setup.plan.steps_per_deg;
  f.low_start_deg = static_cast<double>(f.low_start) / setup.plan.steps_per_deg;
  const auto range = sim::workingVolumeAzimuthDeg(sim::CameraModel(view.cameras.front()),
                                                  sim::CylindricalProjector(view.projector));
  f.azimuth_min = range[0];
  f.azimuth_max = range[1];
  runDataset(direction, view, f, {{"head_camera", name}},
             {{"plan", "ring"},
              {"ring", ringJson(setup.plan)},
              {"board", setup.profile.file.string()},
              {"head_pose", poseJson(sim::cameraPose([&]() -> const sim::CameraParams& {
                 for (const auto& c : setup.head.cameras)
                   if (c.name == name) return c;
                 throw std::logic_error("no camera");
               }()))}},
             started);
}

// Ring scans of the whole head: both sweeps of the ring plan, every camera per
// trigger, each frame filed under the camera's own set (plan.setOf).
class RingScanner {
 public:
  RingScanner(const SimulateRequest& request, const RingSetup& setup, sim::VirtualHead& head)
      : request_(request), setup_(setup), head_(head), rig_(head) {
    bit_depth_ = head.config().cameras.front().bit_depth;
  }

  void writeBundle(const fs::path& dir, const sim::Scene& s, const json& extra) {
    using formats::FringeSetId;
    const firmware::ScanPlan& plan = setup_.plan;
    const std::vector<std::string>& cams = setup_.cameras;
    head_.setScene(s);
    rig_.startCameras(cams, bit_depth_);
    rig_.light(true);
    formats::CaptureInfo info;
    info.cameras = cams;
    const auto setInfo = [&](const std::string& camera, FringeSetId id) {
      return formats::FringeSetInfo{plan.periodDeg(id), plan.anglesDeg(camera, id)};
    };
    info.high = setInfo(cams.front(), FringeSetId::High);
    info.low = setInfo(cams.front(), FringeSetId::Low);
    for (const std::string& c : cams) {
      if (c == cams.front() ||
          plan.setOf(c, FringeSetId::High) == plan.setOf(cams.front(), FringeSetId::High)) {
        continue;
      }
      info.camera_sets[c] = {setInfo(c, FringeSetId::High), setInfo(c, FringeSetId::Low)};
    }
    info.extra = {{"device", "cylscan virtual head"},
                  {"scene", s.name},
                  {"seed", request_.seed},
                  {"steps_per_deg", plan.steps_per_deg},
                  {"stage_steps", {{"high", plan.high.positions}, {"low", plan.low.positions}}},
                  {"exposure_us", head_.config().cameras.front().exposure_us},
                  {"plan", "ring"},
                  {"ring", ringJson(plan)}};
    if (bit_depth_ > 8) info.extra["bit_depth"] = bit_depth_;
    info.extra.update(extra);
    formats::CaptureBundleWriter writer(dir, info);
    for (const auto motion : formats::kFringeSets) {
      const auto& steps = plan.set(motion).positions;
      for (std::size_t k = 0; k < steps.size(); ++k) {
        rig_.moveTo(steps[k]);
        const auto frames = rig_.capture(cams);
        for (std::size_t c = 0; c < cams.size(); ++c) {
          writer.writeFrame(cams[c], plan.setOf(cams[c], motion), static_cast<int>(k),
                            frames[c].image);
        }
        frames_ += static_cast<int>(cams.size());
      }
    }
    writer.commit();
    ++bundles_;
  }

  int frames() const { return frames_; }
  int bundles() const { return bundles_; }

 private:
  const SimulateRequest& request_;
  const RingSetup& setup_;
  sim::VirtualHead& head_;
  Rig rig_;
  int bit_depth_ = 8;
  int frames_ = 0;
  int bundles_ = 0;
};

json ringAcquisition(const SimulateRequest& request, const RingSetup& setup) {
  json cams = json::object();
  const sim::CylindricalProjector projector(setup.head.projector);
  for (const std::string& c : setup.cameras) {
    for (const auto& params : setup.head.cameras) {
      if (params.name != c) continue;
      const auto range = sim::workingVolumeAzimuthDeg(sim::CameraModel(params), projector);
      cams[c] = {{"azimuth_range_deg", {range[0], range[1]}},
                 {"high_deg", setup.plan.anglesDeg(c, formats::FringeSetId::High)},
                 {"low_deg", setup.plan.anglesDeg(c, formats::FringeSetId::Low)}};
    }
  }
  return {{"plan", "ring"},
          {"ring", ringJson(setup.plan)},
          {"steps_per_deg", setup.plan.steps_per_deg},
          {"cameras", cams},
          {"board", setup.profile.file.string()},
          {"seed", request.seed},
          {"noise_scale", setup.head.noise.scale}};
}

void printRingSummary(const SimulateRequest& request, const sim::HeadConfig& head,
                      const RingScanner& scanner, const std::string& what,
                      WallClock::time_point started) {
  const double seconds = std::chrono::duration<double>(WallClock::now() - started).count();
  const sim::CameraParams& main = head.cameras.front();
  if (request.json) {
    std::cout << json{{"out", request.out},           {"what", what},
                      {"width", main.width},          {"height", main.height},
                      {"bundles", scanner.bundles()}, {"frames_rendered", scanner.frames()},
                      {"seed", request.seed},         {"seconds", seconds}}
                     .dump()
              << "\n";
  } else {
    std::cout << "simulate: " << what << ": " << scanner.bundles() << " ring bundles, "
              << scanner.frames() << " frames (" << main.width << "x" << main.height << ") in "
              << seconds << " s -> " << request.out << "\n";
  }
}

// --turntable: the extrinsics dataset (see sim::TurntableDesign).
void runTurntable(const SimulateRequest& request, const RingSetup& setup,
                  WallClock::time_point started) {
  const sim::TurntableDesign d = sim::turntableDesign(kExtraTurnDeg);
  json truth;
  for (const std::string& c : setup.cameras) {
    for (const auto& params : setup.head.cameras) {
      if (params.name == c) truth["head"]["cameras"][c] = poseJson(sim::cameraPose(params));
    }
  }
  for (const auto& t : d.turns) {
    if (!truth["head"]["cameras"].contains(t.facing)) {
      throw std::invalid_argument("simulate --turntable: the board has no camera '" + t.facing +
                                  "' (the turntable dataset is made for board/sim360's cameras)");
    }
  }
  truth["head"]["frame"] = "main";
  truth["head"]["convention"] = "X_main = R * X_cam + T (mm)";
  truth["turntable"] = {
      {"axis_point", vec(d.axis_point)},
      {"axis_direction", vec(d.axis_direction)},
      {"convention",
       "turning the head by turntable_deg (right-handed about axis_direction) maps a world point W "
       "(world = the head frame at turntable_deg 0) to X_head = Rot(axis, -turntable_deg) * W"}};
  json centres = json::array();
  for (const auto& s : d.target)
    centres.push_back(vec(s.center));
  truth["target"] = {{"radius", d.target.front().radius}, {"centers", centres}};
  truth["acquisition"] = ringAcquisition(request, setup);

  sim::VirtualHead head(setup.head, sim::Scene{}, request.seed);
  RingScanner scanner(request, setup, head);
  const fs::path out(request.out);
  fs::create_directories(out);
  const auto scan = [&](const std::vector<sim::Sphere>& spheres,
                        const sim::TurntableDesign::Turn& t, const fs::path& dir,
                        const std::string& name) {
    const sim::RigidMotion to_head = d.worldToHead(t.turntable_deg);
    sim::Scene sc;
    sc.name = name;
    json head_centres = json::array();
    for (std::size_t i = 0; i < spheres.size(); ++i) {
      const Vec3 c = to_head.apply(spheres[i].center);
      sc.objects.push_back(sphere("sphere_" + std::to_string(i), c, spheres[i].radius));
      head_centres.push_back(vec(c));
    }
    scanner.writeBundle(dir, sc, {{"turntable_deg", t.turntable_deg}});
    return json{
        {"turntable_deg", t.turntable_deg}, {"facing", t.facing}, {"centers_head", head_centres}};
  };
  const int n = static_cast<int>(d.turns.size());
  for (int i = 0; i < n; ++i) {
    const std::string id = "turn" + formats::frameFileName(i, n);
    truth["turns"][id] = scan(d.target, d.turns[static_cast<std::size_t>(i)], out / id, "target");
  }
  truth["check"] = {{"radius", d.check.radius}, {"center", vec(d.check.center)}};
  const int m = static_cast<int>(d.check_turns.size());
  for (int i = 0; i < m; ++i) {
    const std::string id = "turn" + formats::frameFileName(i, m);
    truth["check"]["turns"][id] =
        scan({d.check}, d.check_turns[static_cast<std::size_t>(i)], out / "check" / id, "check");
  }
  formats::writeFileAtomically(out / "truth.json", truth.dump(2) + "\n");
  printRingSummary(request, setup.head, scanner, "turntable", started);
}

// Neither flag: ring scans of the board's default scene (or the --scene
// files), in the head frame, with their truth.
void runRingScenes(const SimulateRequest& request, const RingSetup& setup,
                   WallClock::time_point started) {
  std::vector<sim::Scene> scenes;
  if (request.scenes.empty()) {
    if (setup.profile.sim->scene.empty()) {
      throw std::invalid_argument(setup.profile.file.string() +
                                  ": [sim] has no scene; give --scene");
    }
    scenes.push_back(sim::loadScene(setup.profile.sim->scene));
  }
  std::set<std::string> names;
  for (const std::string& file : request.scenes) {
    scenes.push_back(sim::loadScene(file));
    if (!names.insert(scenes.back().name).second) {
      throw std::invalid_argument(file + ": scene name '" + scenes.back().name +
                                  "' is already used");
    }
  }
  sim::VirtualHead head(setup.head, sim::Scene{}, request.seed);
  RingScanner scanner(request, setup, head);
  const fs::path out(request.out);
  fs::create_directories(out);
  json truth = {{"frame", "main"}, {"scenes", json::object()}};
  for (const sim::Scene& s : scenes) {
    scanner.writeBundle(out / "test" / s.name, s, json::object());
    truth["scenes"][s.name] = truthOf(s);
  }
  json cams = json::object();
  for (const std::string& c : setup.cameras) {
    for (const auto& params : setup.head.cameras) {
      if (params.name == c) cams[c] = poseJson(sim::cameraPose(params));
    }
  }
  truth["head"] = {{"cameras", cams}};
  truth["acquisition"] = ringAcquisition(request, setup);
  formats::writeFileAtomically(out / "truth.json", truth.dump(2) + "\n");
  printRingSummary(request, setup.head, scanner, "scenes", started);
}

void runRingSimulate(const SimulateRequest& request, WallClock::time_point started) {
  if (!request.head.empty()) {
    throw std::invalid_argument(
        "simulate: --board takes the head from the board ([sim]); no --head");
  }
  if (!request.camera.empty() && request.turntable) {
    throw std::invalid_argument("simulate: give --camera or --turntable, not both");
  }
  const RingSetup setup = ringSetup(request);
  if (!request.camera.empty()) {
    runCameraDataset(request, setup, started);
  } else if (request.turntable) {
    runTurntable(request, setup, started);
  } else {
    runRingScenes(request, setup, started);
  }
}

void runOneDirection(const SimulateRequest& request, WallClock::time_point started) {
  sim::HeadConfig config =
      request.head.empty() ? sim::defaultHeadConfig() : sim::loadHeadConfig(request.head);
  if (config.cameras.size() < 2 || config.cameras[1].name != "aux") {
    throw std::invalid_argument("simulate: the head needs the cameras 'main' and 'aux'");
  }
  runDataset(request, applyRequest(config, request), std::nullopt, json::object(), json::object(),
             started);
}

void runSimulate(SimulateRequest request) {
  const auto started = WallClock::now();
  if (request.quick) {
    if (request.width == 0) request.width = 320;
    if (request.height == 0) request.height = 256;
  }
  if ((request.width == 0) != (request.height == 0)) {
    throw std::invalid_argument("simulate: give both --width and --height");
  }
  if (!request.board.empty()) {
    runRingSimulate(request, started);
    return;
  }
  if (!request.camera.empty() || request.turntable) {
    throw std::invalid_argument("simulate: --camera and --turntable need --board (a 360° head)");
  }
  runOneDirection(request, started);
}

}  // namespace

void addSimulateCommand(CLI::App& app) {
  auto request = std::make_shared<SimulateRequest>();
  CLI::App* cmd = app.add_subcommand("simulate", "render a dataset on the virtual head (spec §6)");
  cmd->add_option("--out", request->out, "output directory")->required();
  cmd->add_option("--head", request->head,
                  "virtual head file (default: built-in board/sim/head.toml)");
  cmd->add_option("--width", request->width, "image width (intrinsics scaled, same field of view)")
      ->check(CLI::Range(64, 4096));
  cmd->add_option("--height", request->height, "image height")->check(CLI::Range(64, 4096));
  CLI::Option* frames = cmd->add_option("--frames", request->frames, "frames per fringe set")
                            ->check(CLI::Range(3, 200));
  cmd->add_option("--noise", request->noise, "scale on the noise model (0: noiseless)")
      ->check(CLI::Range(0.0, 100.0));
  cmd->add_option("--seed", request->seed, "noise seed (same seed, same bytes)");
  cmd->add_option("--scene", request->scenes, "extra test scene file (repeatable)");
  cmd->add_option("--poses", request->poses, "calibration plane poses")->check(CLI::Range(1, 100));
  cmd->add_option("--boards", request->boards, "checkerboard poses")->check(CLI::Range(1, 99));
  cmd->add_option("--bit-depth", request->bit_depth, "camera bit depth (8, 10, 12 or 16)")
      ->check(CLI::IsMember({8, 10, 12, 16}));
  cmd->add_option("--sphere-poses", request->sphere_poses,
                  "study: poses of the 50 mm sphere (scenes sphere_poseNN, main+aux)")
      ->check(CLI::Range(0, 99));
  cmd->add_option("--plane-poses", request->plane_poses,
                  "study: test plane poses (scenes plane_poseNN, main+aux)")
      ->check(CLI::Range(0, 99));
  cmd->add_option("--repeats", request->repeats,
                  "study: repeated scans of two fixed sphere and plane poses "
                  "(sphere_repeatP_rNN, plane_repeatP_rNN)")
      ->check(CLI::Range(0, 99));
  cmd->add_option("--board", request->board,
                  "a 360° head's board (e.g. board/sim360): with --camera, --turntable or "
                  "neither (a ring scan of its default scene)");
  cmd->add_option("--camera", request->camera,
                  "with --board: the spec §6 dataset of this camera's direction");
  cmd->add_flag("--turntable", request->turntable,
                "with --board: the extrinsics dataset (the head on a turntable)");
  cmd->add_flag("--quick", request->quick, "320x256 unless --width/--height are given");
  cmd->add_flag("--json", request->json, "print the summary as one JSON object");
  cmd->callback([request, frames] {
    request->frames_given = frames->count() > 0;
    runSimulate(*request);
  });
}

}  // namespace cylscan::tools
