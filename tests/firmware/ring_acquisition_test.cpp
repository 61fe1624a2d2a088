// SPDX-License-Identifier: Apache-2.0
// The ring acquisition of the 360° head (docs/head-360.md) on a small copy of the
// virtual head board/sim360 (four cameras, main turned by 0/90/180/270° about
// the projector axis): every camera gets both sets, each in the role the
// projector's geometry gives it; each camera's phase is the head's truth; the
// four cameras cost no more board time than main alone; the bundle keeps each
// camera's own angles and gives the streamed phase again, bit for bit.
//
// The truth comes from the virtual head (its projector's wall angles at the
// executed stage angles), never from the planner.
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "algo/phase_engine.hpp"
#include "drivers/board.hpp"
#include "drivers/sim/virtual_head.hpp"
#include "firmware/acquisition.hpp"
#include "firmware/bundle_sink.hpp"
#include "firmware/phase_sink.hpp"
#include "firmware/scan_plan.hpp"
#include "formats/capture_bundle.hpp"
#include "tests/firmware/homed_scan.hpp"
#include "tests/support/ring_board.hpp"
#include "tests/support/temp_dir.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;
using test_support::ringBoard;
using test_support::TempDir;
constexpr double kPi = std::numbers::pi;

const std::vector<std::string> kCameras{"main", "cam90", "cam180", "cam270"};

struct Scan {
  drivers::Board board;
  ScanOptions options;
  ScanPlan plan;
  explicit Scan(const fs::path& dir, std::vector<std::string> cameras = kCameras)
      : board(drivers::Board::open(dir)), options(scanOptionsFrom(board.profile())) {
    options.cameras = std::move(cameras);
    plan = planScan(options, board.profile().stage);
  }
  sim::VirtualHead& head() { return *board.virtualHead(); }
};

// Every frame the loop hands over: per camera, per set, the frame indices
// and angles in the order they came.
class RecordingSink final : public FrameSink {
 public:
  struct Frame {
    FringeSet set;
    int k;
    double stage_deg;
  };
  void onFrame(std::string_view camera, FringeSet set, int k, double stage_deg,
               const cv::Mat&) override {
    frames[std::string(camera)].push_back({set, k, stage_deg});
  }
  std::map<std::string, std::vector<Frame>> frames;
};

// The set a camera's frames of a motion set are, from the head's geometry:
// the half of the cylinder (high slots on β ∈ [0°, 180°), low on [180°, 360°))
// that lights every lit pixel of the camera at every frame of the motion set.
// `mixed` counts the pixel-frames lit by the other half (0 for a good plan).
struct Role {
  FringeSet set = FringeSet::High;
  long mixed = 0;
  long pixels = 0;
};

Role roleFromHead(sim::VirtualHead& head, const std::string& camera,
                  const std::vector<double>& angles_deg) {
  const auto geometry = head.pixelGeometry(camera);
  long high = 0, low = 0;
  Role role;
  for (int v = 0; v < geometry->points.rows; ++v) {
    for (int u = 0; u < geometry->points.cols; ++u) {
      if (!(geometry->flags.at<std::uint8_t>(v, u) & sim::PixelGeometry::kLit)) continue;
      const cv::Vec3d p = geometry->points.at<cv::Vec3d>(v, u);
      ++role.pixels;
      for (const double rho : angles_deg) {
        const double beta = head.projector().wallAngleDeg(sim::Vec3(p[0], p[1], p[2]), rho);
        (beta < 180.0 ? high : low) += 1;
      }
    }
  }
  role.set = high >= low ? FringeSet::High : FringeSet::Low;
  role.mixed = std::min(high, low);
  return role;
}

// A camera's roles in the two sweeps, and so the executed angles of its own
// sets, from the head (the report's executed angles of the motion sets).
struct CameraTruth {
  FringeSet first_sweep = FringeSet::High;
  std::vector<double> high_deg, low_deg;
};

