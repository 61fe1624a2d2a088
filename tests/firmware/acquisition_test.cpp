// SPDX-License-Identifier: Apache-2.0
// The acquisition loop on the virtual head, driven through the board's driver
// interfaces like hardware: the phase it streams is the head's geometry, the
// bundle it saves gives the same phase offline, continuous mode agrees with
// stop-and-go, and every fault ends in a clear error with the stage disabled
// and the light off.
#include "firmware/acquisition.hpp"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "algo/phase_engine.hpp"
#include "drivers/board.hpp"
#include "drivers/sim/virtual_head.hpp"
#include "firmware/bundle_sink.hpp"
#include "firmware/phase_sink.hpp"
#include "firmware/scan_plan.hpp"
#include "tests/support/small_board.hpp"
#include "tests/support/temp_dir.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;
using test_support::smallBoard;
using test_support::TempDir;
constexpr double kPi = std::numbers::pi;

struct Scan {
  drivers::Board board;
  ScanOptions options;
  ScanPlan plan;
  explicit Scan(const fs::path& dir)
      : board(drivers::Board::open(dir)),
        options(scanOptionsFrom(board.profile())),
        plan(planScan(options, board.profile().stage)) {}
  sim::VirtualHead& head() { return *board.virtualHead(); }
};

// RMS and worst difference between the measured absolute phase of the high
// set and the head's geometry (Φ = 2π·β/θh at the first frame's angle).
struct PhaseError {
  double rms = 0, worst = 0;
  int pixels = 0;
};

PhaseError compareWithHead(sim::VirtualHead& head, const cv::Mat& absolute, double start_deg) {
  const auto geometry = head.pixelGeometry("main");
  PhaseError e;
  double sum = 0;
  for (int v = 0; v < absolute.rows; ++v) {
    for (int u = 0; u < absolute.cols; ++u) {
      const float phi = absolute.at<float>(v, u);
      if (!std::isfinite(phi)) continue;
      if (!(geometry->flags.at<std::uint8_t>(v, u) & sim::PixelGeometry::kLit)) continue;
      const cv::Vec3d p = geometry->points.at<cv::Vec3d>(v, u);
      const double beta = head.projector().wallAngleDeg(sim::Vec3(p[0], p[1], p[2]), start_deg);
      const double truth = 2 * kPi * beta / head.projector().params().theta_high_deg;
      // Φ is absolute within one equivalent wavelength (λeq = 9 high periods).
      const double eq = 2 * kPi * 9;
      const double d = phi - truth - eq * std::round((phi - truth) / eq);
      sum += d * d;
      e.worst = std::max(e.worst, std::abs(d));
      ++e.pixels;
    }
  }
  e.rms = e.pixels ? std::sqrt(sum / e.pixels) : 0;
  return e;
}

TEST(Acquisition, StopAndGoStreamsTheHeadsPhaseAndSavesTheSameBundle) {
  TempDir dir;
  Scan scan(smallBoard(dir, test_support::kWallScene));
  algo::PhaseOptions phase_options;
  PhaseSink phase(scan.plan, phase_options);
  BundleSink bundle(dir.path() / "bundle", scan.plan, {"main"}, nlohmann::json::object());
  TeeSink sinks;
  sinks.add(phase);
  sinks.add(bundle);
  Acquisition acquisition(scan.board);
  const ScanReport report = acquisition.run(scan.options, scan.plan, sinks);
  bundle.commit();

  EXPECT_EQ(report.frames, 50);
  EXPECT_EQ(report.retries, 0);
  EXPECT_TRUE(report.homed);
  ASSERT_TRUE(report.step_check.has_value());
  EXPECT_LE(std::abs(report.step_check->lostSteps()), 2);
  // The executed angles are the plan's step positions, and where the head's
  // stage was (its own count) at the end of the last frame.
  EXPECT_EQ(report.high_deg, scan.plan.anglesDeg(FringeSet::High));
  EXPECT_EQ(report.low_deg, scan.plan.anglesDeg(FringeSet::Low));
  EXPECT_FALSE(scan.head().lightOn());
  EXPECT_FALSE(scan.head().stage().enabled());

  // The streamed phase is the head's geometry (noise ≈ 2 mrad; an order
  // error would be 2π).
  const algo::PhaseMaps maps = phase.finalize("main");
  const PhaseError e = compareWithHead(scan.head(), maps.absolute, report.high_deg.front());
  std::cout << "[scan] stop-and-go: phase vs head rms " << e.rms << " worst " << e.worst << " over "
            << e.pixels << " px, " << report.duration.count() / 1e9 << " s of board time\n";
  EXPECT_GT(e.pixels, 160 * 128 * 8 / 10);
  EXPECT_LT(e.rms, 0.01);
  EXPECT_LT(e.worst, 0.1);

  // The saved bundle gives the same phase, bit for bit, offline.
  const formats::CaptureBundleReader reader(dir.path() / "bundle");
  EXPECT_EQ(reader.info().high.stage_deg, report.high_deg);
  algo::PhaseEngine offline(
      reader.frameSize("main"), {reader.info().high.period_deg, reader.info().high.stage_deg},
      {reader.info().low.period_deg, reader.info().low.stage_deg}, phase_options);
  for (const auto set : kFringeSets) {
    for (int k = 0; k < reader.frameCount(set); ++k) {
      offline.fold(set == FringeSet::High ? FringeSet::High : FringeSet::Low, k,
                   reader.readFrame("main", set, k));
    }
  }
  const algo::PhaseMaps again = offline.finalize();
  EXPECT_EQ(cv::norm(maps.invalid, again.invalid, cv::NORM_INF), 0);
  cv::Mat a = maps.absolute.clone(), b = again.absolute.clone();
  a.setTo(0, maps.invalid != 0);
  b.setTo(0, again.invalid != 0);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0);
}

