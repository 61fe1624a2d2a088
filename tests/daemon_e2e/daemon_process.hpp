// SPDX-License-Identifier: Apache-2.0
// cylscand as a child process of a test: started with fork/execv, its first
// stdout line ("cylscand: listening on http://127.0.0.1:PORT (…)") read
// with a timeout, stderr captured to a file for failure messages, stopped
// with SIGTERM (exit status returned) or SIGKILL. The destructor kills a
// process still running, and the child gets SIGKILL if the test dies first
// (PR_SET_PDEATHSIG), so no daemon outlives its test.
#pragma once

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace cylscan::test {

inline const std::filesystem::path kDaemonProgram = CYLSCAND_PROGRAM;

class DaemonProcess {
 public:
  // Starts `program args…` with stdout on a pipe and stderr in `stderr_file`.
  DaemonProcess(const std::vector<std::string>& args, std::filesystem::path stderr_file,
                const std::filesystem::path& program = kDaemonProgram)
      : stderr_file_(std::move(stderr_file)) {
    int fds[2];
    if (pipe2(fds, O_CLOEXEC) != 0) throw std::runtime_error("pipe2: " + errnoText());
    const int err_fd = open(stderr_file_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (err_fd < 0) {
      close(fds[0]);
      close(fds[1]);
      throw std::runtime_error(stderr_file_.string() + ": " + errnoText());
    }
    std::vector<std::string> argv_text{program.string()};
    argv_text.insert(argv_text.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : argv_text)
      argv.push_back(a.data());
    argv.push_back(nullptr);
    const pid_t parent = getpid();

    pid_ = fork();
    if (pid_ < 0) throw std::runtime_error("fork: " + errnoText());
    if (pid_ == 0) {
      // The child: only async-signal-safe calls until execv.
      prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (getppid() != parent) _exit(127);
      dup2(fds[1], STDOUT_FILENO);
      dup2(err_fd, STDERR_FILENO);
      execv(argv[0], argv.data());
      _exit(127);
    }
    close(fds[1]);
    close(err_fd);
    stdout_fd_ = fds[0];
    reader_ = std::thread([this] { readStdout(); });
  }

  ~DaemonProcess() {
    if (running()) kill();
    if (reader_.joinable()) reader_.join();
    if (stdout_fd_ >= 0) close(stdout_fd_);
  }
  DaemonProcess(const DaemonProcess&) = delete;
  DaemonProcess& operator=(const DaemonProcess&) = delete;

  pid_t pid() const { return pid_; }

  // Waits for the first stdout line and returns the base URL
  // ("http://127.0.0.1:PORT"); std::runtime_error with stderr when the line
  // does not come within `timeout` or is not the listening line.
  std::string waitListening(std::chrono::milliseconds timeout = std::chrono::seconds(30)) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      {
        std::lock_guard lock(mutex_);
        const auto eol = stdout_.find('\n');
        if (eol != std::string::npos) {
          first_line_ = stdout_.substr(0, eol);
          static const std::regex listening(
              R"(^cylscand: listening on (http://127\.0\.0\.1:([0-9]+)) \(.*\)$)");
          std::smatch m;
          if (!std::regex_match(first_line_, m, listening)) {
            throw std::runtime_error("cylscand's first line is not the listening line: '" +
                                     first_line_ + "'\nstderr:\n" + stderrText());
          }
          url_ = m[1];
          port_ = std::stoi(m[2]);
          return url_;
        }
      }
      if (!running()) {
        throw std::runtime_error("cylscand exited (" + describeStatus() +
                                 ") before listening; stderr:\n" + stderrText());
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    throw std::runtime_error("cylscand did not print its listening line within " +
                             std::to_string(timeout.count()) + " ms; stderr:\n" + stderrText());
  }

  const std::string& url() const { return url_; }
  int port() const { return port_; }
  const std::string& firstLine() const { return first_line_; }

  bool running() {
    if (exited_) return false;
    int status = 0;
    const pid_t r = waitpid(pid_, &status, WNOHANG);
    if (r == pid_) {
      exited_ = true;
      status_ = status;
      return false;
    }
    return true;
  }

  // Waits up to `timeout` for the process to exit; its raw wait status.
  std::optional<int> waitExit(std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (running()) {
      if (std::chrono::steady_clock::now() >= deadline) return std::nullopt;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    if (reader_.joinable()) reader_.join();
    return status_;
  }

  // SIGTERM, then waits up to `timeout`; nullopt (and SIGKILL) when it did
  // not stop in time, else the exit code (-signal when killed by a signal).
  std::optional<int> terminate(std::chrono::milliseconds timeout = std::chrono::seconds(20)) {
    if (running()) ::kill(pid_, SIGTERM);
    const auto status = waitExit(timeout);
    if (!status) {
      kill();
      return std::nullopt;
    }
    return exitCode(*status);
  }

  // SIGKILL and reap.
  void kill() {
    if (running()) {
      ::kill(pid_, SIGKILL);
      while (waitpid(pid_, &status_, 0) < 0 && errno == EINTR) {
      }
      exited_ = true;
    }
    if (reader_.joinable()) reader_.join();
  }

  // exit code, or -signal.
  static int exitCode(int status) {
    if (WIFEXITED(status)) return WEXITSTATUS(status);
    if (WIFSIGNALED(status)) return -WTERMSIG(status);
    return -1000;
  }
  std::string describeStatus() const {
    if (!exited_) return "running";
    if (WIFEXITED(status_)) return "exit " + std::to_string(WEXITSTATUS(status_));
    if (WIFSIGNALED(status_)) return "signal " + std::to_string(WTERMSIG(status_));
    return "status " + std::to_string(status_);
  }

  std::string stderrText() const {
    std::ifstream in(stderr_file_);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }
  std::string stdoutText() {
    std::lock_guard lock(mutex_);
    return stdout_;
  }

 private:
  static std::string errnoText() { return std::strerror(errno); }

  // Drains stdout until EOF, so the daemon never blocks on a full pipe.
  void readStdout() {
    char buffer[4096];
    while (true) {
      const ssize_t n = read(stdout_fd_, buffer, sizeof buffer);
      if (n > 0) {
        std::lock_guard lock(mutex_);
        stdout_.append(buffer, static_cast<std::size_t>(n));
      } else if (n == 0 || errno != EINTR) {
        return;
      }
    }
  }

  std::filesystem::path stderr_file_;
  pid_t pid_ = -1;
  int stdout_fd_ = -1;
  bool exited_ = false;
  int status_ = 0;
  std::thread reader_;
  std::mutex mutex_;
  std::string stdout_;
  std::string first_line_;
  std::string url_;
  int port_ = 0;
};

}  // namespace cylscan::test
