// SPDX-License-Identifier: Apache-2.0
// The update's record at start (booted, rolled back, left alone in the same
// boot) and the interlock between an update and a scan on the virtual head.
#include "firmware/daemon/update_service.hpp"

#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>

#include <gtest/gtest.h>

#include "firmware/daemon/scan_service.hpp"
#include "tests/daemon/service_test_support.hpp"
#include "tests/support/fake_update_installer.hpp"
#include "tests/support/small_board.hpp"
#include "tests/support/temp_dir.hpp"

namespace cylscan::firmware {
namespace {

using nlohmann::json;
using test_support::errorOf;
namespace fs = std::filesystem;
using namespace std::chrono_literals;
using test_support::FakeUpdateInstaller;
using test_support::TempDir;

UpdateRecord installedInto(const std::string& slot, const std::string& boot_id) {
  UpdateRecord r;
  r.version = "2.0.0";
  r.target_slot = slot;
  r.result = "installed";
  r.boot_id = boot_id;
  return r;
}

TEST(UpdateRecord, SettlesByTheBootedSlotAfterAReboot) {
  const UpdateRecord booted = settleUpdateRecord(installedInto("b", "boot1"), "b", "boot2", "t");
  EXPECT_EQ(booted.result, "booted");
  const UpdateRecord back = settleUpdateRecord(installedInto("b", "boot1"), "a", "boot2", "t");
  EXPECT_EQ(back.result, "rolled back");
  EXPECT_EQ(back.message, "the new slot did not come up; the head went back to slot a");
  EXPECT_EQ(back.time, "t");
}

TEST(UpdateRecord, StaysInstalledUntilTheReboot) {
  const UpdateRecord same = settleUpdateRecord(installedInto("b", "boot1"), "a", "boot1", "t");
  EXPECT_EQ(same.result, "installed");
}

TEST(UpdateRecord, AnInstallCutShortByTheDaemonIsFailed) {
  UpdateRecord r = installedInto("b", "boot1");
  r.result = "installing";
  EXPECT_EQ(settleUpdateRecord(r, "a", "boot2", "t").result, "failed");
  r.result = "failed";
  r.message = "x";
  EXPECT_EQ(settleUpdateRecord(r, "a", "boot2", "t").message, "x");  // final: unchanged
}

TEST(UpdateRecord, ReadsWhatItWrites) {
  TempDir dir;
  UpdateRecord r = installedInto("b", "boot1");
  r.message = "rebooting";
  r.time = "2026-12-06T07:00:00Z";
  writeUpdateRecord(dir.path() / "last.json", r);
  const auto back = readUpdateRecord(dir.path() / "last.json");
  ASSERT_TRUE(back);
  EXPECT_EQ(back->toJson(), r.toJson());
  dir.write("bad.json", "{not json");
  EXPECT_FALSE(readUpdateRecord(dir.path() / "bad.json"));
}

// A daemon start over DATA/update as a past boot left it.
class UpdateStart : public ::testing::Test {
 protected:
  json startWith(const UpdateRecord& record, const std::string& booted,
                 const std::string& boot_id) {
    fs::create_directories(data.path() / "update");
    writeUpdateRecord(data.path() / "update" / "last.json", record);
    data.write("update/reboot-request", "{}\n");
    data.write("boot_id", boot_id + "\n");
    installer->booted = booted;
    UpdateOptions o;
    o.data_dir = data.path();
    o.boot_id = data.path() / "boot_id";
    o.command_line = data.path() / "cmdline";
    UpdateService service(o, installer, nullptr, nullptr);
    const auto stored = readUpdateRecord(data.path() / "update" / "last.json");
    EXPECT_TRUE(stored);
    EXPECT_EQ(service.report()["update"]["last"]["result"], stored ? stored->result : "");
    return service.report()["update"]["last"];
  }
  TempDir data;
  std::shared_ptr<FakeUpdateInstaller> installer = std::make_shared<FakeUpdateInstaller>();
};

TEST_F(UpdateStart, TheNewSlotCameUp) {
  const json last = startWith(installedInto("b", "boot1"), "b", "boot2");
  EXPECT_EQ(last["result"], "booted");
  EXPECT_FALSE(last.contains("boot_id"));
  EXPECT_FALSE(fs::exists(data.path() / "update" / "reboot-request"));  // served
}

TEST_F(UpdateStart, TheHeadWentBack) {
  const json last = startWith(installedInto("b", "boot1"), "a", "boot2");
  EXPECT_EQ(last["result"], "rolled back");
  EXPECT_EQ(last["message"], "the new slot did not come up; the head went back to slot a");
}

TEST_F(UpdateStart, ARestartBeforeTheRebootChangesNothing) {
  const json last = startWith(installedInto("b", "boot1"), "a", "boot1");
  EXPECT_EQ(last["result"], "installed");
  EXPECT_TRUE(fs::exists(data.path() / "update" / "reboot-request"));  // still to be served
}

TEST_F(UpdateStart, WithoutRaucTheKernelCommandLineSaysTheSlot) {
  installer->available = false;
  data.write("cmdline", "console=ttyAMA0 rauc.slot=b\n");
  fs::create_directories(data.path() / "update");
  writeUpdateRecord(data.path() / "update" / "last.json", installedInto("b", "boot1"));
  data.write("boot_id", "boot2\n");
  UpdateOptions o;
  o.data_dir = data.path();
  o.boot_id = data.path() / "boot_id";
  o.command_line = data.path() / "cmdline";
  const UpdateService service(o, installer, nullptr, nullptr);
  EXPECT_EQ(readUpdateRecord(data.path() / "update" / "last.json")->result, "booted");
}

// The service on the virtual head: a scan and an update exclude each other.
class UpdateAndScan : public ::testing::Test {
 protected:
  void SetUp() override {
    board = test_support::smallBoard(board_dir, test_support::kWallScene);
    ScanServiceOptions o = test_support::serviceOptions(board, data.path());
    o.installer = installer;
    o.boot_id = data.path() / "boot_id";
    service = std::make_unique<ScanService>(o);
  }
  TempDir board_dir, data;
  fs::path board;
  std::shared_ptr<FakeUpdateInstaller> installer = std::make_shared<FakeUpdateInstaller>();
  std::unique_ptr<ScanService> service;
};

TEST_F(UpdateAndScan, AnUpdateWaitsForTheScan) {
  const std::string id = service->startScan(json::object());
  const ServiceError e = errorOf([&] { (void)service->beginUpdate(100); });
  EXPECT_EQ(e.httpStatus(), 409);
  EXPECT_NE(std::string(e.what()).find(id), std::string::npos) << e.what();
  EXPECT_FALSE(service->updates().busy());
  ASSERT_TRUE(service->waitUntilIdle(300s));
}

TEST_F(UpdateAndScan, AScanWaitsForTheUpdate) {
  installer->hold_install = true;
  {
    auto upload = service->beginUpdate(6);
    const ServiceError receiving = errorOf([&] { (void)service->startScan(json::object()); });
    EXPECT_EQ(receiving.httpStatus(), 409);
    EXPECT_STREQ(receiving.what(), "an update is being received");
    upload->write("bundle");
    EXPECT_EQ(upload->finish()["state"], "installing");
  }
  ASSERT_TRUE(installer->waitForInstalls(1, 10s));
  const ServiceError installing = errorOf([&] { (void)service->startScan(json::object()); });
  EXPECT_EQ(installing.httpStatus(), 409);
  EXPECT_STREQ(installing.what(), "an update is being installed");
  const json system = service->system();
  EXPECT_EQ(system["update"]["state"], "installing");
  EXPECT_EQ(system["updates"], true);
  EXPECT_EQ(system["slots"].size(), 2u);
  EXPECT_TRUE(system.contains("hostname"));  // the existing keys stay
  installer->release();
  ASSERT_TRUE(service->updates().waitUntilIdle(10s));
  EXPECT_EQ(service->system()["update"]["last"]["result"], "installed");
  EXPECT_TRUE(fs::exists(data.path() / "update" / "reboot-request"));
  const std::string id = service->startScan(json::object());  // free again
  EXPECT_FALSE(id.empty());
  ASSERT_TRUE(service->waitUntilIdle(300s));
}

}  // namespace
}  // namespace cylscan::firmware