CameraTruth truthOf(sim::VirtualHead& head, const std::string& camera, const ScanReport& report) {
  const Role sweep1 = roleFromHead(head, camera, report.high_deg);
  const Role sweep2 = roleFromHead(head, camera, report.low_deg);
  EXPECT_GT(sweep1.pixels, 160 * 128 / 2) << camera << ": its wall fills most of the view";
  EXPECT_EQ(sweep1.mixed, 0) << camera << ": lit by both halves in sweep 1";
  EXPECT_EQ(sweep2.mixed, 0) << camera << ": lit by both halves in sweep 2";
  EXPECT_NE(sweep1.set, sweep2.set) << camera << ": the same half in both sweeps";
  CameraTruth t;
  t.first_sweep = sweep1.set;
  t.high_deg = sweep1.set == FringeSet::High ? report.high_deg : report.low_deg;
  t.low_deg = sweep1.set == FringeSet::High ? report.low_deg : report.high_deg;
  return t;
}

struct PhaseError {
  double rms = 0, worst = 0;
  int pixels = 0;
};

double wrapPi(double d) {
  return d - 2 * kPi * std::round(d / (2 * kPi));
}

// The measured phases against the head's geometry: Φh = 2π·β/θh at the
// camera's high set's first frame (absolute within one equivalent period,
// 9 high periods), and φl = 2π·β/θl (mod 2π) at its low set's first frame (the
// low half starts with a slot at 180°, a whole 32 low periods from 0).
struct CameraPhaseError {
  PhaseError absolute, wrapped_low;
};

CameraPhaseError compareWithHead(sim::VirtualHead& head, const std::string& camera,
                                 const algo::PhaseMaps& maps, const CameraTruth& truth) {
  const auto geometry = head.pixelGeometry(camera);
  const auto& params = head.projector().params();
  CameraPhaseError e;
  double sum_abs = 0, sum_low = 0;
  for (int v = 0; v < maps.absolute.rows; ++v) {
    for (int u = 0; u < maps.absolute.cols; ++u) {
      const float phi = maps.absolute.at<float>(v, u);
      if (!std::isfinite(phi)) continue;
      if (!(geometry->flags.at<std::uint8_t>(v, u) & sim::PixelGeometry::kLit)) continue;
      const cv::Vec3d p = geometry->points.at<cv::Vec3d>(v, u);
      const sim::Vec3 x(p[0], p[1], p[2]);
      const double beta_high = head.projector().wallAngleDeg(x, truth.high_deg.front());
      const double truth_abs = 2 * kPi * beta_high / params.theta_high_deg;
      const double eq = 2 * kPi * 9;
      const double d = phi - truth_abs - eq * std::round((phi - truth_abs) / eq);
      sum_abs += d * d;
      e.absolute.worst = std::max(e.absolute.worst, std::abs(d));
      ++e.absolute.pixels;
      const double beta_low = head.projector().wallAngleDeg(x, truth.low_deg.front());
      const double dl =
          wrapPi(maps.wrapped_low.at<float>(v, u) - 2 * kPi * beta_low / params.theta_low_deg);
      sum_low += dl * dl;
      e.wrapped_low.worst = std::max(e.wrapped_low.worst, std::abs(dl));
      ++e.wrapped_low.pixels;
    }
  }
  if (e.absolute.pixels) {
    e.absolute.rms = std::sqrt(sum_abs / e.absolute.pixels);
    e.wrapped_low.rms = std::sqrt(sum_low / e.wrapped_low.pixels);
  }
  return e;
}

