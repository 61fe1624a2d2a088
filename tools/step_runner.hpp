// SPDX-License-Identifier: Apache-2.0
// Runs another `cylscan` subcommand as a child process (the same executable),
// so each step of a longer job keeps its own command-line contract: its
// `--json` line is parsed, and a failing step stops the job with its message.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace cylscan::tools {

class StepRunner {
 public:
  // `executable`: the program to run (by default this process's own image);
  // `log_dir`: where each step's stderr is kept (created).
  StepRunner(std::filesystem::path executable, std::filesystem::path log_dir);

  // Runs `executable args... --json` and returns its one JSON object. When the
  // step exits non-zero: std::invalid_argument (exit status 2, bad input) or
  // std::runtime_error (anything else), with the step's own message.
  nlohmann::json run(const std::string& step, const std::vector<std::string>& args);

  int stepsRun() const { return steps_; }

 private:
  std::filesystem::path executable_;
  std::filesystem::path log_dir_;
  int steps_ = 0;
};

// The running program's own executable (/proc/self/exe).
std::filesystem::path selfExecutable();

}  // namespace cylscan::tools
