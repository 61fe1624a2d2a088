// SPDX-License-Identifier: Apache-2.0
// Load on the daemon while a scan runs on the virtual head paced to real
// time (CTest label `load`; figures in docs/robustness.md, "Load").
//
// Three scans of the same seed, each by a fresh cylscand (a fresh head: the
// noise of a frame is keyed by its sequence number since power-up):
//   A, B  unloaded — B checks that the paced head is deterministic per seed
//         (phase.png and depth.tiff byte for byte), and both give the
//         unloaded step lateness;
//   C     loaded — wrk hammers GET /api/v1/status and /metrics on
//         127.0.0.1 with 100 connections, while 32 idle clients hold
//         /api/v1/events open and 8 slow clients read /metrics one byte a
//         second, for 70 % of the shorter of A's and B's board time (at
//         most 30 s), so the load starts and ends while C runs whatever the
//         stage's speed; should it outlast C (A and B slowed by a busy
//         machine), it must have loaded at least the second half of C.
// C must complete with every frame and no retry, the same phase.png and
// depth.tiff bytes as A, and a step lateness p99 within
//   max(2 × unloaded p99, unloaded p99 + 200 µs)
// (unloaded p99: the larger of A's and B's). Lateness p99 of an unloaded run
// on a shared 2-core machine is tens of µs with a few-ms tail (max); the
// bound allows the loaded run twice the unloaded figure, or 200 µs more when
// that is larger — a fifth of the 1 ms poll the acquisition threads use —
// so it fails only when HTTP load visibly delays the real-time thread. A
// sanitized build prints the lateness and does not assert the bound.
//
// The head file of the board is changed in four ways for the paced run:
// pace_real_time = true; the stage's ringing after a stop and the LED's
// warm-up off (settle_amplitude_deg = 0, source_warmup_drop = 0), so a
// stop-and-go exposure sees the same angle and light whatever the real time
// it starts at; and the motor model's start rate and
// top speed raised so far that it follows every pulse: a step executor that
// wakes late emits the overdue pulses back to back, and on a shared VM (max
// lateness of a few ms) the model stalls on such a burst in every paced run.
// The firmware plans its moves from board.toml, unchanged; the lateness it
// measures is what this test is about.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <fstream>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "quick_daemon.hpp"

namespace cylscan::test {
namespace {

// A sanitized cylscand (-O1 and every access checked) takes about twice the
// CPU per request (2,262 against ~5,000 requests/s here), so the same wrk
// load leaves the real-time thread less of the 2 cores than the bound was
// made for: there the lateness is printed, every other check stays.
constexpr bool kSanitized = CYLSCAND_SANITIZED;

constexpr int kIdleEventClients = 32;
constexpr int kSlowClients = 8;
constexpr int kWrkConnections = 100;
constexpr int kMaxLoadSeconds = 30;

// The load's length for a paced scan whose stage moved for `board_s`. A paced
// scan cannot end sooner than its board time, whereas its wall time grows
// with whatever else the machine runs (a scan of 25 s of board time took
// 40 s beside other tests): the load is cut from the floor, so that it ends
// before the scan on a quiet machine too. The daemon's start, the side
// clients' connections and wrk's own start take a few seconds of the scan
// before the load begins; 70 % leaves them room and still loads every part
// of the scan after homing.
int loadSeconds(double board_s) {
  return std::clamp(static_cast<int>(0.7 * board_s), 5, kMaxLoadSeconds);
}

std::string replaceOnce(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  if (at == std::string::npos) throw std::runtime_error("head.toml has no '" + from + "'");
  return text.replace(at, from.size(), to);
}

fs::path pacedBoard(const TempDir& dir) {
  const fs::path board = dir.path() / "paced";
  fs::copy(quickFixture() / "board", board, fs::copy_options::recursive);
  std::string head = readBytes(board / "head.toml");
  head = replaceOnce(head, "pace_real_time = false", "pace_real_time = true");
  head = replaceOnce(head, "settle_amplitude_deg = 0.01", "settle_amplitude_deg = 0.0");
  // The LED's level follows the real time since the light came on.
  head = replaceOnce(head, "source_warmup_drop = 0.02", "source_warmup_drop = 0.0");
  head = replaceOnce(head, "max_speed_deg_s = 30.0", "max_speed_deg_s = 100000.0");
  head = replaceOnce(head, "start_speed_deg_s = 4.0", "start_speed_deg_s = 99999.0");
  std::ofstream(board / "head.toml", std::ios::trunc) << head;
  return board;
}

int connectLoopback(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return -1;
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
  if (connect(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0) {
    close(fd);
    return -1;
  }
  return fd;
}

bool sendAll(int fd, const std::string& text) {
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = send(fd, text.data() + done, text.size() - done, MSG_NOSIGNAL);
    if (n <= 0) return false;
    done += static_cast<std::size_t>(n);
  }
  return true;
}

// Idle event-stream clients and slow readers, held for `seconds` on their
// own thread; what they got.
class SideClients {
 public:
  SideClients(int port, int seconds) {
    for (int i = 0; i < kIdleEventClients; ++i) {
      const int fd = connectLoopback(port);
      if (fd >= 0 && sendAll(fd, "GET /api/v1/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"))
        idle_.push_back(fd);
      else if (fd >= 0)
        close(fd);
    }
    for (int i = 0; i < kSlowClients; ++i) {
      const int fd = connectLoopback(port);
      if (fd >= 0 && sendAll(fd, "GET /metrics HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"))
        slow_.push_back(fd);
      else if (fd >= 0)
        close(fd);
    }
    slow_bytes_.assign(slow_.size(), 0);
    thread_ = std::thread([this, seconds] { run(seconds); });
  }
  ~SideClients() {
    if (thread_.joinable()) thread_.join();
    for (int fd : idle_)
      close(fd);
    for (int fd : slow_)
      close(fd);
  }
  // Idle clients whose stream was answered (read at last: the 200 and the
  // first events).
  int idleAnswered() const {
    int n = 0;
    for (int fd : idle_) {
      char buffer[4096];
      const ssize_t got = recv(fd, buffer, sizeof buffer, MSG_DONTWAIT);
      if (got > 0 &&
          std::string(buffer, static_cast<std::size_t>(got)).rfind("HTTP/1.1 200", 0) == 0)
        ++n;
    }
    return n;
  }
  void join() {
    if (thread_.joinable()) thread_.join();
  }
  int idleHeld() const { return static_cast<int>(idle_.size()); }
  int slowHeld() const { return static_cast<int>(slow_.size()); }
  // Slow readers that got a byte every second they asked for one.
  int slowSteady(int seconds) const {
    int n = 0;
    for (int b : slow_bytes_)
      n += b >= seconds - 1 ? 1 : 0;
    return n;
  }

