// SPDX-License-Identifier: Apache-2.0
#include "drivers/stage_config.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace cylscan::drivers {

namespace {

void check(bool ok, const char* field, const char* rule) {
  if (!ok) throw std::invalid_argument(std::string("stage.") + field + ": " + rule);
}

bool positive(double v) {
  return std::isfinite(v) && v > 0;
}

}  // namespace

void validate(const StageConfig& c) {
  check(c.full_steps_per_rev > 0, "full_steps_per_rev", "must be > 0");
  check(c.microsteps > 0, "microsteps", "must be > 0");
  check(positive(c.gear_ratio), "gear_ratio", "must be > 0");
  check(positive(c.max_speed_deg_s), "max_speed_deg_s", "must be > 0");
  check(positive(c.accel_deg_s2), "accel_deg_s2", "must be > 0");
  check(positive(c.start_speed_deg_s) && c.start_speed_deg_s <= c.max_speed_deg_s,
        "start_speed_deg_s", "must be in (0, max_speed_deg_s]");
  check(positive(c.step_pulse_us), "step_pulse_us", "must be > 0");
  check(std::isfinite(c.dir_setup_us) && c.dir_setup_us >= 0, "dir_setup_us", "must be >= 0");
  check(std::isfinite(c.enable_settle_ms) && c.enable_settle_ms >= 0, "enable_settle_ms",
        "must be >= 0");
  check(std::isfinite(c.settle_ms) && c.settle_ms >= 0, "settle_ms", "must be >= 0");
  check(c.home_direction == 1 || c.home_direction == -1, "home_direction", "must be +1 or -1");
  check(positive(c.home_seek_speed_deg_s) && c.home_seek_speed_deg_s <= c.max_speed_deg_s,
        "home_seek_speed_deg_s", "must be in (0, max_speed_deg_s]");
  check(positive(c.home_approach_speed_deg_s) &&
            c.home_approach_speed_deg_s <= c.home_seek_speed_deg_s,
        "home_approach_speed_deg_s", "must be in (0, home_seek_speed_deg_s]");
  check(positive(c.home_backoff_deg), "home_backoff_deg", "must be > 0");
  check(positive(c.home_max_travel_deg), "home_max_travel_deg", "must be > 0");
  check(std::isfinite(c.home_offset_deg), "home_offset_deg", "must be finite");
  check(c.step_check_tolerance_steps >= 0, "step_check_tolerance_steps", "must be >= 0");
}

}  // namespace cylscan::drivers
