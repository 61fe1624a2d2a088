// SPDX-License-Identifier: Apache-2.0
// What survives the daemon's death: SIGKILL while a scan is written (at the
// moment its temporary ".partial-<id>" directory appears, and at other
// moments across the scan) and SIGTERM during a scan. After a restart on the
// same data directory the earlier scans are listed and byte-identical, the
// interrupted one is absent or failed (never "done" with files missing), and
// no temporary directory is left.
#include <chrono>
#include <functional>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "formats/point_cloud.hpp"
#include "quick_daemon.hpp"

namespace cylscan::test {
namespace {

using std::chrono::milliseconds;
using Clock = std::chrono::steady_clock;

bool isPartial(const fs::path& p) {
  return p.filename().string().rfind(".partial-", 0) == 0;
}

// The ".partial-*" entries in the data directory and one level below it
// (where a store keeps its scans); not deeper, so polling stays cheap.
std::vector<fs::path> partials(const fs::path& data) {
  std::vector<fs::path> found;
  std::error_code ec;
  for (fs::directory_iterator it(data, ec), end; !ec && it != end; it.increment(ec)) {
    if (isPartial(it->path())) {
      found.push_back(it->path());
    } else if (it->is_directory(ec)) {
      for (fs::directory_iterator sub(it->path(), ec), send; !ec && sub != send; sub.increment(ec))
        if (isPartial(sub->path())) found.push_back(sub->path());
      ec.clear();
    }
  }
  return found;
}

std::string tree(const fs::path& data) {
  std::string s;
  std::error_code ec;
  int n = 0;
  for (fs::recursive_directory_iterator it(data, ec), end; !ec && it != end && n < 60;
       it.increment(ec), ++n)
    s += "  " + fs::relative(it->path(), data).string() + "\n";
  return s;
}

struct Recorded {
  json scan;
  std::string cloud;
};

Recorded record(const HttpClient& client, const std::string& id) {
  Recorded r;
  r.scan = client.get("/api/v1/scans/" + id).json();
  r.cloud = client.get("/api/v1/scans/" + id + "/cloud.ply").body;
  return r;
}

// After a restart: the recorded scans are listed, done, byte-identical; the
// interrupted one is absent or failed with a reason, or (killed after it
// finished) done with every listed file there.
void checkAfterRestart(QuickDaemon& daemon, const std::map<std::string, Recorded>& kept,
                       const std::string& interrupted, const std::string& moment) {
  SCOPED_TRACE("killed " + moment);
  const HttpClient& client = daemon.client();
  EXPECT_TRUE(partials(daemon.data()).empty())
      << "a temporary directory is left after the restart:\n"
      << tree(daemon.data());
  // The installed calibration survives too.
  EXPECT_TRUE(client.get("/api/v1/calibration/main").body == quickCalibration());
  EXPECT_EQ(client.get("/api/v1/status").json().at("calibration").value("main", false), true);
  const json list = client.get("/api/v1/scans").json();
  ASSERT_TRUE(list.is_array()) << list.dump() << daemon.stderrTail();
  std::map<std::string, json> listed;
  for (const auto& s : list)
    listed[s.value("id", "")] = s;
  for (const auto& [id, before] : kept) {
    ASSERT_TRUE(listed.count(id)) << id << " is not listed: " << list.dump();
    EXPECT_EQ(listed[id].value("state", ""), "done") << listed[id].dump();
    EXPECT_EQ(listed[id].value("files", json()), before.scan.value("files", json()));
    EXPECT_EQ(listed[id].value("points", -1), before.scan.value("points", -2));
    const auto cloud = client.get("/api/v1/scans/" + id + "/cloud.ply");
    EXPECT_EQ(cloud.status, 200) << cloud.describe();
    EXPECT_TRUE(cloud.body == before.cloud) << id << ": cloud.ply changed";
  }
  const auto r = client.get("/api/v1/scans/" + interrupted);
  if (r.status == 404) {
    EXPECT_EQ(listed.count(interrupted), 0u);
    std::cout << "[daemon e2e] killed " << moment << ": the scan is absent\n";
    return;
  }
  ASSERT_EQ(r.status, 200) << r.describe();
  const json s = r.json();
  const std::string state = s.value("state", "");
  std::cout << "[daemon e2e] killed " << moment << ": the scan is " << state << " ("
            << s.value("error", "") << ")\n";
  EXPECT_TRUE(listed.count(interrupted)) << "GET finds it, the list does not";
  if (state == "done") {
    // Killed after it was whole: all of it must be there.
    for (const auto& f : s.at("files")) {
      const auto file = client.get("/api/v1/scans/" + interrupted + "/" + f.get<std::string>());
      EXPECT_EQ(file.status, 200) << f << " of a done scan: " << file.describe();
    }
  } else {
    EXPECT_EQ(state, "failed") << s.dump();
    EXPECT_FALSE(s.value("error", "").empty()) << "a failed scan says why: " << s.dump();
    EXPECT_EQ(client.get("/api/v1/scans/" + interrupted + "/cloud.ply").status, 404);
  }
}

TEST(DaemonPersistence, SigkillWhileWritingKeepsTheEarlierScans) {
  QuickDaemon daemon;
  std::map<std::string, Recorded> kept;
  for (int i = 0; i < 2; ++i) {
    const std::string id = startScan(daemon.client());
    ASSERT_FALSE(id.empty()) << daemon.stderrTail();
    ASSERT_EQ(finishScan(daemon.client(), id).value("state", ""), "done") << daemon.stderrTail();
    kept[id] = record(daemon.client(), id);
    ASSERT_FALSE(kept[id].cloud.empty());
  }

  // The moments to kill at: when the store's temporary directory appears;
  // while the outputs are written into it; right after the POST; after some
  // frames; when progress passes one half.
  struct Moment {
    std::string name;
    std::function<bool(const HttpClient&, const std::string&, const fs::path&)> reached;
  };
  const std::vector<Moment> moments = {
      {"when .partial-<id> appeared",
       [](const HttpClient&, const std::string& id, const fs::path& data) {
         for (const auto& p : partials(data))
           if (p.filename().string() == ".partial-" + id) return true;
         return false;
       }},
      // The outputs are written into the partial dir after the last frame,
      // scan.json last before the rename: kill in the middle of those.
      {"when the partial's texture.png appeared",
       [](const HttpClient&, const std::string& id, const fs::path& data) {
         return fs::exists(data / "scans" / (".partial-" + id) / "texture.png");
       }},
      {"when the partial's cloud.ply appeared",
       [](const HttpClient&, const std::string& id, const fs::path& data) {
         return fs::exists(data / "scans" / (".partial-" + id) / "cloud.ply");
       }},
      {"when the partial's scan.json appeared",
       [](const HttpClient&, const std::string& id, const fs::path& data) {
         return fs::exists(data / "scans" / (".partial-" + id) / "scan.json");
       }},
      {"when scans/<id> appeared (just renamed)",
       [](const HttpClient&, const std::string& id, const fs::path& data) {
         return fs::exists(data / "scans" / id);
       }},
      {"right after the POST",
       [](const HttpClient&, const std::string&, const fs::path&) { return true; }},
      {"after a few frames",
       [](const HttpClient& c, const std::string& id, const fs::path&) {
         return c.get("/api/v1/scans/" + id).json().value("frames_done", 0) >= 3;
       }},
      {"past half the scan",
       [](const HttpClient& c, const std::string& id, const fs::path&) {
         return c.get("/api/v1/scans/" + id).json().value("progress", 0.0) >= 0.5;
       }},
  };
  for (const auto& moment : moments) {
    // A moment missed (the scan was already committed when the poll looked)
    // is tried again with another scan, up to 5 times.
    std::string id;
    bool reached = false;
    for (int attempt = 0; attempt < 5 && !reached; ++attempt) {
      id = startScan(daemon.client());
      ASSERT_FALSE(id.empty()) << daemon.stderrTail();
      const fs::path committed = daemon.data() / "scans" / id;
      const auto deadline = Clock::now() + std::chrono::seconds(60);
      bool missed = false;
      while (Clock::now() < deadline && !missed &&
             !(reached = moment.reached(daemon.client(), id, daemon.data()))) {
        missed = fs::exists(committed);
        if (!missed) std::this_thread::sleep_for(std::chrono::microseconds(200));
      }
      if (reached) break;
      ASSERT_TRUE(missed) << "never " << moment.name << " within 60 s; the data directory:\n"
                          << tree(daemon.data()) << daemon.stderrTail();
      std::cout << "[daemon e2e] missed the moment " << moment.name << ", again\n";
      ASSERT_EQ(finishScan(daemon.client(), id).value("state", ""), "done");
      kept[id] = record(daemon.client(), id);
    }
    daemon.process().kill();  // at once: no request between the moment and the kill
    ASSERT_TRUE(reached) << "missed " << moment.name << " 5 times";
    daemon.start();
    checkAfterRestart(daemon, kept, id, moment.name);
    if (HasFatalFailure()) return;
    const json s = daemon.client().get("/api/v1/scans/" + id).json();
    if (s.is_object() && s.value("state", "") == "done") kept[id] = record(daemon.client(), id);
  }
  // The restarted daemon still scans.
  const std::string id = startScan(daemon.client(), {{"save_bundle", false}});
  ASSERT_FALSE(id.empty());
  EXPECT_EQ(finishScan(daemon.client(), id).value("state", ""), "done");
  daemon.stop();
}

TEST(DaemonPersistence, SigtermDuringAScanStopsCleanly) {
  QuickDaemon daemon;
  const std::string done = startScan(daemon.client(), {{"frames", 5}});
  ASSERT_EQ(finishScan(daemon.client(), done).value("state", ""), "done");
  const Recorded before = record(daemon.client(), done);

  // A long scan (2×300 frames), stopped once it has frames.
  const std::string id = startScan(daemon.client(), {{"frames", 300}});
  ASSERT_FALSE(id.empty());
  const auto deadline = Clock::now() + std::chrono::seconds(60);
  json s;
  while (Clock::now() < deadline) {
    s = daemon.client().get("/api/v1/scans/" + id).json();
    const std::string state = s.value("state", "");
    if (s.value("frames_done", 0) >= 5 || (state != "running" && state != "queued")) break;
    std::this_thread::sleep_for(milliseconds(2));
  }
  ASSERT_EQ(s.value("state", ""), "running") << "the scan should still run: " << s.dump();
  const auto sent = Clock::now();
  daemon.stop(std::chrono::seconds(15));  // exit 0 within 15 s
  std::cout << "[daemon e2e] SIGTERM during a scan: exited after "
            << std::chrono::duration<double>(Clock::now() - sent).count() << " s\n";
  if (HasFailure()) return;

  daemon.start();
  EXPECT_TRUE(partials(daemon.data()).empty()) << tree(daemon.data());
  const auto r = daemon.client().get("/api/v1/scans/" + id);
  if (r.status == 200) {
    const json after = r.json();
    EXPECT_EQ(after.value("state", ""), "failed") << after.dump();
    EXPECT_FALSE(after.value("error", "").empty()) << after.dump();
    std::cout << "[daemon e2e] after SIGTERM the scan is " << after.value("state", "") << ": "
              << after.value("error", "") << "\n";
  } else {
    EXPECT_EQ(r.status, 404) << r.describe();
  }
  const auto cloud = daemon.client().get("/api/v1/scans/" + done + "/cloud.ply");
  EXPECT_TRUE(cloud.body == before.cloud) << "the earlier scan changed";
  EXPECT_EQ(daemon.client().get("/api/v1/status").json().value("state", ""), "idle");
  daemon.stop();
}

}  // namespace
}  // namespace cylscan::test