// A cylinder whose low half is misaligned by Δ gives the low set a phase
// offset of 2π·Δ/θl, which moves every order residual by R times that (about
// 10 rad per degree). The engine finds the residuals' centre and unwraps
// about it: the same pixels stay valid, the phase is still the head's, and the
// reported centre moves by 9·2π·Δ/θl. (Before, a residual centred beyond the
// fixed π/2 bound lost the whole surface.)
TEST(Acquisition, AMisalignedLowHalfIsMeasuredAndUnwrappedAbout) {
  struct Run {
    double valid = 0;
    double centre = 0;
    PhaseError error;
  };
  const auto scanWith = [](double low_half_offset_deg) {
    TempDir dir;
    const fs::path board = smallBoard(dir, test_support::kWallScene);
    std::ifstream in(board / "board.toml");
    std::stringstream text;
    text << in.rdbuf();
    std::string toml = text.str();
    const std::string section = "[sim.head.projector]\n";
    toml.replace(toml.find(section), section.size(),
                 section + "low_half_offset_deg = " + std::to_string(low_half_offset_deg) + "\n");
    dir.write("board.toml", toml);
    Scan scan(board);
    PhaseSink phase(scan.plan, algo::PhaseOptions{});
    Acquisition acquisition(scan.board);
    const ScanReport report = acquisition.run(scan.options, scan.plan, phase);
    const algo::PhaseMaps maps = phase.finalize("main");
    Run run;
    run.valid = maps.valid_fraction;
    run.centre = maps.order_residual.centre_rad;
    run.error = compareWithHead(scan.head(), maps.absolute, report.high_deg.front());
    return run;
  };
  const Run aligned = scanWith(0.0);
  ASSERT_GT(aligned.valid, 0.8);
  double sign = 0;
  // 0.15° moves the residuals by 1.5 rad: beyond the old fixed bound of π/2.
  for (double delta : {0.05, 0.15, -0.1}) {
    const Run run = scanWith(delta);
    const double expected = 9 * 2 * kPi * delta / 5.625;
    const double moved = std::remainder(run.centre - aligned.centre, 2 * kPi);
    if (sign == 0) sign = moved > 0 ? 1 : -1;
    // The centre is a mean over thousands of pixels (σ ≈ 0.01 rad): 0.05 rad
    // leaves room for the head's other small errors, which Δ does not change.
    EXPECT_NEAR(moved, sign * expected, 0.05) << delta;
    // Edge pixels whose residual lies near the bound may change sides: 0.5 %.
    EXPECT_NEAR(run.valid, aligned.valid, 0.005) << delta;
    // |9·2π·Δ/θl| < π: the centre needs no whole turn, so the orders are the
    // head's own and Φ is its geometry, as for the aligned cylinder.
    EXPECT_LT(run.error.rms, 0.01) << delta;
    EXPECT_LT(run.error.worst, 0.1) << delta;
  }
}