// Every camera's phase against the head, with the tolerances of the
// single-camera tests (tests/firmware/acquisition_test.cpp: noise ≈ 2 mrad rms
// at 8 bits and N = 25; an order error would be 2π). The ring's shifts change
// little: a set stepped by Δ = 0.212° spans 1.06 high or 0.94 low periods,
// which costs ≤ 0.4 % in noise (the planner's gains) and lets the blurred
// slots' 3rd harmonic, which an even N-step over one period cancels, leak a
// φ-dependent bias of a few mrad. Measured here: absolute rms ≈ 2.4 (stop and
// go) / 3.0 (continuous) mrad, worst ≈ 11 mrad; wrapped low rms ≈ 4.2 / 4.4
// mrad, worst ≈ 14 mrad, alike for both roles. So rms < 0.01 and worst < 0.1 rad.
void expectPhaseOfHead(sim::VirtualHead& head, const std::string& mode, PhaseSink& phase,
                       const ScanReport& report, const ScanPlan& plan) {
  for (const std::string& camera : kCameras) {
    SCOPED_TRACE(camera);
    const CameraTruth truth = truthOf(head, camera, report);
    const algo::PhaseMaps maps = phase.finalize(camera);
    const CameraPhaseError e = compareWithHead(head, camera, maps, truth);
    std::cout << "[ring] " << mode << " " << camera
              << (truth.first_sweep == FringeSet::High ? " (sweep 1 high)" : " (sweep 1 low)")
              << ": absolute vs head rms " << e.absolute.rms << " worst " << e.absolute.worst
              << ", wrapped low rms " << e.wrapped_low.rms << " worst " << e.wrapped_low.worst
              << " over " << e.absolute.pixels << " px, valid " << maps.valid_fraction << "\n";
    EXPECT_EQ(plan.setOf(camera, FringeSet::High), truth.first_sweep);
    EXPECT_GT(e.absolute.pixels, 160 * 128 * 8 / 10);
    EXPECT_LT(e.absolute.rms, 0.01);
    EXPECT_LT(e.absolute.worst, 0.1);
    EXPECT_LT(e.wrapped_low.rms, 0.01);
    EXPECT_LT(e.wrapped_low.worst, 0.1);
  }
}

cv::Mat zeroWhereInvalid(const cv::Mat& map, const cv::Mat& invalid) {
  cv::Mat out = map.clone();
  out.setTo(0, invalid != 0);
  return out;
}

