// SPDX-License-Identifier: Apache-2.0
// The acquisition loop on the virtual head, driven through the board's driver
// interfaces like hardware: the phase it streams is the head's geometry, the
// bundle it saves gives the same phase offline, continuous mode agrees with
// stop-and-go, and every fault ends in a clear error with the stage disabled
// and the light off.
#include "firmware/acquisition.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "algo/phase_engine.hpp"
#include "drivers/board.hpp"
#include "drivers/sim/virtual_head.hpp"
#include "firmware/bundle_sink.hpp"
#include "firmware/phase_sink.hpp"
#include "firmware/scan_plan.hpp"
#include "tests/firmware/homed_scan.hpp"
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
  double mean = 0;           // a bias common to the whole map
  double per_row = 0;        // its least-squares slope along the rows (rad per row)
  double rms_about_fit = 0;  // what neither explains
  int wrong = 0;             // valid pixels more than π from the head's phase: a wrong order
};

PhaseError compareWithHead(sim::VirtualHead& head, const cv::Mat& absolute, double start_deg) {
  const auto geometry = head.pixelGeometry("main");
  PhaseError e;
  double sum = 0, sum_d = 0, sum_v = 0, sum_vv = 0, sum_vd = 0;
  for (int v = 0; v < absolute.rows; ++v) {
    for (int u = 0; u < absolute.cols; ++u) {
      const float phi = absolute.at<float>(v, u);
      if (!std::isfinite(phi)) continue;
      if (!(geometry->flags.at<std::uint8_t>(v, u) & sim::PixelGeometry::kLit)) continue;
      const cv::Vec3d p = geometry->points.at<cv::Vec3d>(v, u);
      const double beta = head.projector().wallAngleDeg(sim::Vec3(p[0], p[1], p[2]), start_deg);
      const double truth = 2 * kPi * beta / head.projector().params().theta_high_deg;
      // Φ is absolute within one equivalent wavelength (λeq = R high periods).
      const double th = head.projector().params().theta_high_deg;
      const double tl = head.projector().params().theta_low_deg;
      const double eq = 2 * kPi * tl / (tl - th);
      const double d = phi - truth - eq * std::round((phi - truth) / eq);
      sum += d * d;
      sum_d += d;
      sum_v += v;
      sum_vv += static_cast<double>(v) * v;
      sum_vd += v * d;
      e.worst = std::max(e.worst, std::abs(d));
      if (std::abs(d) > kPi) ++e.wrong;
      ++e.pixels;
    }
  }
  if (e.pixels == 0) return e;
  const double n = e.pixels;
  e.rms = std::sqrt(sum / n);
  e.mean = sum_d / n;
  const double var_v = sum_vv / n - (sum_v / n) * (sum_v / n);
  e.per_row = var_v > 0 ? (sum_vd / n - (sum_v / n) * e.mean) / var_v : 0;
  // Σ(d − a − b·v)² from the sums: Σd² − n·mean² − b²·n·var(v).
  e.rms_about_fit =
      std::sqrt(std::max(0.0, sum / n - e.mean * e.mean - e.per_row * e.per_row * var_v));
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
      offline.fold(set, k, reader.readFrame("main", set, k));
    }
  }
  const algo::PhaseMaps again = offline.finalize();
  EXPECT_EQ(cv::norm(maps.invalid, again.invalid, cv::NORM_INF), 0);
  cv::Mat a = maps.absolute.clone(), b = again.absolute.clone();
  a.setTo(0, maps.invalid != 0);
  b.setTo(0, again.invalid != 0);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0);
}

// A stop-and-go scan of the small board with `replace`d keys: its report
// and the main camera's phase maps.
struct StreamedScan {
  ScanReport report;
  algo::PhaseMaps maps;
  PhaseError error;
};
// The same with head.toml keys too: `projector` added to [sim.head.projector],
// `sections` appended to the board ([sim.head.stage], [[sim.head.camera]]).
StreamedScan scanHead(const std::string& projector, const std::string& sections,
                      const std::vector<std::pair<std::string, std::string>>& replace = {}) {
  TempDir dir;
  const fs::path board = smallBoard(dir, test_support::kWallScene, replace);
  std::ifstream in(board / "board.toml");
  std::stringstream text;
  text << in.rdbuf();
  std::string toml = text.str();
  const std::string header = "[sim.head.projector]\n";
  toml.replace(toml.find(header), header.size(), header + projector);
  dir.write("board.toml", toml + sections);
  Scan scan(board);
  PhaseSink phase(scan.plan, {});
  Acquisition acquisition(scan.board);
  StreamedScan out;
  out.report = acquisition.run(scan.options, scan.plan, phase);
  out.maps = phase.finalize("main");
  out.error = compareWithHead(scan.head(), out.maps.absolute, out.report.high_deg.front());
  return out;
}

