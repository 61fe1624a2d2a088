// SPDX-License-Identifier: Apache-2.0
// The daemon's log: one line per message on stderr, "cylscand: LEVEL: text",
// messages below the configured level dropped. Thread-safe.
#pragma once

#include <string_view>

#include "firmware/daemon/daemon_config.hpp"

namespace cylscan::firmware {

void setLogLevel(LogLevel level);
bool logEnabled(LogLevel level);
void logMessage(LogLevel level, std::string_view text);

inline void logError(std::string_view text) {
  logMessage(LogLevel::Error, text);
}
inline void logWarn(std::string_view text) {
  logMessage(LogLevel::Warn, text);
}
inline void logInfo(std::string_view text) {
  logMessage(LogLevel::Info, text);
}
inline void logDebug(std::string_view text) {
  logMessage(LogLevel::Debug, text);
}

}  // namespace cylscan::firmware
