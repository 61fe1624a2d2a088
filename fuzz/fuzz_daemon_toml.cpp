// SPDX-License-Identifier: Apache-2.0
// cylscan.toml: parseDaemonConfig over the defaults. Every fault must be a
// ConfigError (toml++ syntax errors included); any other exception escaping
// is a finding. An accepted configuration is printed back through the
// parts that have a text form, which must parse again.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "firmware/daemon/daemon_config.hpp"
#include "fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace fw = cylscan::firmware;
  const auto file = cylscan::fuzz::scratchDir() / "cylscan.toml";
  try {
    const fw::DaemonConfig config =
        fw::parseDaemonConfig(cylscan::fuzz::asText(data, size), file, fw::DaemonConfig{});
    const std::string listen = fw::toString(config.listen);
    const fw::ListenAddress again = fw::parseListenAddress(listen);
    if (again.address != config.listen.address || again.port != config.listen.port)
      throw std::logic_error("listen address does not survive toString/parseListenAddress");
    if (fw::parseLogLevel(fw::toString(config.log_level)) != config.log_level)
      throw std::logic_error("log level does not survive toString/parseLogLevel");
  } catch (const fw::ConfigError&) {
  }
  return 0;
}
