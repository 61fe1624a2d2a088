// SPDX-License-Identifier: Apache-2.0
// Runs the `cylscan` program (CYLSCAN_TOOL, defined by the test's target) as a
// user would, with its exit status and everything it printed.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace cylscan::test_support {

struct ToolResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

inline ToolResult runTool(const std::string& args) {
  const std::string command = std::string(CYLSCAN_TOOL) + " " + args + " 2>&1";
  ToolResult result;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return result;
  char buffer[4096];
  std::size_t n = 0;
  while ((n = fread(buffer, 1, sizeof buffer, pipe)) > 0)
    result.output.append(buffer, n);
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

}  // namespace cylscan::test_support