 private:
  void run(int seconds) {
    for (int s = 0; s < seconds; ++s) {
      for (std::size_t i = 0; i < slow_.size(); ++i) {
        pollfd p{slow_[i], POLLIN, 0};
        char byte;
        if (poll(&p, 1, 0) > 0 && recv(slow_[i], &byte, 1, MSG_DONTWAIT) == 1) ++slow_bytes_[i];
      }
      std::this_thread::sleep_for(std::chrono::seconds(1));
    }
  }
  std::vector<int> idle_, slow_;
  std::vector<int> slow_bytes_;
  std::thread thread_;
};

struct WrkFigures {
  double requests_per_s = 0;
  std::string p50, p99;  // as wrk prints them (e.g. "1.23ms")
  std::string errors;    // "Socket errors: …" / "Non-2xx …" lines
  std::string text;
};

// wrk for `seconds` on /api/v1/status and /metrics in turn (a Lua script).
WrkFigures runWrk(const TempDir& dir, const std::string& url, int seconds) {
  const fs::path script = dir.write("paths.lua",
                                    "local paths = {\"/api/v1/status\", \"/metrics\"}\n"
                                    "local i = 0\n"
                                    "request = function()\n"
                                    "  i = i + 1\n"
                                    "  return wrk.format(\"GET\", paths[i % 2 + 1])\n"
                                    "end\n");
  const std::string command = "wrk -t2 -c" + std::to_string(kWrkConnections) + " -d" +
                              std::to_string(seconds) + "s --latency -s " + script.string() + " " +
                              url + " 2>&1";
  WrkFigures f;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) throw std::runtime_error("cannot run: " + command);
  char buffer[4096];
  while (fgets(buffer, sizeof buffer, pipe) != nullptr)
    f.text += buffer;
  pclose(pipe);
  std::smatch m;
  if (std::regex_search(f.text, m, std::regex(R"(Requests/sec:\s+([0-9.]+))")))
    f.requests_per_s = std::stod(m[1]);
  if (std::regex_search(f.text, m, std::regex(R"(\n\s+50%\s+(\S+))"))) f.p50 = m[1];
  if (std::regex_search(f.text, m, std::regex(R"(\n\s+99%\s+(\S+))"))) f.p99 = m[1];
  for (const char* what : {"Socket errors:[^\n]*", "Non-2xx[^\n]*"})
    if (std::regex_search(f.text, m, std::regex(what))) f.errors += m[0].str() + "; ";
  return f;
}

// Time the hypervisor gave this machine's vCPUs to others (the "steal" column
// of /proc/stat), in seconds over all CPUs: a real-time thread is late by it
// whatever its priority, so the figure goes with every lateness printed.
double stolenSeconds() {
  std::ifstream in("/proc/stat");
  std::string cpu;
  long long user = 0, nice = 0, system = 0, idle = 0, iowait = 0, irq = 0, softirq = 0, steal = 0;
  if (!(in >> cpu >> user >> nice >> system >> idle >> iowait >> irq >> softirq >> steal)) return 0;
  return static_cast<double>(steal) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

struct ScanRun {
  json scan;
  std::string phase_png, depth_tiff;
  double step_p99_us = -1, step_max_us = -1;
  bool realtime = false;  // the motion thread got SCHED_FIFO
  double stolen_s = 0;    // vCPU time stolen by the hypervisor during the scan
  WrkFigures wrk;
  int idle_held = 0, slow_held = 0, slow_steady = 0;
  int status_during = 0;  // our own status polls answered 200 during the load
};

// One scan by a fresh daemon; `load_s` > 0 loads it for that many seconds.
ScanRun scanOnce(const fs::path& board, int load_s = 0) {
  DaemonSetup setup;
  setup.board = board;
  QuickDaemon daemon(std::move(setup));
  const HttpClient& client = daemon.client();
  ScanRun run;
  const double stolen_before = stolenSeconds();
  const std::string id = startScan(client, {{"save_bundle", false}});
  if (id.empty()) return run;
  const auto scan_started = std::chrono::steady_clock::now();
  if (load_s > 0) {
    TempDir wrk_dir;
    SideClients side(daemon.process().port(), load_s);
    run.wrk = runWrk(wrk_dir, client.baseUrl(), load_s);
    // wrk loads for load_s seconds and exits: the load began that long ago.
    const double load_began_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - scan_started).count() -
        load_s;
    side.join();
    run.idle_held = side.idleAnswered();
    run.slow_held = side.slowHeld();
    run.slow_steady = side.slowSteady(load_s);
    // Right after wrk exits, its closed connections may still count against
    // the per-address limit until the daemon's poll loop reaps them, and a
    // new connection is then closed unanswered: ask again for up to 2 s.
    HttpResponse during = client.get("/api/v1/scans/" + id);
    if (during.status == 0)
      std::printf("[ load     ] the first request after the load: %s\n", during.describe().c_str());
    for (int i = 0; i < 20 && during.status == 0; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      during = client.get("/api/v1/scans/" + id);
    }
    const json state = during.json();
    if (during.status != 200 || !state.is_object()) {
      ADD_FAILURE() << "the scan's state after the load: " << during.describe();
    } else if (state.value("state", "") != "running") {
      // A scan whose unloaded twins woke late (a machine whose host steals
      // its CPU) took longer than this one needs, and the load was cut from
      // their time: it may outlast the scan. It then loaded the scan from
      // its own start to the scan's end, which must still be at least half
      // of the scan for its lateness to be the loaded one.
      const double duration_s = state.value("duration_s", 0.0);
      EXPECT_EQ(state.value("state", ""), "done") << state.dump();
      EXPECT_GE(duration_s - load_began_s, 0.5 * duration_s)
          << "the load began " << load_began_s << " s into a scan of " << duration_s
          << " s and outlasted it: it loaded less than half of it: " << state.dump();
      std::printf("[ load     ] the load began %.1f s into a scan of %.1f s and outlasted it\n",
                  load_began_s, duration_s);
    }
  }
  run.scan = finishScan(client, id);
  run.phase_png = client.get("/api/v1/scans/" + id + "/phase.png").body;
  run.depth_tiff = client.get("/api/v1/scans/" + id + "/depth.tiff").body;
  if (run.scan.contains("step_jitter")) {
    run.step_p99_us = run.scan["step_jitter"].value("p99_us", -1.0);
    run.step_max_us = run.scan["step_jitter"].value("max_us", -1.0);
  }
  run.realtime = run.scan.value("realtime", false);
  run.stolen_s = stolenSeconds() - stolen_before;
  daemon.stop(std::chrono::seconds(60));
  return run;
}

void expectComplete(const ScanRun& r, const std::string& what) {
  EXPECT_EQ(r.scan.value("state", ""), "done") << what << ": " << r.scan.dump();
  EXPECT_EQ(r.scan.value("frames_done", -1), r.scan.value("frames", -2))
      << what << ": frames lost: " << r.scan.dump();
  EXPECT_EQ(r.scan.value("retries", -1), 0) << what << ": frames retried: " << r.scan.dump();
  EXPECT_FALSE(r.phase_png.empty()) << what;
  EXPECT_FALSE(r.depth_tiff.empty()) << what;
}

TEST(DaemonLoad, ScanUnderHttpLoadMatchesAnUnloadedScan) {
  if (std::system("command -v wrk >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "wrk is not installed (scripts/install-deps.sh)";
  TempDir boards;
  const fs::path board = pacedBoard(boards);

  const ScanRun a = scanOnce(board);
  expectComplete(a, "unloaded scan A");
  const ScanRun b = scanOnce(board);
  expectComplete(b, "unloaded scan B");
  ASSERT_TRUE(a.phase_png == b.phase_png && a.depth_tiff == b.depth_tiff)
      << "two unloaded paced scans of the same seed differ: the head is not deterministic "
         "per seed, so 'the same phase' cannot be byte for byte";
  ASSERT_GT(a.scan.value("board_seconds", 0.0), 0.0)
      << "scan A has no board time: " << a.scan.dump();
  const int load_s =
      loadSeconds(std::min(a.scan.value("board_seconds", 0.0), b.scan.value("board_seconds", 0.0)));
  const ScanRun c = scanOnce(board, load_s);
  expectComplete(c, "loaded scan C");
  EXPECT_TRUE(c.phase_png == a.phase_png) << "the loaded scan's phase.png differs";
  EXPECT_TRUE(c.depth_tiff == a.depth_tiff) << "the loaded scan's depth.tiff differs";

  double unloaded_p99 = std::max(a.step_p99_us, b.step_p99_us);
  double bound = std::max(2 * unloaded_p99, unloaded_p99 + 200.0);
  if (!kSanitized && c.step_p99_us > bound) {
    // A shared machine's own noise changes over minutes. When the loaded scan
    // is over the bound, an unloaded scan right after it tells the load's
    // delay from the machine's: the load still fails the check when that
    // scan is as quiet as A and B were.
    const ScanRun d = scanOnce(board);
    expectComplete(d, "unloaded scan D");
    std::printf(
        "[ load     ] loaded p99 %.0f us over the bound %.0f us; unloaded scan D after it: "
        "p99/max %.0f/%.0f us, %.1f s stolen\n",
        c.step_p99_us, bound, d.step_p99_us, d.step_max_us, d.stolen_s);
    unloaded_p99 = std::max(unloaded_p99, d.step_p99_us);
    bound = std::max(2 * unloaded_p99, unloaded_p99 + 200.0);
  }
  std::printf("[ load     ] wrk %d connections %d s: %.0f requests/s, latency p50 %s p99 %s; %s\n",
              kWrkConnections, load_s, c.wrk.requests_per_s, c.wrk.p50.c_str(), c.wrk.p99.c_str(),
              c.wrk.errors.empty() ? "no errors" : c.wrk.errors.c_str());
  std::printf(
      "[ load     ] %d/%d idle event streams answered, %d/%d slow readers (%d read a byte "
      "every second)\n",
      c.idle_held, kIdleEventClients, c.slow_held, kSlowClients, c.slow_steady);
  std::printf(
      "[ load     ] step lateness p99/max: A %.0f/%.0f us, B %.0f/%.0f us, loaded "
      "%.0f/%.0f us (bound %.0f us); scan %.1f s unloaded, %.1f s loaded; motion thread "
      "SCHED_FIFO: %s; vCPU time stolen A %.1f s, C %.1f s\n",
      a.step_p99_us, a.step_max_us, b.step_p99_us, b.step_max_us, c.step_p99_us, c.step_max_us,
      bound, a.scan.value("duration_s", 0.0), c.scan.value("duration_s", 0.0),
      c.realtime ? "yes" : "no (lateness is the CFS scheduler's)", a.stolen_s, c.stolen_s);
  std::printf("%s\n", c.wrk.text.c_str());
  EXPECT_GT(c.wrk.requests_per_s, 0) << c.wrk.text;
  EXPECT_GE(unloaded_p99, 0) << "no step lateness in the unloaded scans";
  EXPECT_GE(c.step_p99_us, 0) << "no step lateness in the loaded scan";
  if (kSanitized)
    std::printf("[ load     ] sanitized build: the lateness bound is not asserted (p99 %.0f us)\n",
                c.step_p99_us);
  else
    EXPECT_LE(c.step_p99_us, bound) << "step lateness p99 under load";
  EXPECT_GT(c.slow_held, 0) << "no slow client got a connection";
  EXPECT_GT(c.idle_held, 0) << "no idle event stream got a connection";
}

}  // namespace
}  // namespace cylscan::test
