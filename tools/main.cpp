// SPDX-License-Identifier: Apache-2.0
// cylscan: calibration, simulation and offline reconstruction (docs/formats.md,
// command line: exit status 0, 2 bad input, 1 other failures).
#include <cstdio>
#include <exception>
#include <iostream>

#include <CLI/CLI.hpp>

#include "formats/input_error.hpp"
#include "tools/commands.hpp"

namespace {

int runCli(int argc, char** argv) {
  CLI::App app{"cylscan: firmware tools of the cylindrical fringe-projection scanning head"};
  app.set_version_flag("--version", CYLSCAN_VERSION);
  app.require_subcommand(1);
  cylscan::tools::addPhaseCommand(app);
  cylscan::tools::addSimulateCommand(app);
  cylscan::tools::addScanCommand(app);
  cylscan::tools::addCalibrateStereoCommand(app);
  cylscan::tools::addRefineStereoCommand(app);
  cylscan::tools::addCalibrateCommand(app);
  cylscan::tools::addReconstructCommand(app);
  cylscan::tools::addEvaluateCommand(app);
  cylscan::tools::addStudyCommand(app);
  cylscan::tools::addCalibrateHeadCommand(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;  // usage errors are bad input
  } catch (const cylscan::formats::InputError& e) {
    std::cerr << "cylscan: " << e.what() << "\n";
    return 2;
  } catch (const std::invalid_argument& e) {
    std::cerr << "cylscan: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "cylscan: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

}  // namespace

// Anything that escapes the command (its setup included) is an internal error.
int main(int argc, char** argv) {
  try {
    return runCli(argc, argv);
  } catch (const std::exception& e) {
    std::fputs("cylscan: ", stderr);
    std::fputs(e.what(), stderr);
    std::fputs("\n", stderr);
  } catch (...) {
    std::fputs("cylscan: unknown error\n", stderr);
  }
  return 1;
}