TEST(Acquisition, ContinuousModeGivesTheSamePhaseInFewerSeconds) {
  TempDir dir;
  Scan stop(smallBoard(dir, test_support::kWallScene));
  PhaseSink stop_phase(stop.plan, {});
  Acquisition stop_acquisition(stop.board);
  const ScanReport stop_report = stop_acquisition.run(stop.options, stop.plan, stop_phase);

  Scan sweep(
      smallBoard(dir, test_support::kWallScene, {{"mode = \"stop\"", "mode = \"continuous\""}}));
  ASSERT_EQ(sweep.options.mode, firmware::ScanMode::Continuous);
  PhaseSink sweep_phase(sweep.plan, {});
  Acquisition sweep_acquisition(sweep.board);
  const ScanReport report = sweep_acquisition.run(sweep.options, sweep.plan, sweep_phase);
  EXPECT_EQ(report.frames, 50);
  EXPECT_EQ(report.trigger_jitter.count, 50u);

  const algo::PhaseMaps a = stop_phase.finalize("main");
  const algo::PhaseMaps b = sweep_phase.finalize("main");
  const PhaseError e = compareWithHead(sweep.head(), b.absolute, report.high_deg.front());
  std::cout << "[scan] continuous: phase vs head rms " << e.rms << " worst " << e.worst << "; "
            << report.duration.count() / 1e9 << " s vs " << stop_report.duration.count() / 1e9
            << " s stop-and-go (board time)\n";
  EXPECT_LT(e.rms, 0.01);
  EXPECT_LT(e.worst, 0.1);
  // Board (virtual) time, deterministic: a set costs N frame periods instead
  // of N moves and settles, so continuous is faster whatever the machine.
  EXPECT_LT(report.duration, stop_report.duration);
  for (int set = 0; set < 2; ++set) {
    std::cout << "[scan] set " << set << ": " << report.set_duration[set].count() / 1e9
              << " s continuous, " << stop_report.set_duration[set].count() / 1e9
              << " s stop-and-go\n";
    EXPECT_LT(report.set_duration[set], stop_report.set_duration[set]);
  }
  (void)a;
}

// A stop-and-go scan of the small board with `replace`d keys: its report
// and the main camera's phase maps.
struct StreamedScan {
  ScanReport report;
  algo::PhaseMaps maps;
  PhaseError error;
};
StreamedScan scanWith(const std::vector<std::pair<std::string, std::string>>& replace) {
  TempDir dir;
  Scan scan(smallBoard(dir, test_support::kWallScene, replace));
  PhaseSink phase(scan.plan, {});
  Acquisition acquisition(scan.board);
  StreamedScan out;
  out.report = acquisition.run(scan.options, scan.plan, phase);
  out.maps = phase.finalize("main");
  out.error = compareWithHead(scan.head(), out.maps.absolute, out.report.high_deg.front());
  return out;
}

// The main camera's [[camera]] keys from `trigger` on, replaced.
const std::string kMainTrigger =
    "trigger = \"gpio\"\ntrigger_line = \"trigger\"\ntrigger_pulse_us = 10.0\nframe_rate_hz = "
    "30.0\n\n\\[\\[camera\\]\\]\nname = \"aux\"";
std::pair<std::string, std::string> mainCamera(const std::string& keys) {
  return {kMainTrigger, keys + "\nframe_rate_hz = 30.0\n\n[[camera]]\nname = \"aux\""};
}

TEST(Acquisition, AFreeRunningCameraTakesTheFirstFrameExposedAfterTheSettle) {
  // The camera streams at 30 Hz on its own clock and nobody reads it while
  // the stage moves: its sequence jumps between frames, which is no loss.
  const StreamedScan s = scanWith({mainCamera("trigger = \"free\"")});
  EXPECT_EQ(s.report.frames, 50);
  EXPECT_EQ(s.report.retries, 0);
  EXPECT_LT(s.error.rms, 0.01);
  EXPECT_LT(s.error.worst, 0.1);
  EXPECT_GT(s.error.pixels, 160 * 128 * 8 / 10);
}