TEST(RingAcquisition, EveryCameraGetsBothSetsInItsRoleAndTheHeadsPhase) {
  TempDir dir;
  Scan scan(ringBoard(dir));
  ASSERT_TRUE(scan.plan.ring.has_value()) << "board/sim360's profile plans a ring";
  PhaseSink phase(scan.plan, {});
  RecordingSink recorded;
  BundleSink bundle(dir.path() / "bundle", scan.plan, scan.options.cameras,
                    nlohmann::json::object());
  TeeSink sinks;
  sinks.add(phase);
  sinks.add(recorded);
  sinks.add(bundle);
  Acquisition acquisition(scan.board);
  const ScanReport report = acquisition.run(scan.options, scan.plan, sinks);
  bundle.commit();
  const int n = scan.plan.ring->frames;
  EXPECT_EQ(report.frames, 2 * n);
  EXPECT_EQ(report.retries, 0);

  // (a) N frames of each set for every camera, one set after the other (in
  // the order the stage ran the motion sets), each at the executed angles of
  // the motion set whose half the camera faced.
  for (const std::string& camera : kCameras) {
    SCOPED_TRACE(camera);
    const CameraTruth truth = truthOf(scan.head(), camera, report);
    const auto& frames = recorded.frames[camera];
    ASSERT_EQ(frames.size(), static_cast<std::size_t>(2 * n));
    for (int i = 0; i < 2 * n; ++i) {
      const auto& f = frames[static_cast<std::size_t>(i)];
      const FringeSet motion =
          (i < n) == (report.first_set == FringeSet::High) ? FringeSet::High : FringeSet::Low;
      const FringeSet expected = scan.plan.setOf(camera, motion);
      EXPECT_EQ(f.set, expected) << "frame " << i;
      EXPECT_EQ(f.k, i % n);
      const auto& angles = f.set == FringeSet::High ? truth.high_deg : truth.low_deg;
      EXPECT_EQ(f.stage_deg, angles[static_cast<std::size_t>(i % n)]) << "frame " << i;
    }
    EXPECT_EQ(phase.folded(camera), 2 * n);
  }
  // Memory: one engine of 16 bytes a pixel per camera (algo/phase_engine.hpp),
  // no frames kept: O(K × pixels).
  EXPECT_EQ(phase.workingStateBytes(), kCameras.size() * 16u * 160u * 128u);
  // Both roles occur on this head: cameras face both halves in sweep 1.
  EXPECT_FALSE(scan.plan.swapped.empty());
  EXPECT_LT(scan.plan.swapped.size(), kCameras.size());

  // (b) each camera's phase is the head's, in both roles.
  expectPhaseOfHead(scan.head(), "stop-and-go", phase, report, scan.plan);

  // (d) the bundle: top-level sets are main's, each camera reads its own
  // angles, and the phase from the bundle is the streamed one, bit for bit.
  const formats::CaptureBundleReader reader(dir.path() / "bundle");
  EXPECT_EQ(reader.info().high.stage_deg, report.high_deg);
  EXPECT_EQ(reader.info().extra.at("plan"), "ring");
  EXPECT_EQ(reader.info().extra.at("ring").at("frames"), n);
  for (const std::string& camera : kCameras) {
    SCOPED_TRACE(camera);
    const CameraTruth truth = truthOf(scan.head(), camera, report);
    EXPECT_EQ(reader.info().setOf(camera, FringeSet::High).stage_deg, truth.high_deg);
    EXPECT_EQ(reader.info().setOf(camera, FringeSet::Low).stage_deg, truth.low_deg);
    EXPECT_EQ(reader.info().hasOwnSets(camera), truth.first_sweep == FringeSet::Low);
    EXPECT_EQ(reader.info().extra.at("ring").at("cameras").at(camera), toString(truth.first_sweep));
    auto geometryOf = [&](FringeSet id) {
      const formats::FringeSetInfo& set = reader.info().setOf(camera, id);
      return algo::FringeSetGeometry{set.period_deg, set.stage_deg};
    };
    algo::PhaseEngine offline(reader.frameSize(camera), geometryOf(FringeSet::High),
                              geometryOf(FringeSet::Low), {});
    for (const FringeSet id : kFringeSets) {
      for (int k = 0; k < reader.frameCount(camera, id); ++k)
        offline.fold(id, k, reader.readFrame(camera, id, k));
    }
    const algo::PhaseMaps a = phase.finalize(camera);
    const algo::PhaseMaps b = offline.finalize();
    EXPECT_EQ(cv::norm(a.invalid, b.invalid, cv::NORM_INF), 0);
    EXPECT_EQ(cv::norm(a.wrapped_high, b.wrapped_high, cv::NORM_INF), 0);
    EXPECT_EQ(cv::norm(a.wrapped_low, b.wrapped_low, cv::NORM_INF), 0);
    EXPECT_EQ(cv::norm(zeroWhereInvalid(a.absolute, a.invalid),
                       zeroWhereInvalid(b.absolute, b.invalid), cv::NORM_INF),
              0);
    EXPECT_EQ(cv::norm(zeroWhereInvalid(a.fused, a.invalid), zeroWhereInvalid(b.fused, b.invalid),
                       cv::NORM_INF),
              0);
  }
}

using test::seconds;

