// SPDX-License-Identifier: Apache-2.0
// Scans on a homed head: what each keeps to, shared by the tests of every
// plan and profile.
#pragma once

#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "firmware/acquisition.hpp"
#include "firmware/phase_sink.hpp"
#include "firmware/scan_plan.hpp"

namespace cylscan::firmware::test {

inline double seconds(std::chrono::nanoseconds t) {
  return static_cast<double>(t.count()) / 1e9;
}

// A scan after the first on the same head: no homing and no seek of home (its
// step count checked at the home edge that its travel passed), and the other
// set first, so that it starts where the scan before it ended.
inline void expectAHomedHeadsScan(const ScanReport& r, const ScanReport& before) {
  ASSERT_TRUE(r.step_check) << "no step check";
  EXPECT_TRUE(r.step_check->passed) << "the step count was checked by a seek of home";
  EXPECT_EQ(r.step_check->lostSteps(), 0);
  EXPECT_FALSE(r.homed);
  EXPECT_EQ(r.split.step_check.count(), 0) << "time spent seeking home after the sets";
  EXPECT_NE(r.first_set, before.first_set) << "the sets did not alternate";
}

// `count` scans of the plan on one acquisition, the first homing the stage;
// each later one checked by expectAHomedHeadsScan and every one printed with
// its ratio to the shortest continuous scan under `label`.
inline std::vector<ScanReport> scansOnAHomedHead(Acquisition& acquisition,
                                                 const ScanOptions& options, const ScanPlan& plan,
                                                 std::chrono::nanoseconds shortest, int count,
                                                 const std::string& label) {
  std::vector<ScanReport> reports;
  for (int i = 0; i < count; ++i) {
    SCOPED_TRACE(label + " scan " + std::to_string(i));
    PhaseSink phase(plan, {});
    reports.push_back(acquisition.run(options, plan, phase));
    const ScanReport& r = reports.back();
    std::printf("[ homed    ] %s scan %d: %.3f s, %.3f x the shortest (%.3f s), %s set first\n",
                label.c_str(), i, seconds(r.duration), seconds(r.duration) / seconds(shortest),
                seconds(shortest), std::string(toString(r.first_set)).c_str());
    if (i == 0) {
      EXPECT_TRUE(r.homed) << "the first scan did not home";
      EXPECT_TRUE(r.step_check && r.step_check->passed) << "no step check at a passed home edge";
    } else {
      expectAHomedHeadsScan(r, reports[reports.size() - 2]);
    }
  }
  return reports;
}

}  // namespace cylscan::firmware::test