TEST(Acquisition, ATriggeredStreamGivesTheFrameItsImageLatencyAfterTheTrigger) {
  // The trigger starts an exposure; the link repeats the latest finished one
  // at 30 Hz. The exposure has ended 18.02 ms after the trigger (latency,
  // exposure, readout), so a 20 ms image latency takes exactly its frames:
  // the same exposures, with the same noise, as a camera that delivers one
  // frame per trigger.
  const StreamedScan per_exposure = scanWith({});
  const StreamedScan linked = scanWith(
      {mainCamera("trigger = \"gpio\"\nstream = \"continuous\"\nimage_latency_ms = 20.0")});
  EXPECT_EQ(linked.report.frames, 50);
  EXPECT_EQ(linked.report.retries, 0);
  EXPECT_EQ(linked.report.high_deg, per_exposure.report.high_deg);
  EXPECT_EQ(cv::norm(per_exposure.maps.invalid, linked.maps.invalid, cv::NORM_INF), 0);
  cv::Mat a = per_exposure.maps.absolute.clone(), b = linked.maps.absolute.clone();
  a.setTo(0, per_exposure.maps.invalid != 0);
  b.setTo(0, linked.maps.invalid != 0);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0);
  EXPECT_LT(linked.error.rms, 0.01);
  // Without the latency, the frame stamped after the trigger still shows the
  // exposure before it: each set's frames shifted by one (the first black),
  // a phase far off the head's (noise: a few mrad).
  const StreamedScan early = scanWith({mainCamera("trigger = \"gpio\"\nstream = \"continuous\"")});
  std::cout << "[scan] triggered stream: phase vs head rms " << linked.error.rms
            << " with a 20 ms image latency, " << early.error.rms << " without\n";
  EXPECT_GT(early.error.rms, 10 * linked.error.rms);
  EXPECT_GT(early.error.rms, 0.03);
}

TEST(Acquisition, ACameraThatStreamsCannotSweep) {
  TempDir dir;
  Scan scan(smallBoard(dir, test_support::kWallScene,
                       {{"mode = \"stop\"", "mode = \"continuous\""},
                        mainCamera("trigger = \"gpio\"\nstream = \"continuous\"")}));
  PhaseSink phase(scan.plan, {});
  Acquisition acquisition(scan.board);
  try {
    acquisition.run(scan.options, scan.plan, phase);
    ADD_FAILURE() << "a sweep with a streaming camera ran";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("camera 'main' streams continuously"), std::string::npos)
        << e.what();
  }
}

struct FailedScan {
  std::string message;
  bool light_on = true;
  bool stage_enabled = true;
  bool bundle_committed = true;
};

// Runs a scan on a small board with `fault` injected once 5 frames are in.
template <class Fault>
FailedScan failScan(const std::vector<std::pair<std::string, std::string>>& replace, Fault fault) {
  TempDir dir;
  Scan scan(smallBoard(dir, test_support::kWallScene, replace));
  PhaseSink phase(scan.plan, {});
  BundleSink bundle(dir.path() / "bundle", scan.plan, {"main"}, nlohmann::json::object());
  TeeSink sinks;
  sinks.add(phase);
  sinks.add(bundle);
  Acquisition acquisition(scan.board);
  FailedScan out;
  try {
    acquisition.run(scan.options, scan.plan, sinks, [&](const ScanProgress& p) {
      if (p.frames_done == 5) fault(scan);
    });
    bundle.commit();
    out.message = "(no error)";
  } catch (const ScanError& e) {
    out.message = e.what();
  }
  out.light_on = scan.head().lightOn();
  out.stage_enabled = scan.head().stage().enabled();
  out.bundle_committed = fs::exists(dir.path() / "bundle" / "capture.json");
  return out;
}

void expectSafe(const FailedScan& f) {
  EXPECT_FALSE(f.light_on);
  EXPECT_FALSE(f.stage_enabled);
  EXPECT_FALSE(f.bundle_committed) << "a failed scan must not look complete";
}

TEST(Acquisition, ACameraTimeoutIsRetriedOnce) {
  TempDir dir;
  Scan scan(smallBoard(dir, test_support::kWallScene));
  scan.head().dropFrames("main", 1);
  PhaseSink phase(scan.plan, {});
  Acquisition acquisition(scan.board);
  const ScanReport report = acquisition.run(scan.options, scan.plan, phase);
  EXPECT_EQ(report.retries, 1);
  EXPECT_EQ(report.frames, 50);
  const PhaseError e =
      compareWithHead(scan.head(), phase.finalize("main").absolute, report.high_deg.front());
  EXPECT_LT(e.rms, 0.01);
}

