// SPDX-License-Identifier: Apache-2.0
// The data directory: a scan appears whole or not at all, leftovers of a crash
// are cleaned, unusable records are set aside, retention removes the oldest.
#include "firmware/daemon/scan_store.hpp"

#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "tests/support/temp_dir.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test_support::TempDir;

ScanRecord record(const std::string& id, const std::string& created,
                  ScanState state = ScanState::kDone) {
  ScanRecord r;
  r.id = id;
  r.state = state;
  r.created = created;
  return r;
}

// A scan with one file of `bytes` bytes, committed.
void addScan(ScanStore& store, const std::string& id, const std::string& created,
             std::size_t bytes = 10) {
  const fs::path partial = store.beginScan(id);
  std::ofstream(partial / "texture.png") << std::string(bytes, 'x');
  store.commit(record(id, created));
}

std::vector<std::string> ids(const ScanStore& store) {
  std::vector<std::string> out;
  for (const auto& s : store.list())
    out.push_back(s.id);
  return out;
}

TEST(ScanStore, APartialScanIsNotListedAndIsCleanedOnReopen) {
  TempDir dir;
  {
    ScanStore store(dir.path());
    const fs::path partial = store.beginScan("20261201-100000-0001");
    std::ofstream(partial / "texture.png") << "half";
    EXPECT_EQ(store.count(), 0u);
    EXPECT_FALSE(store.get("20261201-100000-0001"));
    EXPECT_FALSE(store.file("20261201-100000-0001", "texture.png"));
    // The "crash": the store goes away without a commit.
  }
  EXPECT_TRUE(fs::exists(dir.path() / "scans/.partial-20261201-100000-0001"));
  ScanStore reopened(dir.path());
  EXPECT_EQ(reopened.count(), 0u);
  EXPECT_FALSE(fs::exists(dir.path() / "scans/.partial-20261201-100000-0001"));
}

TEST(ScanStore, ACommittedScanIsListedWithItsFilesAndSurvivesReopen) {
  TempDir dir;
  {
    ScanStore store(dir.path());
    addScan(store, "20261201-100000-0001", "2026-12-01T10:00:00Z", 100);
    ASSERT_TRUE(store.get("20261201-100000-0001"));
    EXPECT_EQ(store.get("20261201-100000-0001")->state, ScanState::kDone);
    const auto file = store.file("20261201-100000-0001", "texture.png");
    ASSERT_TRUE(file);
    EXPECT_EQ(fs::file_size(*file), 100u);
    EXPECT_FALSE(store.file("20261201-100000-0001", "cloud.ply"));     // not written
    EXPECT_FALSE(store.file("20261201-100000-0001", "../scan.json"));  // not a file name
    EXPECT_FALSE(store.file("../20261201-100000-0001", "scan.json"));  // not an id
    EXPECT_GE(store.totalBytes(), 100u);
  }
  ScanStore reopened(dir.path());
  EXPECT_EQ(ids(reopened), std::vector<std::string>{"20261201-100000-0001"});
  EXPECT_TRUE(reopened.file("20261201-100000-0001", "scan.json"));
}

TEST(ScanStore, AFailedScanKeepsOnlyItsRecord) {
  TempDir dir;
  ScanStore store(dir.path());
  const fs::path partial = store.beginScan("20261201-100000-0002");
  std::ofstream(partial / "texture.png") << "x";
  ScanRecord failed = record("20261201-100000-0002", "2026-12-01T10:00:00Z", ScanState::kFailed);
  failed.error = "home switch never fired";
  store.commit(failed, /*keep_files=*/false);
  EXPECT_FALSE(store.file("20261201-100000-0002", "texture.png"));
  EXPECT_EQ(store.get("20261201-100000-0002")->error, "home switch never fired");
}

TEST(ScanStore, ACorruptRecordIsSetAsideAndTheOthersKept) {
  TempDir dir;
  {
    ScanStore store(dir.path());
    addScan(store, "20261201-100000-0001", "2026-12-01T10:00:00Z");
    addScan(store, "20261201-100000-0002", "2026-12-01T10:00:01Z");
    addScan(store, "20261201-100000-0003", "2026-12-01T10:00:02Z");
  }
  std::ofstream(dir.path() / "scans/20261201-100000-0002/scan.json", std::ios::trunc)
      << "{\"id\": ";
  fs::remove(dir.path() / "scans/20261201-100000-0003/scan.json");
  ScanStore reopened(dir.path());
  EXPECT_EQ(ids(reopened), std::vector<std::string>{"20261201-100000-0001"});
  EXPECT_TRUE(fs::exists(dir.path() / "scans/.broken-20261201-100000-0002/texture.png"));
  EXPECT_TRUE(fs::exists(dir.path() / "scans/.broken-20261201-100000-0003"));
  // Set aside once: a second open finds the same.
  ScanStore again(dir.path());
  EXPECT_EQ(again.count(), 1u);
}

