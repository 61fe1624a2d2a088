// SPDX-License-Identifier: Apache-2.0
// PUT /api/v1/system/update end to end: a real HttpApi, the update's real
// service (firmware/daemon/update_service.hpp) behind it, RAUC scripted by a
// fake. Every refusal leaves nothing behind; a bundle is streamed to its
// file, checked, installed in the background, recorded and followed by the
// reboot request.
#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "firmware/daemon/update_service.hpp"
#include "tests/http/http_test_support.hpp"
#include "tests/support/fake_update_installer.hpp"
#include "tests/support/temp_dir.hpp"

namespace cylscan::test_support {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using firmware::ServiceError;
using firmware::UpdateService;

// The fake head with a real update service; `scanning` stands for a scan.
class UpdateHead : public FakeService {
 public:
  UpdateHead(const fs::path& data_dir, std::shared_ptr<FakeUpdateInstaller> installer,
             firmware::UpdateOptions options) {
    options.data_dir = data_dir;
    options.boot_id = data_dir / "boot_id";
    options.command_line = data_dir / "cmdline";
    updates = std::make_unique<UpdateService>(
        options, std::move(installer),
        [this](const std::string& name, const json& data) {
          std::lock_guard lock(events_mutex);
          events.push_back({name, data});
        },
        [this] {
          if (scanning) throw ServiceError(409, "scan 20261201-160102-3f9a is running");
        });
  }
  std::unique_ptr<firmware::UpdateUpload> beginUpdate(std::uint64_t bytes) override {
    return updates->begin(bytes);
  }
  std::vector<std::pair<std::string, json>> eventsSeen() {
    std::lock_guard lock(events_mutex);
    return events;
  }

  std::atomic<bool> scanning{false};
  std::mutex events_mutex;
  std::vector<std::pair<std::string, json>> events;
  // Declared after what its callbacks use, so that it is destroyed first: its
  // destructor joins the install thread, which may still be publishing.
  std::unique_ptr<UpdateService> updates;
};

class UpdateApi : public ::testing::Test {
 protected:
  void SetUp() override { start({}); }
  void TearDown() override {
    api.reset();
    head.reset();
  }
  void start(const firmware::UpdateOptions& options) {
    api.reset();
    head.reset();
    head = std::make_unique<UpdateHead>(data.path(), installer, options);
    http.port = 0;
    http.token = "secret";
    api = std::make_unique<firmware::HttpApi>(*head, http);
  }
  std::string url() const {
    return "http://127.0.0.1:" + std::to_string(api->port()) + "/api/v1/system/update";
  }
  HttpResult put(const std::string& bundle, bool token = true) const {
    RequestOptions o;
    if (token) o.headers.emplace_back("Authorization: Bearer secret");
    o.headers.emplace_back("Content-Type: application/octet-stream");
    o.body = bundle;
    o.has_body = true;
    return curlRequest("PUT", url(), o);
  }
  fs::path dir() const { return data.path() / "update"; }
  json record() const {
    std::ifstream in(dir() / "last.json");
    return json::parse(in, nullptr, false);
  }
  // Nothing of an upload left behind, and no record written.
  void expectNothingChanged() const {
    EXPECT_FALSE(fs::exists(dir() / "bundle.raucb.part"));
    EXPECT_FALSE(fs::exists(dir() / "bundle.raucb"));
    EXPECT_FALSE(fs::exists(dir() / "last.json"));
    EXPECT_FALSE(fs::exists(dir() / "reboot-request"));
    EXPECT_TRUE(installer->installs.empty());
  }