TEST(Acquisition, AContinuousSetIsSweptAgainAfterATimeout) {
  TempDir dir;
  Scan scan(
      smallBoard(dir, test_support::kWallScene, {{"mode = \"stop\"", "mode = \"continuous\""}}));
  scan.options.cameras = {"main", "aux"};
  PhaseSink phase(scan.plan, {});
  Acquisition acquisition(scan.board);
  const ScanReport report =
      acquisition.run(scan.options, scan.plan, phase, [&](const ScanProgress& p) {
        // The set's last frame: nothing follows it, so its loss is a timeout.
        if (p.frames_done == 24) scan.head().dropFrames("aux", 1);
      });
  EXPECT_EQ(report.retries, 1);
  EXPECT_EQ(report.frames, 50);
  EXPECT_EQ(phase.folded("aux"), 50);
  EXPECT_EQ(report.trigger_jitter.count, 75u) << "the high set swept twice";
  const PhaseError e =
      compareWithHead(scan.head(), phase.finalize("main").absolute, report.high_deg.front());
  EXPECT_LT(e.rms, 0.01);
  EXPECT_LT(e.worst, 0.1);
}

TEST(Acquisition, AMissingFrameIsASequenceGap) {
  // In a sweep the next exposure follows within the timeout: a frame the
  // camera lost shows as a jump of its sequence number.
  const FailedScan f = failScan({{"mode = \"stop\"", "mode = \"continuous\""}},
                                [](Scan& s) { s.head().dropFrames("main", 1); });
  EXPECT_NE(f.message.find("camera 'main': frame sequence jumped"), std::string::npos) << f.message;
  EXPECT_NE(f.message.find("a frame was lost"), std::string::npos) << f.message;
  expectSafe(f);
}

TEST(Acquisition, ASecondTimeoutFailsTheScan) {
  const FailedScan f = failScan({}, [](Scan& s) { s.head().dropFrames("main", 2); });
  EXPECT_NE(f.message.find("camera 'main': no frame 5 of the high set"), std::string::npos)
      << f.message;
  EXPECT_NE(f.message.find("twice"), std::string::npos) << f.message;
  expectSafe(f);
}