TEST(ScanStore, ARecordOfTheWrongShapeIsSetAsideAndAnEarlierOneKept) {
  TempDir dir;
  const auto scanDir = [&](const std::string& id, const json& record) {
    fs::create_directories(dir.path() / "scans" / id);
    std::ofstream(dir.path() / "scans" / id / "scan.json") << record.dump();
  };
  const std::string created = "2026-12-01T10:00:00Z";
  scanDir("20261201-100000-0001", {{"id", "20261201-100000-0001"},
                                   {"state", "done"},
                                   {"created", created}});  // an earlier version's
  scanDir("20261201-100000-0002",
          {{"id", "20261201-100000-0002"}, {"state", "running"}, {"created", created}});
  scanDir(
      "20261201-100000-0003",
      {{"id", "20261201-100000-0003"}, {"state", "done"}, {"created", created}, {"frames", "ten"}});
  scanDir("20261201-100000-0004",
          {{"id", "20261201-100000-0009"}, {"state", "done"}, {"created", created}});
  ScanStore store(dir.path());
  EXPECT_EQ(ids(store), std::vector<std::string>{"20261201-100000-0001"});
  for (const char* broken : {"0002", "0003", "0004"})
    EXPECT_TRUE(
        fs::exists(dir.path() / "scans" / (".broken-20261201-100000-" + std::string(broken))))
        << broken;
  EXPECT_EQ(store.get("20261201-100000-0001")->created, created);
  // A scan that has not finished is no record to store.
  ScanRecord running = record("20261201-100000-0005", created, ScanState::kRunning);
  store.beginScan(running.id);
  EXPECT_THROW(store.commit(running), std::invalid_argument);
}

TEST(ScanStore, ListsNewestFirstAndDeletes) {
  TempDir dir;
  ScanStore store(dir.path());
  addScan(store, "20261201-100002-0000", "2026-12-01T10:00:02Z");
  addScan(store, "20261201-100000-0000", "2026-12-01T10:00:00Z");
  addScan(store, "20261201-100001-0000", "2026-12-01T10:00:01Z");
  EXPECT_EQ(ids(store), (std::vector<std::string>{"20261201-100002-0000", "20261201-100001-0000",
                                                  "20261201-100000-0000"}));
  EXPECT_TRUE(store.remove("20261201-100001-0000"));
  EXPECT_FALSE(store.remove("20261201-100001-0000"));
  EXPECT_FALSE(fs::exists(dir.path() / "scans/20261201-100001-0000"));
  EXPECT_EQ(store.count(), 2u);
}

TEST(ScanStore, RetentionByCountRemovesTheOldest) {
  TempDir dir;
  ScanStore store(dir.path());
  for (int i = 0; i < 5; ++i)
    addScan(store, "20261201-10000" + std::to_string(i) + "-0000",
            "2026-12-01T10:00:0" + std::to_string(i) + "Z");
  const auto removed = store.applyRetention({3, 0}, "20261201-100004-0000");
  EXPECT_EQ(removed, (std::vector<std::string>{"20261201-100000-0000", "20261201-100001-0000"}));
  EXPECT_EQ(ids(store), (std::vector<std::string>{"20261201-100004-0000", "20261201-100003-0000",
                                                  "20261201-100002-0000"}));
  EXPECT_TRUE(store.applyRetention({0, 0}, "").empty());  // no limits
}

TEST(ScanStore, RetentionByBytesRemovesTheOldestButNeverTheNewScan) {
  TempDir dir;
  ScanStore store(dir.path());
  addScan(store, "20261201-100000-0000", "2026-12-01T10:00:00Z", 1000);
  addScan(store, "20261201-100001-0000", "2026-12-01T10:00:01Z", 1000);
  addScan(store, "20261201-100002-0000", "2026-12-01T10:00:02Z", 1000);
  const std::uint64_t one = store.totalBytes() / 3;
  // Room for two: the oldest goes.
  auto removed = store.applyRetention({0, 2 * one + one / 2}, "20261201-100002-0000");
  EXPECT_EQ(removed, std::vector<std::string>{"20261201-100000-0000"});
  // Room for less than one: everything but the new scan goes.
  removed = store.applyRetention({0, one / 2}, "20261201-100002-0000");
  EXPECT_EQ(removed, std::vector<std::string>{"20261201-100001-0000"});
  EXPECT_EQ(ids(store), std::vector<std::string>{"20261201-100002-0000"});
}

TEST(ScanStore, CalibrationIsInstalledAtomicallyInItsPlace) {
  TempDir dir;
  ScanStore store(dir.path());
  const std::string bytes = "calibration bytes";
  store.installCalibration("main", std::as_bytes(std::span(bytes.data(), bytes.size())));
  const fs::path file = store.calibrationPath("main");
  EXPECT_EQ(file, dir.path() / "calibration/main.qcal");
  std::ifstream in(file);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), bytes);
  EXPECT_THROW(store.calibrationPath("../main"), std::invalid_argument);
  // No temporary left beside it.
  int entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path() / "calibration"))
    ++entries;
  EXPECT_EQ(entries, 1);
}

TEST(ScanStore, ReportsFreeSpace) {
  TempDir dir;
  ScanStore store(dir.path());
  EXPECT_GT(store.freeBytes(), 0u);
}

}  // namespace
}  // namespace cylscan::firmware