// (c) Four cameras cost no more board time than main alone (the ring plan's
// aim, checked to at most 10 % more), whether main alone is scanned with the
// same ring profile or with the single-camera head's plan (board/sim's sets
// plan: each set at its own start, steps of θ/N). Board (virtual) time is
// deterministic, so this is not a wall-clock assertion.
void expectFourCamerasAsFastAsOne(const std::vector<std::pair<std::string, std::string>>& replace,
                                  const std::string& mode, bool check_phase) {
  TempDir dir;
  const fs::path board = ringBoard(dir, replace);
  Scan four(board);
  PhaseSink four_phase(four.plan, {});
  Acquisition four_acquisition(four.board);
  std::vector<double> done_s;  // board time at which each frame was in from every camera
  const ScanReport four_report = four_acquisition.run(
      four.options, four.plan, four_phase,
      [&](const ScanProgress&) { done_s.push_back(seconds(four.board.clock().now())); });

  Scan one(board, {"main"});
  PhaseSink one_phase(one.plan, {});
  Acquisition one_acquisition(one.board);
  const ScanReport one_report = one_acquisition.run(one.options, one.plan, one_phase);

  TempDir sets_dir;
  auto sets_replace = replace;
  sets_replace.emplace_back("plan = \"ring\"",
                            "plan = \"sets\"\nhigh_start_deg = 235.98\nlow_start_deg = 55.98");
  Scan sets(ringBoard(sets_dir, sets_replace), {"main"});
  ASSERT_FALSE(sets.plan.ring.has_value());
  PhaseSink sets_phase(sets.plan, {});
  Acquisition sets_acquisition(sets.board);
  const ScanReport sets_report = sets_acquisition.run(sets.options, sets.plan, sets_phase);

  const double t4 = seconds(four_report.duration);
  const double t1 = seconds(one_report.duration);
  const double t1_sets = seconds(sets_report.duration);
  std::cout << "[ring] " << mode << ": K=4 " << t4 << " s of board time (sweeps "
            << seconds(four_report.set_duration[0]) << " + " << seconds(four_report.set_duration[1])
            << " s); main alone: ring plan " << t1 << " s (ratio " << t4 / t1 << "), sets plan "
            << t1_sets << " s (sets " << seconds(sets_report.set_duration[0]) << " + "
            << seconds(sets_report.set_duration[1]) << " s, ratio " << t4 / t1_sets << ")\n";
  EXPECT_EQ(four_report.frames, one_report.frames);
  if (four.options.mode == firmware::ScanMode::Continuous) {
    // A sweep's frames come one camera frame period apart, not faster: the
    // speed follows the ring's common step Δ, not θ/N (with θl/N a low sweep
    // would trigger at 31.8 Hz, beyond the cameras' 30 Hz). Averaged over a
    // sweep, so the capture thread's 1 ms polls do not matter.
    const int n = four.plan.ring->frames;
    ASSERT_EQ(done_s.size(), static_cast<std::size_t>(2 * n));
    for (int sweep = 0; sweep < 2; ++sweep) {
      const double period = (done_s[static_cast<std::size_t>(sweep * n + n - 1)] -
                             done_s[static_cast<std::size_t>(sweep * n)]) /
                            (n - 1);
      std::cout << "[ring] continuous sweep " << sweep + 1 << ": a frame every " << period * 1e3
                << " ms\n";
      EXPECT_GE(period, 1.0 / four.options.frame_rate_hz - 1e-4) << "sweep " << sweep + 1;
    }
  }
  EXPECT_LE(t4, 1.10 * t1);
  EXPECT_LE(t4, 1.10 * t1_sets);
  if (check_phase) expectPhaseOfHead(four.head(), mode, four_phase, four_report, four.plan);
}

TEST(RingAcquisition, FourCamerasTakeTheTimeOfOneStopAndGo) {
  // The phase of a stop-and-go ring scan is checked in the test above.
  expectFourCamerasAsFastAsOne({}, "stop-and-go", false);
}

TEST(RingAcquisition, FourCamerasTakeTheTimeOfOneContinuous) {
  expectFourCamerasAsFastAsOne({{"mode = \"stop\"", "mode = \"continuous\""}}, "continuous", true);
}