TEST(Acquisition, AHomeSwitchThatNeverFiresFailsTheScan) {
  // The stage starts 200° away from home and may travel only 90° to find it.
  TempDir dir;
  const fs::path board =
      smallBoard(dir, test_support::kWallScene,
                 {{"home_max_travel_deg = 370.0", "home_max_travel_deg = 90.0"}});
  std::ofstream(board / "board.toml", std::ios::app) << "[sim.head.stage]\ninitial_deg = 200.0\n";
  Scan scan(board);
  PhaseSink phase(scan.plan, {});
  Acquisition acquisition(scan.board);
  try {
    acquisition.run(scan.options, scan.plan, phase);
    ADD_FAILURE() << "the scan should fail";
  } catch (const ScanError& e) {
    EXPECT_NE(std::string(e.what()).find("home switch never fired"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(scan.head().lightOn());
  EXPECT_FALSE(scan.head().stage().enabled());
}

TEST(Acquisition, LostStepsAreCaughtByTheStepCheck) {
  // A driver without a fault output: only the re-seek of home can tell.
  const FailedScan f = failScan({{"fault = \\{ name = \"fault\" \\}\n", ""}},
                                [](Scan& s) { s.head().loseSteps(40); });
  EXPECT_NE(f.message.find("lost"), std::string::npos) << f.message;
  expectSafe(f);
}

TEST(Acquisition, LostStepsRaiseTheDriversFaultInput) {
  // The head's driver raises its fault output when the rotor stalls.
  const FailedScan f = failScan({}, [](Scan& s) { s.head().loseSteps(40); });
  EXPECT_NE(f.message.find("fault"), std::string::npos) << f.message;
  expectSafe(f);
}

TEST(Acquisition, TheStageFaultInputFailsTheScan) {
  TempDir dir;
  Scan scan(smallBoard(dir, test_support::kWallScene));
  PhaseSink phase(scan.plan, {});
  Acquisition acquisition(scan.board);
  try {
    acquisition.run(scan.options, scan.plan, phase, [&](const ScanProgress& p) {
      if (p.frames_done == 5) scan.head().setStageFault(true);
    });
    ADD_FAILURE() << "the scan should fail";
  } catch (const ScanError& e) {
    EXPECT_NE(std::string(e.what()).find("fault"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(scan.head().lightOn());
  EXPECT_FALSE(scan.head().stage().enabled());
}

TEST(Acquisition, AbortStopsTheScanSafely) {
  TempDir dir;
  Scan scan(smallBoard(dir, test_support::kWallScene));
  PhaseSink phase(scan.plan, {});
  Acquisition acquisition(scan.board);
  int seen = 0;
  try {
    acquisition.run(scan.options, scan.plan, phase, [&](const ScanProgress& p) {
      seen = p.frames_done;
      if (p.frames_done == 10) acquisition.abort();
    });
    ADD_FAILURE() << "the scan should be aborted";
  } catch (const ScanError& e) {
    EXPECT_NE(std::string(e.what()).find("aborted"), std::string::npos) << e.what();
  }
  EXPECT_GE(seen, 10);
  EXPECT_LT(seen, 50);
  EXPECT_FALSE(scan.head().lightOn());
  EXPECT_FALSE(scan.head().stage().enabled());
}

// The lateness figures of a report are its own scan's: the first scan homes
// (more edges), the next two run the same plan from home and so time the
// same number of step edges and triggers.
TEST(Acquisition, EachReportTimesTheEdgesOfItsOwnScan) {
  TempDir dir;
  Scan scan(smallBoard(dir, test_support::kWallScene));
  Acquisition acquisition(scan.board);
  std::vector<ScanReport> reports;
  for (int i = 0; i < 3; ++i) {
    PhaseSink phase(scan.plan, {});
    reports.push_back(acquisition.run(scan.options, scan.plan, phase));
  }
  EXPECT_TRUE(reports[0].homed);
  EXPECT_FALSE(reports[1].homed);
  EXPECT_GT(reports[1].step_jitter.count, 0u);
  EXPECT_GT(reports[0].step_jitter.count, reports[1].step_jitter.count);
  EXPECT_EQ(reports[2].step_jitter.count, reports[1].step_jitter.count);
  EXPECT_EQ(reports[2].trigger_jitter.count, reports[1].trigger_jitter.count);
}

// A still is one exposure of each camera where the stage stands: the light as
// asked for it and off afterwards, the stage never moved, a silent camera
// triggered once more and a second silence an error.
TEST(Acquisition, AStillIsOneExposureOfEachCameraWithTheStageAtRest) {
  TempDir dir;
  Scan scan(smallBoard(dir, test_support::kWallScene));
  Acquisition acquisition(scan.board);
  const std::int64_t position = scan.head().stage().position();
  StillOptions options;
  options.cameras = {"main", "aux"};
  options.light = true;
  const std::vector<cv::Mat> lit = acquisition.still(options);
  options.light = false;
  const std::vector<cv::Mat> dark = acquisition.still(options);
  ASSERT_EQ(lit.size(), 2u);
  ASSERT_EQ(dark.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    const auto& camera = scan.board.profile().camera(options.cameras[i]).config;
    EXPECT_EQ(lit[i].cols, camera.width);
    EXPECT_EQ(lit[i].rows, camera.height);
    // The scene's ambient light is 0.03: the projector's light is most of a lit frame.
    EXPECT_GT(cv::mean(lit[i])[0], 3 * cv::mean(dark[i])[0]) << options.cameras[i];
  }
  EXPECT_FALSE(scan.head().lightOn());
  EXPECT_EQ(scan.head().stage().position(), position);
  EXPECT_FALSE(acquisition.outputs().stage_enabled);

  scan.head().dropFrames("aux", 1);
  EXPECT_EQ(acquisition.still(options).size(), 2u);
  scan.head().dropFrames("aux", 2);
  try {
    acquisition.still(options);
    ADD_FAILURE() << "a camera silent twice must fail the still";
  } catch (const ScanError& e) {
    EXPECT_NE(std::string(e.what()).find("camera 'aux'"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(scan.head().lightOn());
}

TEST(ScanPlan, ExactStepPositionsFromTheStartAngles) {
  drivers::StageConfig stage;  // 250 steps per degree
  ScanOptions options;
  options.high_start_deg = 235.98;
  options.low_start_deg = 55.98;
  const ScanPlan plan = planScan(options, stage);
  ASSERT_EQ(plan.high.positions.size(), 25u);
  EXPECT_EQ(plan.high.positions[0], 58995);
  EXPECT_EQ(plan.high.positions[1] - plan.high.positions[0], 50);  // 0.2° = 50 steps
  EXPECT_EQ(plan.low.positions[2] - plan.low.positions[0], 113);   // 2 × 0.225° = 112.5 → 113
  options.frames_high = 2;
  EXPECT_THROW(planScan(options, stage), std::invalid_argument);
  options.frames_high = 25;
  options.period_low_deg = 0;
  EXPECT_THROW(planScan(options, stage), std::invalid_argument);
}

}  // namespace
}  // namespace cylscan::firmware
