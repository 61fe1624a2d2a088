// SPDX-License-Identifier: Apache-2.0
#include "firmware/scan_profile.hpp"

#include <string>

#include "drivers/toml_reader.hpp"

namespace cylscan::firmware {

std::string_view toString(ScanMode mode) {
  return mode == ScanMode::StopAndGo ? "stop" : "continuous";
}

std::string_view toString(PlanKind plan) {
  return plan == PlanKind::Sets ? "sets" : "ring";
}

ScanProfile readScanProfile(const drivers::BoardProfile& profile) {
  const toml::table& table = profile.scanTable();
  drivers::TableReader r(table, profile.file.string(), "scan");
  ScanProfile s;
  s.frames_high = r.integer("frames_high", s.frames_high);
  r.require(s.frames_high >= 3 && s.frames_high <= 1000, "frames_high", "must be in [3, 1000]");
  s.frames_low = r.integer("frames_low", s.frames_low);
  r.require(s.frames_low >= 3 && s.frames_low <= 1000, "frames_low", "must be in [3, 1000]");
  const std::string mode = r.string("mode", "stop");
  if (mode == "stop") {
    s.mode = ScanMode::StopAndGo;
  } else if (mode == "continuous") {
    s.mode = ScanMode::Continuous;
  } else {
    r.fail("mode", "unknown mode '" + mode + "' (\"stop\" or \"continuous\")");
  }
  s.frame_timeout_ms = r.positive("frame_timeout_ms", s.frame_timeout_ms);
  if (r.has("settle_ms")) s.settle_ms = r.nonNegative("settle_ms", 0.0);
  s.save_bundle = r.boolean("save_bundle", s.save_bundle);
  s.verify_steps = r.boolean("verify_steps", s.verify_steps);
  s.period_high_deg = r.positive("period_high_deg", s.period_high_deg);
  s.period_low_deg = r.positive("period_low_deg", s.period_low_deg);
  r.require(s.period_low_deg != s.period_high_deg, "period_low_deg",
            "must differ from period_high_deg (two wavelengths)");
  const std::string plan = r.string("plan", "sets");
  if (plan == "sets") {
    s.plan = PlanKind::Sets;
  } else if (plan == "ring") {
    s.plan = PlanKind::Ring;
  } else {
    r.fail("plan", "unknown plan '" + plan + "' (\"sets\" or \"ring\")");
  }
  s.step_deg = r.nonNegative("step_deg", s.step_deg);
  r.require(s.plan == PlanKind::Ring || !r.has("step_deg"), "step_deg",
            "only with plan = \"ring\" (the sets plan steps by period / frames)");
  s.high_half_start_deg = r.number("high_half_start_deg", s.high_half_start_deg);
  r.require(s.high_half_start_deg >= 0 && s.high_half_start_deg < 360, "high_half_start_deg",
            "must be in [0, 360)");
  if (s.plan == PlanKind::Sets) {
    // The start angles place each set on its own half of the cylinder; only
    // the installer knows where home is against the halves (board/README.md).
    for (const char* key : {"high_start_deg", "low_start_deg"}) {
      r.require(r.has(key), key,
                "is required with plan = \"sets\": the stage angle of the set's first frame, "
                "from where the home switch sits against the cylinder's slot halves");
    }
    s.high_start_deg = r.number("high_start_deg", 0);
    r.require(s.high_start_deg >= 0 && s.high_start_deg < 360, "high_start_deg",
              "must be in [0, 360)");
    s.low_start_deg = r.number("low_start_deg", 0);
    r.require(s.low_start_deg >= 0 && s.low_start_deg < 360, "low_start_deg",
              "must be in [0, 360)");
  } else {
    r.require(!r.has("frames_low") || s.frames_low == s.frames_high, "frames_low",
              "must equal frames_high with plan = \"ring\" (both sweeps have the same frames)");
    s.frames_low = s.frames_high;
    for (const char* key : {"high_start_deg", "low_start_deg"}) {
      r.require(!r.has(key), key,
                "not used with plan = \"ring\" (the planner computes the sweeps' starts)");
    }
    for (const drivers::CameraProfile& camera : profile.cameras) {
      r.require(camera.azimuth_deg.has_value(), "plan",
                "\"ring\" needs azimuth_deg (the projector azimuths [lo, hi] of its working "
                "volume) on every camera; camera '" +
                    camera.name + "' has none");
    }
  }
  r.finish();
  return s;
}

double settleMs(const drivers::BoardProfile& board, const ScanProfile& scan) {
  return scan.settle_ms.value_or(board.stage.settle_ms);
}

}  // namespace cylscan::firmware
