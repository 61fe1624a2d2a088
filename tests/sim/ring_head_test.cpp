// SPDX-License-Identifier: Apache-2.0
// The 360° virtual head (board/sim360, drivers/sim/ring_head.hpp): its cameras
// are main turned about the projector axis, the board profile's azimuth ranges
// contain the cameras' working volumes, the head re-expressed in a camera's
// frame renders that camera's frames, and the turntable dataset's design puts
// the target in front of each camera at its turn.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "drivers/board_profile.hpp"
#include "drivers/sim/ring_head.hpp"
#include "sim_test_support.hpp"

namespace cylscan::sim {
namespace {

namespace fs = std::filesystem;

const fs::path kBoard = fs::path(CYLSCAN_SOURCE_DIR) / "board" / "sim360";
const std::pair<const char*, double> kRing[] = {
    {"main", 0.0}, {"cam90", 90.0}, {"cam180", 180.0}, {"cam270", 270.0}};

HeadConfig ringHead(int width = 0, int height = 0) {
  HeadConfig head = loadHeadConfig(kBoard / "head.toml");
  if (width > 0) head = withResolution(head, width, height);
  return head;
}

const CameraParams& cameraOf(const HeadConfig& head, std::string_view name) {
  for (const CameraParams& c : head.cameras) {
    if (c.name == name) return c;
  }
  throw std::invalid_argument("no camera " + std::string(name));
}

// The rotation about the projector axis (vertical through (120, 0, 0)).
RigidMotion aboutProjectorAxis(double deg) {
  return rotationAbout(Vec3(120, 0, 0), Vec3::UnitY(), deg);
}

double wrap180(double a) {
  return std::remainder(a, 360.0);
}

TEST(RingHead, CamerasAreMainTurnedAboutTheProjectorAxis) {
  const HeadConfig head = ringHead();
  ASSERT_EQ(head.cameras.size(), 5u);
  EXPECT_EQ(head.cameras.back().name, "aux");
  const CylindricalProjector projector(head.projector);
  const CameraModel main(cameraOf(head, "main"));
  for (const auto& [name, a] : kRing) {
    const CameraParams& params = cameraOf(head, name);
    const CameraModel cam(params);
    const RigidMotion turn = aboutProjectorAxis(a);
    // The same intrinsics and sensor as main: only the pose differs.
    CameraParams same = params;
    same.name = "main";
    same.position_mm = {0, 0, 0};
    same.rotation_deg = {0, 0, 0};
    EXPECT_EQ(same, cameraOf(head, "main")) << name;
    // Centre and rays: main's turned by A (1e-9: the head file's exact values
    // through a rotation vector; the pixel rays share the same Newton inversion).
    EXPECT_LT((cam.centre() - turn.apply(main.centre())).norm(), 1e-9) << name;
    for (const auto& [u, v] : {std::pair{0.0, 0.0}, std::pair{999.0, 0.0}, std::pair{502.3, 397.8},
                               std::pair{0.0, 799.0}, std::pair{999.0, 799.0}}) {
      EXPECT_LT((cam.rayDirection(u, v) - turn.r * main.rayDirection(u, v)).norm(), 1e-12)
          << name << " pixel " << u << ", " << v;
    }
    // The projector azimuth of its centre pixel's point at 580 mm: main's + A.
    const auto at580 = [](const CameraModel& c) {
      const Vec3 d = c.rayDirection(c.params().cx, c.params().cy);
      const double z = (c.rotationCamFromMain() * d).z();
      return Vec3(c.centre() + d * (580.0 / z));
    };
    EXPECT_NEAR(wrap180(projector.azimuthDeg(at580(cam)) - projector.azimuthDeg(at580(main)) - a),
                0.0, 1e-9)
        << name;
  }
}

TEST(RingHead, TheTrueExtrinsicsAreTheHeadFilesPoses) {
  // X_main = R · X_cam + T, R = R_y(A), T = the camera's centre: what
  // simulate --turntable writes to truth.json.
  const HeadConfig head = ringHead();
  for (const auto& [name, a] : kRing) {
    const RigidMotion pose = cameraPose(cameraOf(head, name));
    const Mat3 ry = Eigen::AngleAxisd(a * kDeg, Vec3::UnitY()).toRotationMatrix();
    EXPECT_LT((pose.r - ry).norm(), 1e-12) << name;
    const Vec3 c(120 - 120 * std::cos(a * kDeg), 0, 120 * std::sin(a * kDeg));
    EXPECT_LT((pose.t - c).norm(), 1e-9) << name;
    // A point 580 mm ahead of the camera, mapped by the pose, is the camera's projection centre.
    const CameraModel cam(cameraOf(head, name));
    const Vec3 ahead = pose.apply(Vec3(0, 0, 580));
    const auto px = cam.project(ahead);
    ASSERT_TRUE(px);
    EXPECT_NEAR(px->x(), cam.params().cx, 1e-9);
    EXPECT_NEAR(px->y(), cam.params().cy, 1e-9);
  }
}

TEST(RingHead, ProfileAzimuthsContainTheWorkingVolumes) {
  const drivers::BoardProfile profile = drivers::loadBoardProfile(kBoard);
  EXPECT_EQ(profile.scanTable()["plan"].value_or(std::string()), "ring");
  ASSERT_TRUE(profile.sim);
  ASSERT_EQ(profile.cameras.size(), 4u);
  const CylindricalProjector projector(profile.sim->head.projector);
  std::string trigger;
  for (const auto& [name, a] : kRing) {
    const drivers::CameraProfile& cam = profile.camera(name);
    ASSERT_TRUE(cam.azimuth_deg) << name;
    const auto [lo, hi] = *cam.azimuth_deg;
    const auto range =
        workingVolumeAzimuthDeg(CameraModel(cameraOf(profile.sim->head, name)), projector);
    // The head's range, shifted by whole turns next to the profile's.
    const double shift = 360.0 * std::round(((lo + hi) - (range[0] + range[1])) / 720.0);
    EXPECT_LE(lo, range[0] + shift) << name;
    EXPECT_GE(hi, range[1] + shift) << name;
    // Written from the computed values, rounded outwards to 0.1°: never looser than that.
    EXPECT_LT(range[0] + shift - lo, 0.1) << name;
    EXPECT_LT(hi - range[1] - shift, 0.1) << name;
    // Main's range (docs: −20.15 … −2.88), turned by A.
    EXPECT_NEAR(range[0] + shift - a, -20.155, 0.01) << name;
    EXPECT_NEAR(range[1] + shift - a, -2.883, 0.01) << name;
    if (trigger.empty()) trigger = cam.trigger_line;
    EXPECT_EQ(cam.trigger_line, trigger) << name << ": one trigger line for all cameras";
  }
}

// The first hit and the pattern of every pixel of `camera` in the full head
// equal those of main in the head re-expressed in that camera's frame.
TEST(RingHead, ReexpressedHeadRendersTheCamerasFrames) {
  HeadConfig full = ringHead(160, 128);
  full.noise.scale = 0;
  const Scene surround = loadScene(kBoard / "scenes" / "surround.toml");
  const CylindricalProjector full_projector(full.projector);
  for (const auto& [name, a] : kRing) {
    const HeadConfig view = headForCamera(full, name);
    ASSERT_EQ(view.cameras.size(), 2u);
    EXPECT_EQ(view.cameras[0].name, "main");
    EXPECT_EQ(view.cameras[1].name, "aux");
    const CylindricalProjector view_projector(view.projector);
    const RigidMotion pose = cameraPose(cameraOf(full, name));  // view frame → head frame
    const CameraModel full_cam(cameraOf(full, name)), view_cam(view.cameras[0]);
    const PixelGeometry g_full = tracePixels(surround, full_cam, full_projector);
    const PixelGeometry g_view =
        tracePixels(transformed(surround, pose.inverse()), view_cam, view_projector);
    int hits = 0;
    double worst_point = 0, worst_light = 0, worst_intensity = 0;
    for (int i = 0; i < g_full.width * g_full.height; ++i) {
      ASSERT_EQ(g_full.flags.data[i], g_view.flags.data[i]) << name << " pixel " << i;
      const auto k = static_cast<std::size_t>(i);
      worst_light = std::max({worst_light, double{std::abs(g_full.ambient[k] - g_view.ambient[k])},
                              double{std::abs(g_full.direct[k] - g_view.direct[k])}});
      if (!(g_full.flags.data[i] & PixelGeometry::kHit)) continue;
      ++hits;
      const Vec3 pf(g_full.points.at<cv::Vec3d>(i)[0], g_full.points.at<cv::Vec3d>(i)[1],
                    g_full.points.at<cv::Vec3d>(i)[2]);
      const Vec3 pv(g_view.points.at<cv::Vec3d>(i)[0], g_view.points.at<cv::Vec3d>(i)[1],
                    g_view.points.at<cv::Vec3d>(i)[2]);
      worst_point = std::max(worst_point, (pose.apply(pv) - pf).norm());
      // The same projector azimuth, so the same wall angle at every stage angle.
      EXPECT_NEAR(wrap180(view_projector.azimuthDeg(pv) - full_projector.azimuthDeg(pf)), 0, 1e-9);
      for (double rho : {17.3, 236.0}) {
        const auto intensity = [&](const PixelGeometry& g, const CylindricalProjector& p) {
          const double beta =
              p.wallAngleDeg(g.rays[static_cast<std::size_t>(i)], p.centreOffset(rho), rho);
          return g.ambient[i] + g.direct[i] * p.transmission(beta);
        };
        worst_intensity = std::max(worst_intensity, std::abs(intensity(g_full, full_projector) -
                                                             intensity(g_view, view_projector)));
      }
    }
    // Every camera sees its two objects (a fifth of its pixels at least).
    EXPECT_GT(hits, g_full.width * g_full.height / 5) << name;
    // Same geometry computed in two frames: double rounding (1e-9 mm); the
    // lighting terms are floats (relative 6e-8 of values ≤ 1.1); the wall
    // crossing's azimuth γ0 is a float too (≈ 8e-6° at 100°), and the blurred
    // pattern's slope is < 0.8 per degree: ≈ 1e-5 of intensity (full well = 1).
    EXPECT_LT(worst_point, 1e-6) << name;
    EXPECT_LT(worst_light, 1e-6) << name;
    EXPECT_LT(worst_intensity, 2e-5) << name;

    // The rendered 16-bit frames, noise off: the same counts (a count is
    // 1.5e-5 of full well, so a rounding boundary may move one pixel by 1).
    Exposure e;
    e.samples = 1;
    e.stage_deg[0] = 236.0;
    e.light[0] = true;
    e.bit_depth = 16;
    e.noise_scale = 0;
    const NoiseTable noise(1);
    const cv::Mat f_full = renderFrame(g_full, full_projector, e, noise, 1);
    const cv::Mat f_view = renderFrame(g_view, view_projector, e, noise, 1);
    cv::Mat diff;
    cv::absdiff(f_full, f_view, diff);
    double max_diff = 0;
    cv::minMaxLoc(diff, nullptr, &max_diff);
    EXPECT_LE(max_diff, 1.0) << name;
    EXPECT_LT(cv::countNonZero(diff), diff.total() / 100) << name;
  }
}

TEST(RingHead, ReexpressionKeepsAuxBesideTheCamera) {
  const HeadConfig full = ringHead();
  const HeadConfig sim = defaultHeadConfig();  // board/sim: aux beside main
  for (const auto& [name, a] : kRing) {
    const HeadConfig view = headForCamera(full, name);
    EXPECT_EQ(view.cameras[1], sim.cameras[1]) << name;
    // The projector axis stays 120 mm right of the (new) main, vertical.
    const Vec3 axis = toVec(view.projector.axis_origin_mm);
    EXPECT_LT((axis - Vec3(120, 0, 0)).norm(), 1e-9) << name;
    const Mat3 r = rotationFromVectorDeg(view.projector.rotation_deg);
    EXPECT_LT((r.col(1) - Vec3::UnitY()).norm(), 1e-12) << name;
    // ... turned by −A, so the azimuths keep the cylinder's zero.
    EXPECT_NEAR(wrap180(std::atan2(r(0, 2), r(2, 2)) / kDeg + a), 0, 1e-9) << name;
  }
  // For main it is the one-direction head (board/sim) with the 360° head's values.
  const HeadConfig main_view = headForCamera(full, "main");
  EXPECT_EQ(main_view.projector, sim.projector);
  EXPECT_EQ(main_view.cameras[0], sim.cameras[0]);
  try {
    headForCamera(full, "cam45");
    FAIL() << "no error for an unknown camera";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("cam45"), std::string::npos) << e.what();
  }
}

TEST(RingHead, ReexpressionKeepsFrameFaultsOnTheirCamera) {
  HeadConfig full = ringHead();
  full.faults.drop_frames = 2;
  full.faults.corrupt_frames = 1;
  full.faults.lose_steps_after = 100;
  full.faults.lose_steps = 3;
  full.faults.camera = "cam90";
  const HeadConfig cam90 = headForCamera(full, "cam90");
  EXPECT_EQ(cam90.faults.camera, "main");  // cam90 is this head's main
  EXPECT_EQ(cam90.faults.drop_frames, 2);
  EXPECT_EQ(cam90.faults.corrupt_frames, 1);
  full.faults.camera = "aux";
  EXPECT_EQ(headForCamera(full, "cam90").faults, full.faults);
  // The old main is not in cam180's head: its frame faults must not move to cam180.
  full.faults.camera = "main";
  const HeadConfig cam180 = headForCamera(full, "cam180");
  EXPECT_EQ(cam180.faults.camera, "main");
  EXPECT_EQ(cam180.faults.drop_frames, 0);
  EXPECT_EQ(cam180.faults.corrupt_frames, 0);
  EXPECT_EQ(cam180.faults.lose_steps, 3);  // the stage's faults stay
  EXPECT_EQ(cam180.faults.lose_steps_after, 100);
}

TEST(RingHead, TransformedScenesMoveEveryShape) {
  const RigidMotion m = aboutProjectorAxis(90).after({Mat3::Identity(), Vec3(1, 2, 3)});
  Scene s;
  s.objects.push_back({"sphere", Sphere{Vec3(0, 0, 580), 50}, 0.8});
  s.objects.push_back({"box", Box{Vec3(10, 0, 600), Vec3(10, 20, 30), Mat3::Identity()}, 0.8});
  s.objects.push_back({"plane", Plane{Vec3(0, 0, 640), Vec3(0, 0, -1), std::nullopt}, 0.8});
  const Scene t = transformed(s, m);
  EXPECT_LT((std::get<Sphere>(t.objects[0].shape).center - m.apply(Vec3(0, 0, 580))).norm(), 1e-12);
  EXPECT_LT((std::get<Box>(t.objects[1].shape).rotation - m.r).norm(), 1e-12);
  EXPECT_LT((std::get<Plane>(t.objects[2].shape).normal - m.r * Vec3(0, 0, -1)).norm(), 1e-12);
  // A ray and its moved copy hit the scenes at the same distance.
  const Ray ray{Vec3(5, -3, 0), Vec3(0.01, 0.02, 1).normalized()};
  const auto h0 = s.firstHit(ray, 1e9);
  const auto h1 = t.firstHit({m.apply(ray.origin), m.r * ray.dir}, 1e9);
  ASSERT_TRUE(h0 && h1);
  EXPECT_NEAR(h0->t, h1->t, 1e-9);
  // A plane rectangle's sides follow the main x axis: a turn about y cannot keep them.
  Scene patch;
  patch.objects.push_back({"patch", Plane{Vec3(0, 0, 600), Vec3(0, 0, -1), {{40, 30}}}, 0.8});
  EXPECT_THROW(transformed(patch, aboutProjectorAxis(90)), std::invalid_argument);
  EXPECT_NO_THROW(transformed(patch, {Mat3::Identity(), Vec3(0, 5, 0)}));
}

// Pixel margin of a sphere's visible cap in a camera's image (negative: cut
// by the border) and its depth range along the camera's view.
struct CapView {
  double margin_px = 1e9;
  double z_min = 1e9, z_max = -1e9;
};
CapView capView(const CameraModel& cam, const Sphere& s) {
  CapView v;
  for (int i = 0; i < 4000; ++i) {
    const double u = (i + 0.5) / 4000.0, th = std::acos(1 - 2 * u), ph = i * 2.399963;
    const Vec3 n(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th));
    const Vec3 x = s.center + s.radius * n;
    if (n.dot(cam.centre() - x) < 0) continue;
    const auto px = cam.project(x);
    if (!px) return {-1e9, 0, 0};
    v.margin_px = std::min(
        {v.margin_px, px->x(), px->y(), cam.width() - 1 - px->x(), cam.height() - 1 - px->y()});
    const double z = cam.toCamera(x).z();
    v.z_min = std::min(v.z_min, z);
    v.z_max = std::max(v.z_max, z);
  }
  return v;
}

