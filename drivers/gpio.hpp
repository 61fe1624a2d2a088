// SPDX-License-Identifier: Apache-2.0
// GPIO lines behind a small interface: one backend per file (gpiod, sim).
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

namespace cylscan::drivers {

using Nanoseconds = std::chrono::nanoseconds;

// Where a line is: by its device-tree name (gpiofind-style), or by chip and
// offset. Exactly one of `name` or (`chip`, `offset`) is used.
struct LineSpec {
  std::string name;         // e.g. "GPIO17" or "cylscan-step"; empty when chip/offset used
  std::string chip;         // e.g. "gpiochip0" or "/dev/gpiochip0"
  int offset = -1;          // line offset on `chip`
  bool active_low = false;  // polarity: set(true) drives the line to its active level
  std::string role;         // what the line is for ("step", "home", ...), for messages
};

enum class Edge { Rising, Falling };

struct LineEvent {
  Edge edge = Edge::Rising;
  Nanoseconds timestamp{0};  // kernel (or virtual) CLOCK_MONOTONIC timestamp
};

class GpioError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// An output line. set() must not allocate or lock: the real-time executor calls it.
class OutputLine {
 public:
  virtual ~OutputLine() = default;
  virtual void set(bool active) = 0;
};

// An input line with edge events (both edges).
class InputLine {
 public:
  virtual ~InputLine() = default;
  virtual bool get() = 0;
  // Waits up to `timeout` for the next edge; nullopt on timeout.
  virtual std::optional<LineEvent> waitEdge(Nanoseconds timeout) = 0;
};

class GpioBackend {
 public:
  virtual ~GpioBackend() = default;
  // Throws GpioError naming the line (role and name or chip/offset) when it
  // cannot be found or requested.
  virtual std::unique_ptr<OutputLine> requestOutput(const LineSpec& spec, bool initial_active) = 0;
  virtual std::unique_ptr<InputLine> requestInput(const LineSpec& spec) = 0;
};

}  // namespace cylscan::drivers