StreamedScan scanWith(const std::vector<std::pair<std::string, std::string>>& replace) {
  return scanHead("", "", replace);
}

// A cylinder whose low half is misaligned by Δ gives the low set a phase
// offset of 2π·Δ/θl, which moves every order residual by R times that (about
// 10 rad per degree). The engine finds the residuals' centre and unwraps
// about it: the same pixels stay valid, the phase is still the head's, and the
// reported centre moves by 9·2π·Δ/θl. (Before, a residual centred beyond the
// fixed π/2 bound lost the whole surface.)
TEST(Acquisition, AMisalignedLowHalfIsMeasuredAndUnwrappedAbout) {
  const auto scanOffset = [](double low_half_offset_deg) {
    return scanHead("low_half_offset_deg = " + std::to_string(low_half_offset_deg) + "\n", "");
  };
  const StreamedScan aligned = scanOffset(0.0);
  ASSERT_GT(aligned.maps.valid_fraction, 0.8);
  double sign = 0;
  // 0.15° moves the residuals by 1.5 rad: beyond the old fixed bound of π/2.
  for (double delta : {0.05, 0.15, -0.1}) {
    const StreamedScan run = scanOffset(delta);
    const double expected = 9 * 2 * kPi * delta / 5.625;
    const double moved = std::remainder(
        run.maps.order_residual.centre_rad - aligned.maps.order_residual.centre_rad, 2 * kPi);
    if (sign == 0) sign = moved > 0 ? 1 : -1;
    // The centre is a mean over thousands of pixels (σ ≈ 0.01 rad): 0.05 rad
    // leaves room for the head's other small errors, which Δ does not change.
    EXPECT_NEAR(moved, sign * expected, 0.05) << delta;
    // Edge pixels whose residual lies near the bound may change sides: 0.5 %.
    EXPECT_NEAR(run.maps.valid_fraction, aligned.maps.valid_fraction, 0.005) << delta;
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
  // From home the low set's window (56°) is nearer than the high set's (236°),
  // so the low set runs first.
  EXPECT_NE(f.message.find("camera 'main': no frame 5 of the low set"), std::string::npos)
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
  // A driver without a fault output: only the home edge can tell. The steps
  // are lost in the first set; the travel to the second passes home.
  const FailedScan f = failScan({{"fault = \\{ name = \"fault\" \\}\n", ""}},
                                [](Scan& s) { s.head().loseSteps(40); });
  EXPECT_NE(f.message.find("lost 40 steps"), std::string::npos) << f.message;
  EXPECT_NE(f.message.find("as the stage passes it"), std::string::npos) << f.message;
  expectSafe(f);
}

// A homed head neither homes nor seeks home again: the travel between the
// sets passes the home edge, which checks the step count; the sets alternate,
// so that each scan starts where the last ended; a continuous scan takes at
// most 1.2 times the shortest that the stage's limits allow, and its phase is
// still the head's.
TEST(Acquisition, AScanOnAHomedHeadIsNearTheStagesLimit) {
  TempDir dir;
  Scan scan(
      smallBoard(dir, test_support::kWallScene, {{"mode = \"stop\"", "mode = \"continuous\""}}));
  Acquisition acquisition(scan.board);
  const drivers::StageConfig& stage = scan.board.profile().stage;
  const auto shortest = shortestScan(scan.options, scan.plan, stage);
  const auto enable_settle = std::chrono::nanoseconds{std::llround(stage.enable_settle_ms * 1e6)};
  const std::vector<ScanReport> reports =
      test::scansOnAHomedHead(acquisition, scan.options, scan.plan, shortest, 4, "sim continuous");
  for (std::size_t i = 1; i < reports.size(); ++i) {
    EXPECT_EQ(reports[i].split.homing, enable_settle) << i;  // only the driver's enable settle
    EXPECT_LE(test::seconds(reports[i].duration) / test::seconds(shortest), 1.2) << i;
  }
  // The phase of a scan on the homed head is still the head's.
  PhaseSink phase(scan.plan, {});
  const ScanReport r = acquisition.run(scan.options, scan.plan, phase);
  const PhaseError e =
      compareWithHead(scan.head(), phase.finalize("main").absolute, r.high_deg.front());
  std::printf("[ scan     ] phase rms %.4f rad after %zu scans\n", e.rms, reports.size());
  EXPECT_LT(e.rms, 0.003);  // the sensor noise gives 1.7 mrad
}

// Stop-and-go on a homed head: the same route, the frames' stops and settles
// added (printed for docs/performance.md, bounded only by the route: no
// homing, no seek of home, the sets alternating).
TEST(Acquisition, AStopAndGoScanOnAHomedHeadTakesTheSameRoute) {
  TempDir dir;
  Scan scan(smallBoard(dir, test_support::kWallScene));
  Acquisition acquisition(scan.board);
  const auto shortest = shortestScan(scan.options, scan.plan, scan.board.profile().stage);
  for (const ScanReport& r :
       test::scansOnAHomedHead(acquisition, scan.options, scan.plan, shortest, 3, "sim stop"))
    std::printf("[ scan     ] stop-and-go settling %.3f s\n", test::seconds(r.split.settling));
}

// A section of a board.toml: its header line and every line up to the next
// table header.
std::string tomlSection(const std::string& text, const std::string& header) {
  const auto at = text.find("\n" + header + "\n");
  if (at == std::string::npos) throw std::runtime_error("no " + header);
  auto end = text.find("\n[", at + 1);
  if (end == std::string::npos) end = text.size();
  return text.substr(at + 1, end - at);
}

std::string readText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// Every hardware profile's stage and scan sections, verbatim, on the small
// virtual head (its cameras are board/sim's: 30 Hz, 10 ms, as rpi4's and
// rpi5's), the head's stage geared as the profile's: a homed head scans
// within 1.2 times the shortest continuous scan that the profile's limits
// allow, and stop-and-go keeps to the same route. The home window of the
// head is ±0.1°, so a profile with home_offset_deg = 0 puts its zero 0.1°
// from the head's; the time does not depend on it.
class ProfileScanTime : public ::testing::TestWithParam<const char*> {};

TEST_P(ProfileScanTime, AScanOnAHomedHeadIsNearTheStagesLimit) {
  const std::string profile = GetParam();
  const std::string board_toml =
      readText(fs::path(CYLSCAN_SOURCE_DIR) / "board" / profile / "board.toml");
  const std::string stage = tomlSection(board_toml, "[stage]");
  std::smatch m;
  int gearing[3] = {};
  const char* keys[3] = {"full_steps_per_rev", "microsteps", "gear_ratio"};
  for (int k = 0; k < 3; ++k) {
    ASSERT_TRUE(std::regex_search(stage, m, std::regex(std::string(keys[k]) + R"( = (\d+))")))
        << keys[k];
    gearing[k] = std::stoi(m[1]);
  }
  for (const char* mode : {"continuous", "stop"}) {
    TempDir dir;
    smallBoard(dir, test_support::kWallScene);
    std::string text = readText(dir.path() / "board.toml");
    const std::string sim_stage = tomlSection(text, "[stage]");
    text.replace(text.find(sim_stage), sim_stage.size(), stage);
    const std::string sim_scan = tomlSection(text, "[scan]");
    std::string scan_section = tomlSection(board_toml, "[scan]");
    scan_section = std::regex_replace(scan_section, std::regex(R"(mode = "\w+")"),
                                      std::string("mode = \"") + mode + "\"");
    text.replace(text.find(sim_scan), sim_scan.size(), scan_section);
    text += "[sim.head.stage]\nfull_steps_per_rev = " + std::to_string(gearing[0]) +
            "\nmicrosteps = " + std::to_string(gearing[1]) +
            "\ngear_ratio = " + std::to_string(gearing[2]) + ".0\n";
    dir.write("board.toml", text);
    Scan scan(dir.path());
    Acquisition acquisition(scan.board);
    const auto shortest = shortestScan(scan.options, scan.plan, scan.board.profile().stage);
    const std::vector<ScanReport> reports = test::scansOnAHomedHead(
        acquisition, scan.options, scan.plan, shortest, 3, profile + " " + mode);
    if (std::string(mode) == "continuous") {
      for (std::size_t i = 1; i < reports.size(); ++i)
        EXPECT_LE(test::seconds(reports[i].duration) / test::seconds(shortest), 1.2) << i;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Profiles, ProfileScanTime,
                         ::testing::Values("rpi4", "rpi5", "qemu-virt", "generic-arm64"),
                         [](const ::testing::TestParamInfo<const char*>& profile) {
                           std::string name = profile.param;
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

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
// (more edges); the next ones alternate the order of the sets, so the second
// and the fourth run the same way and time the same number of step edges and
// triggers.
TEST(Acquisition, EachReportTimesTheEdgesOfItsOwnScan) {
  TempDir dir;
  Scan scan(smallBoard(dir, test_support::kWallScene));
  Acquisition acquisition(scan.board);
  std::vector<ScanReport> reports;
  for (int i = 0; i < 4; ++i) {
    PhaseSink phase(scan.plan, {});
    reports.push_back(acquisition.run(scan.options, scan.plan, phase));
  }
  EXPECT_TRUE(reports[0].homed);
  EXPECT_FALSE(reports[1].homed);
  EXPECT_GT(reports[1].step_jitter.count, 0u);
  EXPECT_GT(reports[0].step_jitter.count, reports[1].step_jitter.count);
  EXPECT_EQ(reports[3].first_set, reports[1].first_set);
  EXPECT_EQ(reports[3].step_jitter.count, reports[1].step_jitter.count);
  EXPECT_EQ(reports[3].trigger_jitter.count, reports[1].trigger_jitter.count);
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

namespace cylscan::firmware {
namespace {

// ---- an imperfect head: each imperfection swept ---------------------------------
//
// Each test scans the small wall on heads that differ in one imperfection
// (head.toml keys in the board's [sim] section) and shows that the firmware
// compensates it, or that what it leaves is a reproducible bias (which the
// quasi-calibration, fitted on the same head, absorbs) or a reported figure:
// never a wrong fringe order.

// The two cameras with `main_keys` for main (the others are CameraParams').
std::string cameras(const std::string& main_keys) {
  return "[[sim.head.camera]]\nname = \"main\"\n" + main_keys +
         "\n[[sim.head.camera]]\nname = \"aux\"\nposition_mm = [270.0, 1.5, -3.0]\n"
         "look_at_mm = [0.0, 0.0, 580.0]\n";
}

void print(const std::string& what, const StreamedScan& s) {
  std::cout << "[head] " << what << ": valid " << s.maps.valid_fraction << ", phase vs head rms "
            << s.error.rms << " mean " << s.error.mean << " per row " << s.error.per_row
            << " about that " << s.error.rms_about_fit << ", wrong " << s.error.wrong << ", centre "
            << s.maps.order_residual.centre_rad << " spread " << s.maps.order_residual.spread_rad
            << "\n";
}

// Gamma bends the sinusoid into harmonics, which an N-step fit rejects up to
// order N − 2: at the board's N = 25 the phase keeps the linear camera's
// accuracy (the noise, 1.7 mrad). At N = 3 and 4 they are an error the
// validity rule must bound (docs/validation.md).
TEST(ImperfectHead, CameraGammaIsRejectedByTheNStepFit) {
  const StreamedScan linear = scanHead("", cameras(""));
  print("gamma 1", linear);
  for (double gamma : {0.7, 0.45}) {
    const StreamedScan s = scanHead("", cameras("response_gamma = " + std::to_string(gamma)));
    print("gamma " + std::to_string(gamma), s);
    EXPECT_EQ(s.error.wrong, 0) << gamma;
    EXPECT_GT(s.maps.valid_fraction, linear.maps.valid_fraction - 0.01) << gamma;
    EXPECT_LT(s.error.rms, 0.01) << gamma;
  }
}

// The LED's output falls as it warms: each set's frames see a slowly falling
// intensity, which the fit reads as a small phase error (a ramp is not
// orthogonal to the sine terms). It grows with the drop and stays far below
// an order: 15 % over a 10 s time constant gave 4 mrad.
TEST(ImperfectHead, LedWarmUpGivesASmallPhaseErrorNeverAWrongOrder) {
  double steady_rms = 0;
  for (double drop : {0.0, 0.05, 0.15}) {
    const StreamedScan s = scanHead(
        "source_warmup_drop = " + std::to_string(drop) + "\nsource_warmup_tau_s = 10.0\n", "");
    print("warm-up drop " + std::to_string(drop), s);
    EXPECT_EQ(s.error.wrong, 0) << drop;
    EXPECT_GT(s.maps.valid_fraction, 0.99) << drop;
    EXPECT_LT(s.error.rms, 0.01) << drop;
    if (drop == 0.0) steady_rms = s.error.rms;
    if (drop == 0.15) {
      EXPECT_GT(s.error.rms, steady_rms + 0.001) << "the drift is not modelled";
    }
  }
}

// A home switch that trips a little early or late moves the firmware's zero:
// both sets shift alike, so the orders and the residual centre do not move and
// the phase takes one common bias (2π·δ/θh). The step check meets the edge
// again (on the way, or by seeking it at the end) and reports the difference
// as lost or gained steps; beyond the
// board's step_check_tolerance_steps the scan fails, naming the home edge.
TEST(ImperfectHead, HomingErrorIsACommonBiasOrAReportedStepCheck) {
  const StreamedScan exact = scanHead("", "");
  for (double sigma : {0.005, 0.01}) {
    const StreamedScan s =
        scanHead("", "[sim.head.stage]\nhome_repeatability_deg = " + std::to_string(sigma) + "\n");
    print("home repeatability " + std::to_string(sigma), s);
    ASSERT_TRUE(s.report.step_check);
    EXPECT_LE(std::abs(s.report.step_check->lostSteps()), 2) << sigma;
    EXPECT_EQ(s.error.wrong, 0) << sigma;
    EXPECT_LT(s.error.rms_about_fit, 0.003) << sigma;  // noise: 1.7 mrad
    EXPECT_LT(std::abs(s.error.mean), 2 * kPi * 4 * sigma / 5.0) << sigma;
    EXPECT_NEAR(s.maps.order_residual.centre_rad, exact.maps.order_residual.centre_rad, 0.01);
  }
  // 0.02° is five steps of this stage: past the tolerance of 2 on this seed.
  try {
    const StreamedScan s = scanHead("", "[sim.head.stage]\nhome_repeatability_deg = 0.02\n");
    ASSERT_TRUE(s.report.step_check);
    EXPECT_LE(std::abs(s.report.step_check->lostSteps()), 2);
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("the home edge is at step"), std::string::npos)
        << e.what();
  }
}

// Play in the gear train: the stage lags the motor by the backlash after a
// reversal. Every frame of both sets is approached forward after homing, so
// the lag is one constant: a common bias of about 2π·b/θh, the same on every
// scan (the quasi-calibration absorbs it), with no order lost and no step
// check error (the switch is approached from the same side each time).
TEST(ImperfectHead, BacklashIsOneConstantBias) {
  for (double backlash : {0.02, 0.05}) {
    const StreamedScan s =
        scanHead("", "[sim.head.stage]\nbacklash_deg = " + std::to_string(backlash) + "\n");
    print("backlash " + std::to_string(backlash), s);
    ASSERT_TRUE(s.report.step_check);
    EXPECT_EQ(s.report.step_check->lostSteps(), 0) << backlash;
    EXPECT_EQ(s.error.wrong, 0) << backlash;
    EXPECT_GT(s.maps.valid_fraction, 0.99) << backlash;
    EXPECT_LT(s.error.rms_about_fit, 0.003) << backlash;
    // Measured 1.10 and 1.06 times 2π·b/θh: the homing edge adds a step's play.
    const double expected = 2 * kPi * backlash / 5.0;
    EXPECT_GT(std::abs(s.error.mean), 0.8 * expected) << backlash;
    EXPECT_LT(std::abs(s.error.mean), 1.3 * expected) << backlash;
  }
}

// A rolling shutter under continuous motion: row v is exposed v line times
// later, at a stage angle further on, so the phase takes a bias linear in the
// row, proportional to the line time, the same on every scan at that speed
// (a per-pixel offset the quasi-calibration absorbs). Both sets shift alike
// in their own phase, so the residual centre moves by the high set's shift
// and its spread grows with the range of rows: reported, never a wrong order.
TEST(ImperfectHead, RollingShutterIsABiasLinearInTheRow) {
  const auto sweep = [](double line_us) {
    const StreamedScan s = scanHead("", cameras("line_time_us = " + std::to_string(line_us)),
                                    {{"mode = \"stop\"", "mode = \"continuous\""}});
    print("line time " + std::to_string(line_us), s);
    EXPECT_EQ(s.error.wrong, 0) << line_us;
    EXPECT_GT(s.maps.valid_fraction, 0.99) << line_us;
    EXPECT_LT(s.error.rms_about_fit, 0.003) << line_us;
    return s;
  };
  const StreamedScan global = sweep(0);
  const StreamedScan short_line = sweep(10);
  const StreamedScan long_line = sweep(40);
  EXPECT_LT(std::abs(global.error.per_row), 2e-5);
  EXPECT_GT(std::abs(short_line.error.per_row), 1e-4);
  // Linear in the line time: the exposure sub-samples and the ringing add a few per cent.
  EXPECT_NEAR(long_line.error.per_row / short_line.error.per_row, 4.0, 0.4);
}

// ---- few phase steps: harmonics and gamma that the N-step fit cannot reject -------
//
// At N = 3 the camera's gamma puts a second harmonic into the fringes, which
// the 3-step fit aliases onto the phase; at N = 4 the square wave's third does
// the same. Each set's phase error is a sinusoid of ~0.1 rad, and the order
// residual R·φeq − φh carries them times R and R − 1: a bounded spread of
// ±2.5 rad that never reaches ±π. The projector here is the virtual head's
// own blurred square wave (σ 0.6°: third harmonic 3 % of the fundamental at
// θh), the camera's gamma 0.45 is an uncorrected sRGB-like response, and the
// periods are 5° and 40/7° (R = 8), as in the recordings these goals come from.

struct FewStepScan {
  double coverage = 0;  // valid pixels over those with modulation (neither dark nor saturated)
  double wrong = 0;     // wrong orders over valid pixels
  StreamedScan scan;
};

FewStepScan scanFewSteps(int n, double gamma) {
  constexpr double kRatio = 8;
  const std::string theta_low = std::to_string(5.0 * kRatio / (kRatio - 1));
  const std::string frames = std::to_string(n);
  FewStepScan out;
  out.scan = scanHead("theta_low_deg = " + theta_low + "\nblur_width_deg = 0.6\n",
                      cameras("response_gamma = " + std::to_string(gamma)),
                      {{"frames_high = 25", "frames_high = " + frames},
                       {"frames_low = 25", "frames_low = " + frames},
                       {"period_low_deg = 5.625", "period_low_deg = " + theta_low}});
  const cv::Mat& invalid = out.scan.maps.invalid;
  const int modulated =
      cv::countNonZero((invalid & (algo::kLowModulation | algo::kSaturated)) == 0);
  const int valid = cv::countNonZero(invalid == 0);
  out.coverage = modulated > 0 ? static_cast<double>(valid) / modulated : 0;
  out.wrong = valid > 0 ? static_cast<double>(out.scan.error.wrong) / valid : 1;
  print("N " + frames + ", gamma " + std::to_string(gamma), out.scan);
  std::cout << "[head] coverage " << out.coverage << " of " << modulated << " modulated, wrong "
            << out.wrong << ", bound " << out.scan.maps.order_residual.bound_rad
            << ", decided by neighbours " << out.scan.maps.order_residual.decided_by_neighbours
            << "\n";
  return out;
}

// With the spread's bound alone (π/2 at this spread) N = 3 kept 81 % of the
// modulated pixels, every rejected one with the right order; the residuals
// leave ±π empty, so the bound moves into that gap and keeps them all.
TEST(FewSteps, ThreeStepsWithGammaKeepNineTenthsAndTheirOrders) {
  const FewStepScan s = scanFewSteps(3, 0.45);
  EXPECT_GT(s.scan.maps.order_residual.spread_rad, 1.0);  // the harmonics are there
  EXPECT_GE(s.coverage, 0.90);
  EXPECT_LE(s.wrong, 1e-3);
  EXPECT_LT(s.scan.error.rms, 0.15);  // the harmonics' ~0.1 rad, never an order
}

TEST(FewSteps, FourStepsWithGammaKeepNearlyAll) {
  for (double gamma : {1.0, 0.45}) {
    const FewStepScan s = scanFewSteps(4, gamma);
    EXPECT_GE(s.coverage, 0.98) << gamma;
    EXPECT_LE(s.wrong, 5e-4) << gamma;
  }
}

// From N = 8 the harmonics up to the 6th are rejected by the fit: the bound
// keeps at least every pixel the classic π/2 would.
TEST(FewSteps, EightStepsKeepEverything) {
  for (double gamma : {1.0, 0.45}) {
    const FewStepScan s = scanFewSteps(8, gamma);
    EXPECT_GE(s.scan.maps.order_residual.bound_rad, std::numbers::pi / 2 - 1e-6);
    EXPECT_GE(s.coverage, 0.999) << gamma;
    EXPECT_LE(s.wrong, 1e-4) << gamma;
  }
}

}  // namespace
}  // namespace cylscan::firmware