TEST(RingHead, TurntableTargetFacesEachCameraAtItsTurn) {
  const HeadConfig head = ringHead(320, 256);  // the fixture's resolution
  const TurntableDesign d = turntableDesign(2.5);
  // The axis is near, not on, the projector axis: a few mm off, a fraction of a degree tilted.
  const Vec3 off = d.axis_point - Vec3(120, 0, 0);
  EXPECT_GT(std::hypot(off.x(), off.z()), 1.0);
  EXPECT_LT(std::hypot(off.x(), off.z()), 10.0);
  const double tilt = std::acos(d.axis_direction.dot(Vec3::UnitY())) / kDeg;
  EXPECT_GT(tilt, 0.1);
  EXPECT_LT(tilt, 1.0);
  // Four spheres of radius 25, not coplanar (the fourth centre > 20 mm off the others' plane).
  ASSERT_EQ(d.target.size(), 4u);
  const Vec3 n = (d.target[1].center - d.target[0].center)
                     .cross(d.target[2].center - d.target[0].center)
                     .normalized();
  EXPECT_GT(std::abs(n.dot(d.target[3].center - d.target[0].center)), 20.0);
  std::map<std::string, int> turns_facing;
  const auto check = [&](const std::vector<Sphere>& spheres, const TurntableDesign::Turn& turn) {
    const RigidMotion to_head = d.worldToHead(turn.turntable_deg);
    for (const CameraParams& params : head.cameras) {
      if (params.name == "aux") continue;
      const CameraModel cam(params);
      for (const Sphere& s : spheres) {
        const CapView v = capView(cam, {to_head.apply(s.center), s.radius});
        const std::string where = params.name + " at turn " + std::to_string(turn.turntable_deg);
        if (params.name == turn.facing) {
          // Wholly inside the image, 5 px from the border (at 320 × 256), in
          // the calibrated depths (540–620 mm, extrapolated by at most 10 mm).
          EXPECT_GT(v.margin_px, 5.0) << where;
          EXPECT_GT(v.z_min, 530.0) << where;
          EXPECT_LT(v.z_max, 630.0) << where;
        } else {
          EXPECT_LT(v.margin_px, -s.radius) << where << " sees a sphere it should not";
        }
      }
    }
  };
  for (const auto& turn : d.turns) {
    check(d.target, turn);
    ++turns_facing[turn.facing];
  }
  EXPECT_EQ(turns_facing["cam90"], 1);
  EXPECT_EQ(turns_facing["cam180"], 1);
  EXPECT_EQ(turns_facing["cam270"], 1);
  EXPECT_EQ(turns_facing["main"], 3);  // at 0 and at the two extra turns
  // The held-out check sphere: main at one turn, its neighbours at others.
  EXPECT_EQ(d.check.radius, 50.0);
  ASSERT_EQ(d.check_turns.size(), 3u);
  for (const auto& turn : d.check_turns)
    check({d.check}, turn);
}

