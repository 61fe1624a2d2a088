// SPDX-License-Identifier: Apache-2.0
// Subcommands of the `cylscan` program, one file each.
#pragma once

#include <CLI/CLI.hpp>

namespace cylscan::tools {

void addPhaseCommand(CLI::App& app);
void addSimulateCommand(CLI::App& app);
void addCalibrateStereoCommand(CLI::App& app);
void addCalibrateCommand(CLI::App& app);
void addReconstructCommand(CLI::App& app);
void addEvaluateCommand(CLI::App& app);
void addRefineStereoCommand(CLI::App& app);
void addScanCommand(CLI::App& app);
void addStudyCommand(CLI::App& app);
void addCalibrateHeadCommand(CLI::App& app);

}  // namespace cylscan::tools
