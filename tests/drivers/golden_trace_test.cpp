// SPDX-License-Identifier: Apache-2.0
// Golden traces: the executor's edges on the virtual head's output lines
// (line, level, virtual time from the start of the trace) for a short
// trapezoid move, a homing and a short continuous sweep, compared with the
// committed files in tests/drivers/golden/: the number of edges per line and
// their order exactly, their times within kTimeBound.
//
// To regenerate them after an intended change of the plans:
//   CYLSCAN_UPDATE_GOLDEN=1 build/<dir>/tests/drivers_tests --gtest_filter='GoldenTrace.*'
// (the tests then write the files and skip), and review the diff.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>

#include "drivers/rotation_stage.hpp"
#include "drivers_test_support.hpp"

namespace cylscan::drivers {
namespace {

using namespace std::chrono_literals;
using TracedEdge = sim::VirtualHead::TracedEdge;

// The traces are in virtual time, so a run reproduces them to the
// nanosecond. The bound only lets the planning arithmetic change its
// rounding (deadlines are rounded to 1 ns from doubles): 1 µs is 1/5 of the
// 5 µs step pulse and 1/2000 of the shortest step interval in these traces
// (2 ms at 20°/s and 25 steps/°), so a trace within it drives the stage
// identically, while any real change of a profile (another speed, ramp or
// step) moves edges by tens of microseconds or more.
constexpr std::int64_t kTimeBound = 1000;

// A coarse stage (25 steps/°) keeps the files small; the home window's
// edges fall on whole steps (±0.08° = ±2 steps).
sim::HeadConfig goldenHead(double initial_deg) {
  sim::HeadConfig h = test::smallHead(initial_deg);
  h.stage.microsteps = 1;
  h.stage.home_window_deg = 0.16;
  return h;
}

std::filesystem::path goldenFile(const std::string& name) {
  return std::filesystem::path(CYLSCAN_SOURCE_DIR) / "tests/drivers/golden" / (name + ".trace");
}

std::vector<TracedEdge> relative(std::vector<TracedEdge> edges, std::chrono::nanoseconds start) {
  for (TracedEdge& e : edges)
    e.time -= start;
  return edges;
}

void write(const std::string& name, const std::vector<TracedEdge>& edges) {
  std::ofstream out(goldenFile(name));
  out << "# cylscan golden trace '" << name << "' (tests/drivers/golden_trace_test.cpp)\n"
      << "# line level time_ns (virtual, from the start of the trace)\n";
  for (const TracedEdge& e : edges)
    out << e.line << ' ' << (e.active ? 1 : 0) << ' ' << e.time.count() << '\n';
  if (!out) throw std::runtime_error("cannot write " + goldenFile(name).string());
}

std::vector<TracedEdge> read(const std::string& name) {
  std::ifstream in(goldenFile(name));
  if (!in) throw std::runtime_error("no golden trace " + goldenFile(name).string());
  std::vector<TracedEdge> edges;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    TracedEdge e;
    int level = 0;
    std::int64_t t = 0;
    if (!(fields >> e.line >> level >> t)) throw std::runtime_error("bad line: " + line);
    e.active = level != 0;
    e.time = std::chrono::nanoseconds{t};
    edges.push_back(e);
  }
  return edges;
}

void compareWithGolden(const std::string& name, const std::vector<TracedEdge>& actual) {
  const char* update = std::getenv("CYLSCAN_UPDATE_GOLDEN");
  if (update != nullptr && std::string(update) == "1") {
    write(name, actual);
    GTEST_SKIP() << "regenerated " << goldenFile(name);
  }
  const std::vector<TracedEdge> golden = read(name);
  std::map<std::string, int> count_actual, count_golden;
  for (const auto& e : actual)
    ++count_actual[e.line + (e.active ? "+" : "-")];
  for (const auto& e : golden)
    ++count_golden[e.line + (e.active ? "+" : "-")];
  EXPECT_EQ(count_actual, count_golden) << name << ": edges per line";
  ASSERT_EQ(actual.size(), golden.size()) << name;
  for (std::size_t i = 0; i < actual.size(); ++i) {
    ASSERT_EQ(actual[i].line, golden[i].line) << name << " edge " << i;
    ASSERT_EQ(actual[i].active, golden[i].active) << name << " edge " << i;
    ASSERT_LE(std::abs((actual[i].time - golden[i].time).count()), kTimeBound)
        << name << " edge " << i << " (" << actual[i].line << ")";
  }
}

struct GoldenRig {
  explicit GoldenRig(double initial_deg)
      : head(goldenHead(initial_deg), test::planeScene()),
        stage(test::stageFor(head.config()), head.clock(), head.gpio(), test::stageSpecs(true)) {}
  std::vector<TracedEdge> trace() { return relative(head.takeTrace(), start); }
  void startTrace() {
    start = head.clock().now();
    head.startTrace();
  }
  sim::VirtualHead head;
  RotationStage stage;
  std::chrono::nanoseconds start{0};
};

TEST(GoldenTrace, TrapezoidMove) {
  GoldenRig rig(3.0);
  rig.stage.enable();
  rig.startTrace();
  rig.stage.moveBySteps(200);  // 8°: ramps of 62 steps, a cruise at 20°/s
  const auto edges = rig.trace();
  EXPECT_EQ(rig.head.stage().counters().lost, 0u);
  compareWithGolden("trapezoid_move", edges);
}

TEST(GoldenTrace, Homing) {
  GoldenRig rig(2.0);
  rig.startTrace();
  rig.stage.enable();
  rig.stage.home();
  const auto edges = rig.trace();
  EXPECT_EQ(rig.stage.position(), rig.head.stage().position());
  EXPECT_EQ(rig.head.stage().counters().lost, 0u);
  compareWithGolden("homing", edges);
}

TEST(GoldenTrace, ContinuousSweep) {
  GoldenRig rig(3.0);
  auto trigger = rig.head.gpio().requestOutput(test::spec("trigger"), false);
  rig.stage.enable();
  rig.stage.home();
  SweepRequest r;
  r.speed_deg_s = 10;  // 250 steps/s
  r.range_steps = 50;
  r.trigger_offsets = {0, 10, 20, 30, 40, 50};
  const PreparedSweep sweep = rig.stage.prepareSweep(100, r);
  rig.startTrace();
  rig.stage.runSweep(sweep, *trigger);
  const auto edges = rig.trace();
  EXPECT_EQ(rig.head.stage().counters().lost, 0u);
  compareWithGolden("continuous_sweep", edges);
}

}  // namespace
}  // namespace cylscan::drivers