// Retries work per camera in a ring scan too: a swapped camera's lost frame at the end
// of sweep 1 (its low set) sweeps it again, every camera skipping the frames
// it has; a second loss fails the scan naming the camera's own set.
TEST(RingAcquisition, ALostFrameOfASwappedCameraIsSweptAgain) {
  TempDir dir;
  Scan scan(ringBoard(dir, {{"mode = \"stop\"", "mode = \"continuous\""}}));
  ASSERT_FALSE(scan.plan.swapped.empty());
  const std::string swapped = *scan.plan.swapped.begin();
  const int n = scan.plan.ring->frames;
  PhaseSink phase(scan.plan, {});
  Acquisition acquisition(scan.board);
  const ScanReport report =
      acquisition.run(scan.options, scan.plan, phase, [&](const ScanProgress& p) {
        // The sweep's last frame: nothing follows it, so its loss is a timeout.
        if (p.frames_done == n - 1) scan.head().dropFrames(swapped, 1);
      });
  EXPECT_EQ(report.retries, 1);
  EXPECT_EQ(report.trigger_jitter.count, static_cast<std::uint64_t>(3 * n)) << "sweep 1 twice";
  for (const std::string& camera : kCameras)
    EXPECT_EQ(phase.folded(camera), 2 * n) << camera;
  const CameraTruth truth = truthOf(scan.head(), swapped, report);
  const CameraPhaseError e = compareWithHead(scan.head(), swapped, phase.finalize(swapped), truth);
  EXPECT_LT(e.absolute.rms, 0.01);  // the tolerances of expectPhaseOfHead
  EXPECT_LT(e.absolute.worst, 0.1);

  TempDir again_dir;
  Scan again(ringBoard(again_dir));
  PhaseSink again_phase(again.plan, {});
  Acquisition again_acquisition(again.board);
  // The swapped camera's set in the motion set that runs first.
  const FringeSet lost_set =
      again.plan.setOf(swapped, again_acquisition.nextSetOrder(again.options, again.plan)[0]);
  try {
    again_acquisition.run(again.options, again.plan, again_phase, [&](const ScanProgress& p) {
      if (p.frames_done == 5) again.head().dropFrames(swapped, 2);
    });
    ADD_FAILURE() << "the scan should fail";
  } catch (const ScanError& error) {
    EXPECT_NE(std::string(error.what())
                  .find("camera '" + swapped + "': no frame 5 of the " +
                        std::string(toString(lost_set)) + " set"),
              std::string::npos)
        << error.what();
  }
  EXPECT_FALSE(again.head().lightOn());
  EXPECT_FALSE(again.head().stage().enabled());
}

}  // namespace
// A camera's calibration scans use its own sets of the ring, as a plan of
// their own: the same positions, each set in its own role.
TEST(RingAcquisition, ACamerasSetsAreAPlanOfTheirOwn) {
  TempDir dir;
  const Scan scan(ringBoard(dir));
  for (const std::string& camera : kCameras) {
    const ScanPlan own = cameraSetsPlan(scan.plan, camera);
    EXPECT_FALSE(own.ring);
    for (const FringeSet id : kFringeSets) {
      EXPECT_EQ(own.set(id).positions, scan.plan.motionSetOf(camera, id).positions) << camera;
      EXPECT_EQ(own.setOf("main", id), id);
      EXPECT_EQ(own.anglesDeg(id), scan.plan.anglesDeg(camera, id)) << camera;
    }
  }
  EXPECT_THROW(cameraSetsPlan(scan.plan, "cam45"), std::invalid_argument);
  EXPECT_THROW(cameraSetsPlan(cameraSetsPlan(scan.plan, "main"), "main"), std::invalid_argument);
}

// The ring plan on a homed head, both modes: no homing, no seek of home, the
// sweeps alternating, and each scan within 1.2 times the shortest the stage's
// limits allow for a continuous scan of the plan (stop-and-go adds its
// settles and its stops, so it is printed, not bounded).
TEST(RingAcquisition, AScanOnAHomedHeadIsNearTheStagesLimit) {
  for (const char* mode : {"stop", "continuous"}) {
    TempDir dir;
    Scan scan(ringBoard(dir, {{"mode = \"stop\"", std::string("mode = \"") + mode + "\""}}));
    const auto shortest = shortestScan(scan.options, scan.plan, scan.board.profile().stage);
    Acquisition acquisition(scan.board);
    const std::vector<ScanReport> reports = test::scansOnAHomedHead(
        acquisition, scan.options, scan.plan, shortest, 3, std::string("ring ") + mode);
    if (std::string(mode) == "continuous") {
      for (std::size_t i = 1; i < reports.size(); ++i)
        EXPECT_LE(test::seconds(reports[i].duration) / test::seconds(shortest), 1.2) << i;
    }
  }
}

}  // namespace cylscan::firmware
