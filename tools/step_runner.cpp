// SPDX-License-Identifier: Apache-2.0
#include "tools/step_runner.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <system_error>

namespace cylscan::tools {
namespace {

namespace fs = std::filesystem;

// A pipe whose ends close themselves.
class Pipe {
 public:
  Pipe() {
    if (::pipe2(fds_, O_CLOEXEC) != 0) throw std::runtime_error("pipe: " + errnoText());
  }
  ~Pipe() {
    closeRead();
    closeWrite();
  }
  Pipe(const Pipe&) = delete;
  Pipe& operator=(const Pipe&) = delete;
  int readEnd() const { return fds_[0]; }
  int writeEnd() const { return fds_[1]; }
  void closeRead() { closeFd(fds_[0]); }
  void closeWrite() { closeFd(fds_[1]); }
  static std::string errnoText() { return std::generic_category().message(errno); }

 private:
  static void closeFd(int& fd) {
    if (fd >= 0) ::close(fd);
    fd = -1;
  }
  int fds_[2] = {-1, -1};
};

std::string lastLine(const std::string& text) {
  std::string trimmed = text;
  while (!trimmed.empty() && (trimmed.back() == '\n' || trimmed.back() == '\r'))
    trimmed.pop_back();
  const auto nl = trimmed.rfind('\n');
  return nl == std::string::npos ? trimmed : trimmed.substr(nl + 1);
}

std::string readFile(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace

fs::path selfExecutable() {
  return fs::read_symlink("/proc/self/exe");
}

StepRunner::StepRunner(fs::path executable, fs::path log_dir)
    : executable_(std::move(executable)), log_dir_(std::move(log_dir)) {
  fs::create_directories(log_dir_);
}

nlohmann::json StepRunner::run(const std::string& step, const std::vector<std::string>& args) {
  ++steps_;
  const fs::path log = log_dir_ / (std::to_string(steps_) + "_" + step + ".stderr");
  std::vector<std::string> argv_text{executable_.string()};
  argv_text.insert(argv_text.end(), args.begin(), args.end());
  argv_text.push_back("--json");
  std::vector<char*> argv;
  argv.reserve(argv_text.size() + 1);
  for (auto& a : argv_text)
    argv.push_back(a.data());
  argv.push_back(nullptr);

  Pipe out;
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, out.writeEnd(), STDOUT_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, log.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  pid_t pid = 0;
  const int spawned =
      posix_spawn(&pid, executable_.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) {
    throw std::runtime_error(step + ": cannot start " + executable_.string() + ": " +
                             std::generic_category().message(spawned));
  }
  out.closeWrite();
  std::string output;
  char buffer[65536];
  for (;;) {
    const ssize_t n = ::read(out.readEnd(), buffer, sizeof buffer);
    if (n > 0) {
      output.append(buffer, static_cast<std::size_t>(n));
    } else if (n == 0 || errno != EINTR) {
      break;
    }
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (code != 0) {
    const std::string message = lastLine(readFile(log));
    const std::string text = "step '" + step + "' failed (exit " + std::to_string(code) +
                             "): " + (message.empty() ? "no message" : message);
    if (code == 2) throw std::invalid_argument(text);
    throw std::runtime_error(text);
  }
  try {
    return nlohmann::json::parse(lastLine(output));
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error("step '" + step + "' printed no JSON object: " + e.what());
  }
}

}  // namespace cylscan::tools