  TempDir data;
  std::shared_ptr<FakeUpdateInstaller> installer = std::make_shared<FakeUpdateInstaller>();
  std::unique_ptr<UpdateHead> head;
  firmware::HttpOptions http;
  std::unique_ptr<firmware::HttpApi> api;
};

TEST_F(UpdateApi, InstallsAStreamedBundleRecordsItAndAsksForTheReboot) {
  // Larger than the 64 KiB of a JSON body: this endpoint streams.
  const std::string bundle(300000, 'x');
  const HttpResult r = put(bundle);
  ASSERT_EQ(r.status, 202) << r.body;
  EXPECT_EQ(r.bodyJson()["state"], "installing");
  EXPECT_EQ(r.bodyJson()["version"], "1.2.3");
  EXPECT_EQ(r.bodyJson()["target_slot"], "b");
  ASSERT_TRUE(head->updates->waitUntilIdle(10s));
  ASSERT_EQ(installer->installed_bytes.size(), 1u);
  EXPECT_EQ(installer->installed_bytes[0], bundle);  // every byte, in order
  const json last = record();
  EXPECT_EQ(last["result"], "installed");
  EXPECT_EQ(last["version"], "1.2.3");
  EXPECT_EQ(last["target_slot"], "b");
  EXPECT_TRUE(fs::exists(dir() / "reboot-request"));
  EXPECT_FALSE(fs::exists(dir() / "bundle.raucb"));  // deleted after the install
  // Events: receiving, installing with RAUC's progress, idle with the record.
  bool receiving = false, progress40 = false, finished = false;
  // The last event follows the idle state: wait for it.
  for (int i = 0; i < 250 && head->eventsSeen().back().second["state"] != "idle"; ++i)
    std::this_thread::sleep_for(20ms);
  for (const auto& [name, e] : head->eventsSeen()) {
    ASSERT_EQ(name, "update");
    if (e["state"] == "receiving") receiving = true;
    if (e["state"] == "installing" && e["progress"] == 40) progress40 = true;
    if (e["state"] == "idle" && e["last"].is_object() && e["last"]["result"] == "installed")
      finished = true;
  }
  EXPECT_TRUE(receiving);
  EXPECT_TRUE(progress40);
  EXPECT_TRUE(finished);
}

TEST_F(UpdateApi, NoRebootRequestWhenTurnedOff) {
  firmware::UpdateOptions o;
  o.reboot = false;
  start(o);
  ASSERT_EQ(put("bundle").status, 202);
  ASSERT_TRUE(head->updates->waitUntilIdle(10s));
  EXPECT_EQ(record()["result"], "installed");
  EXPECT_FALSE(fs::exists(dir() / "reboot-request"));
}

TEST_F(UpdateApi, AFailedInstallIsRecordedWithRaucsError) {
  installer->install_error = "Failed to mount bundle: bad magic";
  ASSERT_EQ(put("bundle").status, 202);
  ASSERT_TRUE(head->updates->waitUntilIdle(10s));
  EXPECT_EQ(record()["result"], "failed");
  EXPECT_EQ(record()["message"], "Failed to mount bundle: bad magic");
  EXPECT_FALSE(fs::exists(dir() / "reboot-request"));
  EXPECT_FALSE(fs::exists(dir() / "bundle.raucb"));
}

TEST_F(UpdateApi, NeedsTheToken) {
  const HttpResult r = put("bundle", false);
  EXPECT_EQ(r.status, 401);
  expectNothingChanged();
}

TEST_F(UpdateApi, NeedsAContentLength) {
  RawSocket s("127.0.0.1", api->port());
  ASSERT_TRUE(
      s.send("PUT /api/v1/system/update HTTP/1.1\r\nHost: x\r\n"
             "Authorization: Bearer secret\r\nTransfer-Encoding: chunked\r\n\r\n"
             "6\r\nbundle\r\n0\r\n\r\n"));
  EXPECT_NE(s.readHead().find(" 411 "), std::string::npos);
  RawSocket t("127.0.0.1", api->port());
  ASSERT_TRUE(
      t.send("PUT /api/v1/system/update HTTP/1.1\r\nHost: x\r\n"
             "Authorization: Bearer secret\r\n\r\n"));
  EXPECT_NE(t.readHead().find(" 411 "), std::string::npos);
  expectNothingChanged();
}

TEST_F(UpdateApi, RefusesABundleOverTheLimit) {
  firmware::UpdateOptions o;
  o.max_bundle_bytes = 1000;
  start(o);
  const HttpResult r = put(std::string(1001, 'x'));
  EXPECT_EQ(r.status, 413);
  EXPECT_NE(r.body.find("update.max_bundle_bytes"), std::string::npos) << r.body;
  expectNothingChanged();
}

TEST_F(UpdateApi, RefusesABundleThatLeavesTooLittleFreeSpace) {
  firmware::UpdateOptions o;
  o.reserve_bytes = std::uint64_t{1} << 60;  // more than any disk has
  start(o);
  const HttpResult r = put("bundle");
  EXPECT_EQ(r.status, 507);
  EXPECT_NE(r.body.find("does not fit"), std::string::npos) << r.body;
  expectNothingChanged();
}

TEST_F(UpdateApi, ATruncatedUploadIsRemovedAndRecordedFailed) {
  {
    RawSocket s("127.0.0.1", api->port());
    ASSERT_TRUE(
        s.send("PUT /api/v1/system/update HTTP/1.1\r\nHost: x\r\n"
               "Authorization: Bearer secret\r\nContent-Length: 100000\r\n"
               "Content-Type: application/octet-stream\r\n\r\n"));
    ASSERT_TRUE(s.send(std::string(5000, 'x')));
    // The part file exists while the upload is received.
    for (int i = 0; i < 100 && !fs::exists(dir() / "bundle.raucb.part"); ++i)
      std::this_thread::sleep_for(20ms);
    EXPECT_TRUE(fs::exists(dir() / "bundle.raucb.part"));
  }  // closed before the 100000 bytes
  ASSERT_TRUE(head->updates->waitUntilIdle(10s));
  for (int i = 0; i < 100 && !fs::exists(dir() / "last.json"); ++i)
    std::this_thread::sleep_for(20ms);
  EXPECT_FALSE(fs::exists(dir() / "bundle.raucb.part"));
  EXPECT_EQ(record()["result"], "failed");
  EXPECT_NE(record()["message"].get<std::string>().find("truncated upload"), std::string::npos);
  EXPECT_TRUE(installer->installs.empty());
  // The next upload is taken.
  EXPECT_EQ(put("bundle").status, 202);
}

TEST_F(UpdateApi, ABadSignatureIs422WithRaucsMessage) {
  installer->info_error = "signature verification failed: certificate not trusted";
  const HttpResult r = put("bundle");
  EXPECT_EQ(r.status, 422);
  EXPECT_NE(r.body.find("certificate not trusted"), std::string::npos) << r.body;
  expectNothingChanged();
}

TEST_F(UpdateApi, ABundleForAnotherHeadIs422) {
  installer->bundle_compatible = "cylscan-rpi4";
  const HttpResult r = put("bundle");
  EXPECT_EQ(r.status, 422);
  EXPECT_EQ(r.bodyJson()["error"], "bundle is for cylscan-rpi4, this head is cylscan-sim");
  expectNothingChanged();
}

TEST_F(UpdateApi, RefusedDuringAScan) {
  head->scanning = true;
  const HttpResult r = put("bundle");
  EXPECT_EQ(r.status, 409);
  EXPECT_NE(r.body.find("running"), std::string::npos);
  expectNothingChanged();
  EXPECT_FALSE(head->updates->busy());  // the claim was given back
}

TEST_F(UpdateApi, RefusedDuringAnInstall) {
  installer->hold_install = true;
  ASSERT_EQ(put("first").status, 202);
  ASSERT_TRUE(installer->waitForInstalls(1, 10s));
  EXPECT_TRUE(head->updates->busy());
  EXPECT_EQ(head->updates->report()["update"]["state"], "installing");
  const HttpResult r = put("second");
  EXPECT_EQ(r.status, 409);
  EXPECT_EQ(r.bodyJson()["error"], "an update is being installed");
  installer->release();
  ASSERT_TRUE(head->updates->waitUntilIdle(10s));
  EXPECT_EQ(installer->installs.size(), 1u);
}

TEST_F(UpdateApi, WithoutRaucIs503) {
  installer->available = false;
  const HttpResult r = put("bundle");
  EXPECT_EQ(r.status, 503);
  EXPECT_NE(r.body.find("updates need RAUC"), std::string::npos) << r.body;
  expectNothingChanged();
  const json report = head->updates->report();
  EXPECT_EQ(report["updates"], false);
  EXPECT_EQ(report["slots"], json::array());
}

TEST_F(UpdateApi, ReportsTheSlots) {
  const json report = head->updates->report();
  EXPECT_EQ(report["updates"], true);
  ASSERT_EQ(report["slots"].size(), 2u);
  EXPECT_EQ(report["slots"][0]["bootname"], "a");
  EXPECT_EQ(report["slots"][0]["state"], "booted");
  EXPECT_EQ(report["slots"][0]["version"], "1.0.0");
  EXPECT_EQ(report["slots"][1]["state"], "inactive");
  EXPECT_EQ(report["update"]["state"], "idle");
  EXPECT_EQ(report["update"]["last"], nullptr);
}

}  // namespace
}  // namespace cylscan::test_support