TEST(RingHead, SurroundSceneIsInFrontOfEveryCamera) {
  const HeadConfig head = ringHead(160, 128);
  const Scene surround = loadScene(kBoard / "scenes" / "surround.toml");
  EXPECT_EQ(surround.objects.size(), 8u);
  for (const auto& [name, a] : kRing) {
    const CameraModel cam(cameraOf(head, name));
    int spheres = 0, boxes = 0;
    for (const SceneObject& o : surround.objects) {
      const bool own = o.name.ends_with(std::string("_") + name);
      if (const auto* s = std::get_if<Sphere>(&o.shape)) {
        EXPECT_EQ(s->radius, 50.0);
        const CapView v = capView(cam, *s);
        if (own) {
          ++spheres;
          EXPECT_GT(v.margin_px, 1.0) << o.name;
          EXPECT_GE(v.z_min, 540.0) << o.name;
          EXPECT_LE(v.z_max, 620.0) << o.name;
        } else {
          EXPECT_LT(v.margin_px, -50.0) << o.name << " seen by " << name;
        }
      } else if (const auto* b = std::get_if<Box>(&o.shape)) {
        const Vec3 c = cam.toCamera(b->center);
        if (own) {
          ++boxes;
          EXPECT_GT(c.z(), 560.0) << o.name;
          EXPECT_LT(c.z(), 600.0) << o.name;
          const auto px = cam.project(b->center);
          ASSERT_TRUE(px) << o.name;
          EXPECT_GT(px->x(), 0.0);
          EXPECT_LT(px->x(), cam.width() - 1.0);
        } else {
          EXPECT_LT(c.z(), 100.0) << o.name << " in front of " << name;
        }
      }
    }
    EXPECT_EQ(spheres, 1) << name;
    EXPECT_EQ(boxes, 1) << name;
  }
  // Lit and unshadowed: the projector reaches (almost) every pixel a camera sees.
  const CylindricalProjector projector(head.projector);
  for (const auto& [name, a] : kRing) {
    const PixelGeometry g = tracePixels(surround, CameraModel(cameraOf(head, name)), projector);
    int hit = 0, lit = 0, shadow = 0;
    for (int i = 0; i < g.width * g.height; ++i) {
      hit += (g.flags.data[i] & PixelGeometry::kHit) ? 1 : 0;
      lit += (g.flags.data[i] & PixelGeometry::kLit) ? 1 : 0;
      shadow += (g.flags.data[i] & PixelGeometry::kShadow) ? 1 : 0;
    }
    EXPECT_GT(lit, 0.97 * hit) << name;
    EXPECT_LT(shadow, 0.01 * hit) << name;
  }
}

}  // namespace
}  // namespace cylscan::sim
