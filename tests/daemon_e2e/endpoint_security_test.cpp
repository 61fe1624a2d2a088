// SPDX-License-Identifier: Apache-2.0
// Security of the endpoint on a running cylscand (docs/robustness.md), the parts the
// other daemon_e2e suites leave: oversized headers, bodies and calibration
// uploads are refused without the daemon's memory growing (its VmRSS from
// /proc/PID/status before and after a thousand of them), and the daemon
// binds only the address it was given.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "quick_daemon.hpp"

namespace cylscan::test {
namespace {

// Resident memory of a process in bytes (VmRSS of /proc/PID/status).
std::uint64_t residentBytes(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stoull(line.substr(6)) * 1024;  // kB
  }
  throw std::runtime_error("no VmRSS for process " + std::to_string(pid));
}

// True when a TCP connection to address:port is accepted.
bool connects(const std::string& address, int port) {
  const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return false;
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  inet_pton(AF_INET, address.c_str(), &a.sin_addr);
  const bool ok = connect(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a) == 0;
  close(fd);
  return ok;
}

// 1000 requests over the limits: a 100 KiB JSON body (limit 64 KiB: 413), a
// 9 KiB header (limit 8 KiB: 431) and a 200 kB calibration (limit 64 KiB
// here: 413), in turn. They carry ~100 MB in all; a daemon that kept any
// part of each would grow by tens of MB. The bound, 16 MiB of resident
// memory after a warm-up of 60 such requests, leaves room for the
// allocator's arenas and libmicrohttpd's connection pool, which a warm-up
// does not fully reach, and is still far below what keeping the bodies
// would take.
TEST(DaemonEndpoint, OversizedRequestsAreRefusedWithoutMemoryGrowth) {
  TempDir config_dir;
  const fs::path config =
      config_dir.write("cylscan.toml", "[daemon]\nmax_calibration_bytes = 65536\n");
  QuickDaemon daemon(DaemonSetup({"--config", config.string()}, /*calibrate=*/false));
  const HttpClient& client = daemon.client();
  const std::string body =
      "{\"mode\": \"stop\", \"pad\": \"" + std::string(100 * 1024, 'x') + "\"}";
  const std::string header = "X-Padding: " + std::string(9 * 1024, 'h');
  const std::string calibration = quickCalibration().substr(0, 200000);
  int wrong = 0;
  std::string first_wrong;
  auto one = [&](int i) {
    HttpResponse r;
    long expected = 0;
    switch (i % 3) {
      case 0:
        r = client.post("/api/v1/scans", body, {"Content-Type: application/json"});
        expected = 413;
        break;
      case 1:
        r = client.get("/api/v1/status", {header});
        expected = 431;
        break;
      default:
        r = client.put("/api/v1/calibration", calibration);
        expected = 413;
        break;
    }
    // A body refused before it is read may also end with the connection
    // closed while the client still sends it (the refusal comes first and
    // libmicrohttpd closes without draining): refused all the same.
    const bool closed_while_sending =
        r.status == 0 && expected == 413 && r.curl_error == curl_easy_strerror(CURLE_SEND_ERROR);
    if (r.status != expected && !closed_while_sending) {
      if (wrong++ == 0) first_wrong = std::to_string(i) + ": " + r.describe();
    }
  };
  for (int i = 0; i < 60; ++i)
    one(i);
  const std::uint64_t before = residentBytes(daemon.process().pid());
  for (int i = 0; i < 1000; ++i)
    one(i);
  const std::uint64_t after = residentBytes(daemon.process().pid());
  EXPECT_EQ(wrong, 0) << "requests not refused as expected, the first: " << first_wrong;
  const double growth_mib = (static_cast<double>(after) - static_cast<double>(before)) / 1048576.0;
  std::printf(
      "[ memory   ] cylscand VmRSS %.1f MiB before, %.1f MiB after 1000 oversized "
      "requests (%+.2f MiB)\n",
      before / 1048576.0, after / 1048576.0, growth_mib);
  EXPECT_LT(growth_mib, 16.0) << "the daemon's resident memory grew by " << growth_mib << " MiB";
  // Nothing was stored, and the daemon goes on serving.
  EXPECT_EQ(client.get("/api/v1/scans").json().size(), 0u);
  EXPECT_EQ(client.get("/api/v1/calibration/main").status, 404);
  EXPECT_EQ(client.get("/api/v1/status").status, 200);
  EXPECT_TRUE(daemon.process().running()) << daemon.stderrTail();
  daemon.stop();
}

// --listen 127.0.0.1:0: the port is open on 127.0.0.1 and on no other
// loopback address (127.0.0.2 is loopback too, so a wildcard bind would
// accept there).
TEST(DaemonEndpoint, BindsOnlyWhereConfigured) {
  QuickDaemon daemon(DaemonSetup({}, /*calibrate=*/false));
  const int port = daemon.process().port();
  EXPECT_TRUE(connects("127.0.0.1", port));
  EXPECT_FALSE(connects("127.0.0.2", port)) << "cylscand answers on 127.0.0.2:" << port;
  EXPECT_NE(daemon.process().firstLine().find("127.0.0.1:" + std::to_string(port)),
            std::string::npos)
      << daemon.process().firstLine();
  daemon.stop();
}

}  // namespace
}  // namespace cylscan::test
