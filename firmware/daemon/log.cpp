// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/log.hpp"

#include <atomic>
#include <cstdio>
#include <mutex>
#include <string>

namespace cylscan::firmware {
namespace {

std::atomic<int> g_level{static_cast<int>(LogLevel::Info)};
std::mutex g_mutex;

}  // namespace

void setLogLevel(LogLevel level) {
  g_level.store(static_cast<int>(level));
}

bool logEnabled(LogLevel level) {
  return static_cast<int>(level) <= g_level.load();
}

void logMessage(LogLevel level, std::string_view text) {
  if (!logEnabled(level)) return;
  std::string line = "cylscand: ";
  line += toString(level);
  line += ": ";
  line += text;
  line += '\n';
  const std::lock_guard lock(g_mutex);
  std::fwrite(line.data(), 1, line.size(), stderr);
  std::fflush(stderr);
}

}  // namespace cylscan::firmware
