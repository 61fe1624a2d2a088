// SPDX-License-Identifier: Apache-2.0
// cylscan simulate in a build without the virtual head (CYLSCAN_WITH_SIM=OFF):
// the subcommand stays, so that a script or `cylscan study` that runs it is
// told why it cannot, not that the command does not exist; it exits 2.
#include <stdexcept>
#include <string>

#include "drivers/board_profile.hpp"
#include "tools/commands.hpp"

namespace cylscan::tools {

void addSimulateCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand(
      "simulate", "render a dataset on the virtual head (not in this build: CYLSCAN_WITH_SIM=OFF)");
  cmd->allow_extras();
  cmd->callback(
      [] { throw std::invalid_argument("simulate: " + std::string(drivers::kNoVirtualHead)); });
}

}  // namespace cylscan::tools
