// SPDX-License-Identifier: Apache-2.0
// cylscand: the scanning head's daemon. Reads cylscan.toml and the flags
// (firmware/daemon/daemon_config.hpp), opens the head (ScanService) and its
// HTTP API (HttpApi), prints
//   cylscand: listening on http://ADDR:PORT (board NAME, data DIR)
// on stdout once serving, tells systemd it is ready (and pings its watchdog),
// and stops cleanly on SIGTERM/SIGINT: the running scan aborted (stage
// disabled, light off), the HTTP server stopped, exit 0.
#include <malloc.h>
#include <pthread.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#ifdef CYLSCAN_WITH_SYSTEMD
#include <systemd/sd-daemon.h>
#endif

#include "firmware/daemon/daemon_config.hpp"
#include "firmware/daemon/log.hpp"
#include "firmware/daemon/rauc_installer.hpp"
#include "firmware/daemon/scan_service.hpp"
#include "firmware/http/http_api.hpp"

namespace {

namespace fs = std::filesystem;
using namespace cylscan::firmware;

void notify([[maybe_unused]] const char* state) {
#ifdef CYLSCAN_WITH_SYSTEMD
  sd_notify(0, state);
#endif
}

// Half of systemd's WatchdogSec, or nullopt when there is no watchdog.
std::optional<std::chrono::microseconds> watchdogInterval() {
#ifdef CYLSCAN_WITH_SYSTEMD
  std::uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0) return std::chrono::microseconds(usec / 2);
#endif
  return std::nullopt;
}

fs::path exeDir(const char* argv0) {
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) return self.parent_path();
  return fs::absolute(argv0, ec).parent_path();
}

// Waits for SIGTERM or SIGINT (blocked in every thread), pinging the watchdog.
int waitForStop(const sigset_t& signals) {
  const auto watchdog = watchdogInterval();
  const std::chrono::microseconds tick = watchdog.value_or(std::chrono::seconds(1));
  for (;;) {
    timespec timeout{};
    timeout.tv_sec = static_cast<time_t>(tick.count() / 1000000);
    timeout.tv_nsec = static_cast<long>((tick.count() % 1000000) * 1000);
    const int sig = sigtimedwait(&signals, nullptr, &timeout);
    if (sig == SIGTERM || sig == SIGINT) return sig;
    if (sig < 0 && errno != EAGAIN && errno != EINTR) return -1;
    if (watchdog) notify("WATCHDOG=1");
  }
}

}  // namespace

// A function-try-block: an exception nothing below expects (std::bad_alloc)
// is reported and ends the daemon with 1 instead of escaping main.
int main(int argc, char** argv) try {
  // A scan allocates buffers of frames, maps and clouds (hundreds of KB to
  // tens of MB) on its threads. glibc's dynamic mmap threshold moves such
  // sizes into the threads' arenas once the first is freed, where they stay
  // resident between scans; a fixed threshold keeps them mapped on their
  // own and returned to the system when the scan frees them. No thread runs
  // yet.
  // NOLINTNEXTLINE(concurrency-mt-unsafe)
  mallopt(M_MMAP_THRESHOLD, 128 * 1024);
  CLI::App app{"cylscand: the daemon of the cylscan scanning head (HTTP API, docs/http-api.md)"};
  std::vector<std::string> configs;
  std::string board, listen, data, token, web_root, log_level;
  app.add_option("--config", configs,
                 "cylscan.toml (default /etc/cylscan/cylscan.toml when present); "
                 "repeat it to lay files over each other in order");
  auto* o_board = app.add_option("--board", board, "board profile folder");
  auto* o_listen =
      app.add_option("--listen", listen, "ADDRESS:PORT ([::1]:8080 for IPv6; port 0 = any)");
  auto* o_data = app.add_option("--data", data, "data directory");
  auto* o_token = app.add_option("--token", token, "bearer token (empty: no authentication)");
  auto* o_web = app.add_option("--web-root", web_root, "the web page's static files");
  auto* o_log = app.add_option("--log-level", log_level, "error | warn | info | debug");
  app.set_version_flag("--version", std::string("cylscand ") + CYLSCAN_VERSION);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }

  DaemonFlags flags;
  flags.configs.assign(configs.begin(), configs.end());
  if (o_board->count()) flags.board = board;
  if (o_listen->count()) flags.listen = listen;
  if (o_data->count()) flags.data_dir = data;
  if (o_token->count()) flags.token = token;
  if (o_web->count()) flags.web_root = web_root;
  if (o_log->count()) flags.log_level = log_level;
  DaemonConfig cfg;
  try {
    cfg = resolveDaemonConfig(flags, daemonDefaults(exeDir(argv[0])));
  } catch (const ConfigError& e) {
    std::cerr << "cylscand: " << e.what() << "\n";
    return 2;
  }
  setLogLevel(cfg.log_level);

  // SIGTERM and SIGINT go to waitForStop only: blocked before any thread starts.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  std::signal(SIGPIPE, SIG_IGN);

  std::unique_ptr<ScanService> service;
  try {
    ScanServiceOptions options = scanServiceOptions(cfg, CYLSCAN_VERSION);
    options.installer = makeRaucInstaller();
    service = std::make_unique<ScanService>(std::move(options));
  } catch (const std::invalid_argument& e) {  // a bad board profile (drivers::ConfigError)
    std::cerr << "cylscand: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "cylscand: cannot open the head: " << e.what() << "\n";
    return 1;
  }
  int status = 0;
  try {
    HttpOptions http;
    http.address = cfg.listen.address;
    http.port = cfg.listen.port;
    http.token = cfg.token;
    http.allow_loopback_without_token = cfg.allow_loopback_without_token;
    http.web_root = cfg.web_root;
    http.max_calibration_bytes = static_cast<std::size_t>(cfg.max_calibration_bytes);
    HttpApi api(*service, http);
    if (cfg.token.empty() && cfg.listen.address != "127.0.0.1" && cfg.listen.address != "::1")
      logWarn("no token: anyone who can reach " + toString(cfg.listen) + " can scan");
    const ListenAddress bound{cfg.listen.address, api.port()};
    std::cout << "cylscand: listening on http://" << toString(bound) << " (board "
              << service->boardName() << ", data " << cfg.data_dir.string() << ")" << std::endl;
    notify("READY=1");
    const int sig = waitForStop(signals);
    logInfo(sig > 0 ? std::string("stopping on ") + (sig == SIGTERM ? "SIGTERM" : "SIGINT")
                    : "stopping: cannot wait for signals");
    notify("STOPPING=1");
    service->stop();  // aborts the scan, closes the event streams
    if (sig < 0) status = 1;
  } catch (const std::exception& e) {
    logError(e.what());
    status = 1;
  }
  service.reset();
  logInfo("stopped");
  return status;
} catch (const std::exception& e) {
  std::cerr << "cylscand: " << e.what() << "\n";
  return 1;
}
