// SPDX-License-Identifier: Apache-2.0
#include "drivers/gpio_gpiod.hpp"

#include <algorithm>
#include <exception>
#include <system_error>
#include <utility>

#include <gpiod.hpp>

namespace cylscan::drivers {

namespace {

constexpr std::size_t kEventBufferSize = 16;

// Reads one chip's label and line names.
ChipLines readChip(const std::filesystem::path& path) {
  gpiod::chip chip(path);
  const gpiod::chip_info info = chip.get_info();
  ChipLines lines;
  lines.path = path.string();
  lines.label = info.label();
  lines.names.reserve(info.num_lines());
  for (std::size_t i = 0; i < info.num_lines(); ++i) {
    lines.names.push_back(chip.get_line_info(static_cast<gpiod::line::offset>(i)).name());
  }
  return lines;
}

gpiod::line_request requestLine(const LineLocation& where, const LineSpec& spec,
                                const std::string& consumer, gpiod::line_settings settings) {
  try {
    gpiod::chip chip(where.chip);
    return chip.prepare_request()
        .set_consumer(consumer)
        .set_event_buffer_size(kEventBufferSize)
        .add_line_settings(where.offset, settings.set_active_low(spec.active_low))
        .do_request();
  } catch (const std::exception& e) {
    throw GpioError("gpio: " + describeLine(spec) + " (" + where.chip + ":" +
                    std::to_string(where.offset) + "): cannot request it: " + e.what());
  }
}

class GpiodOutputLine final : public OutputLine {
 public:
  GpiodOutputLine(gpiod::line_request request, const LineLocation& where, std::string what)
      : request_(std::move(request)),
        offsets_{where.offset},
        values_{gpiod::line::value::INACTIVE},
        what_(std::move(what)) {}

  // The offsets and values vectors are allocated once: set_values() with them
  // only copies into the request's own preallocated buffer.
  void set(bool active) override {
    values_[0] = active ? gpiod::line::value::ACTIVE : gpiod::line::value::INACTIVE;
    try {
      request_.set_values(offsets_, values_);
    } catch (const std::exception& e) {
      throw GpioError("gpio: " + what_ + ": cannot set it: " + e.what());
    }
  }

 private:
  gpiod::line_request request_;
  gpiod::line::offsets offsets_;
  gpiod::line::values values_;
  std::string what_;
};

class GpiodInputLine final : public InputLine {
 public:
  GpiodInputLine(gpiod::line_request request, const LineLocation& where, std::string what)
      : request_(std::move(request)),
        offset_(where.offset),
        events_(kEventBufferSize),
        what_(std::move(what)) {}

  bool get() override {
    try {
      return request_.get_value(offset_) == gpiod::line::value::ACTIVE;
    } catch (const std::exception& e) {
      throw GpioError("gpio: " + what_ + ": cannot read it: " + e.what());
    }
  }

  // Events read together are handed out one per call, oldest first.
  std::optional<LineEvent> waitEdge(Nanoseconds timeout) override {
    try {
      if (next_ >= events_.num_events()) {
        if (!request_.wait_edge_events(std::max(timeout, Nanoseconds(0)))) return std::nullopt;
        next_ = 0;
        if (request_.read_edge_events(events_) == 0) return std::nullopt;
      }
      const gpiod::edge_event& e = events_.get_event(static_cast<unsigned int>(next_++));
      LineEvent out;
      out.edge =
          e.type() == gpiod::edge_event::event_type::RISING_EDGE ? Edge::Rising : Edge::Falling;
      out.timestamp = Nanoseconds(static_cast<std::int64_t>(e.timestamp_ns().ns()));
      return out;
    } catch (const std::exception& e) {
      throw GpioError("gpio: " + what_ + ": cannot read edge events: " + e.what());
    }
  }

 private:
  gpiod::line_request request_;
  gpiod::line::offset offset_;
  gpiod::edge_event_buffer events_;
  std::size_t next_ = 0;
  std::string what_;
};

std::string located(const LineSpec& spec, const LineLocation& where) {
  return describeLine(spec) + " (" + where.chip + ":" + std::to_string(where.offset) + ")";
}

}  // namespace

GpiodBackend::GpiodBackend(std::filesystem::path device_dir, std::string consumer)
    : device_dir_(std::move(device_dir)), consumer_(std::move(consumer)) {}

const std::vector<ChipLines>& GpiodBackend::chips() {
  if (scanned_) return chips_;
  std::vector<std::filesystem::path> paths;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(device_dir_, ec)) {
    const std::string file = entry.path().filename().string();
    if (file.rfind("gpiochip", 0) != 0) continue;
    try {
      if (gpiod::is_gpiochip_device(entry.path())) paths.push_back(entry.path());
    } catch (const std::exception&) {
      // Not a readable GPIO chip: not one of ours.
    }
  }
  if (ec) {
    throw GpioError("gpio: cannot list " + device_dir_.string() + ": " + ec.message());
  }
  std::sort(paths.begin(), paths.end());
  std::vector<ChipLines> chips;
  for (const auto& path : paths) {
    try {
      chips.push_back(readChip(path));
    } catch (const std::exception& e) {
      throw GpioError("gpio: cannot read GPIO chip " + path.string() + ": " + e.what());
    }
  }
  chips_ = std::move(chips);
  scanned_ = true;
  return chips_;
}

LineLocation GpiodBackend::locate(const LineSpec& spec) {
  const std::vector<ChipLines>& found = chips();
  if (found.empty()) {
    throw GpioError("gpio: " + describeLine(spec) + ": no GPIO chips under " +
                    device_dir_.string());
  }
  return resolveLine(spec, found);
}

std::unique_ptr<OutputLine> GpiodBackend::requestOutput(const LineSpec& spec, bool initial_active) {
  const LineLocation where = locate(spec);
  gpiod::line_settings settings;
  settings.set_direction(gpiod::line::direction::OUTPUT)
      .set_output_value(initial_active ? gpiod::line::value::ACTIVE : gpiod::line::value::INACTIVE);
  return std::make_unique<GpiodOutputLine>(requestLine(where, spec, consumer_, settings), where,
                                           located(spec, where));
}

std::unique_ptr<InputLine> GpiodBackend::requestInput(const LineSpec& spec) {
  const LineLocation where = locate(spec);
  gpiod::line_settings settings;
  settings.set_direction(gpiod::line::direction::INPUT)
      .set_edge_detection(gpiod::line::edge::BOTH)
      .set_event_clock(gpiod::line::clock::MONOTONIC);
  return std::make_unique<GpiodInputLine>(requestLine(where, spec, consumer_, settings), where,
                                          located(spec, where));
}

}  // namespace cylscan::drivers
