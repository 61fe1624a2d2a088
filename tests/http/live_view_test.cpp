// SPDX-License-Identifier: Apache-2.0
// The cameras' endpoints of the HTTP layer on a scripted service: the list,
// PATCH of the controls, snapshot.jpg (a suspended request answered when the
// picture comes) and stream.mjpg (multipart parts, the end when a scan
// starts, a client that goes away), with their error paths.
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "firmware/http/http_api.hpp"
#include "tests/http/http_test_support.hpp"

namespace cylscan::firmware {
namespace {

using nlohmann::json;
using test_support::countOf;
using test_support::curlRequest;
using test_support::eventually;
using test_support::FakeService;
using test_support::RawSocket;
using test_support::RequestOptions;
using test_support::statusOf;

constexpr const char* kToken = "camera-token-0123456789";
const std::string kAuth = std::string("Authorization: Bearer ") + kToken;

LiveFrame picture(std::uint64_t sequence, std::string jpeg) {
  LiveFrame f;
  f.sequence = sequence;
  f.jpeg = std::move(jpeg);
  f.focus = 12.5;
  f.saturated = 0.25;
  return f;
}

class LiveViewTest : public test_support::TokenApiTest {
 protected:
  LiveViewTest() : TokenApiTest(kToken) {}
  std::unique_ptr<RawSocket> rawGet(const std::string& path) {
    auto s = std::make_unique<RawSocket>("127.0.0.1", api->port());
    EXPECT_TRUE(s->ok());
    s->send("GET " + path + " HTTP/1.1\r\nHost: x\r\n" + kAuth + "\r\n\r\n");
    return s;
  }
  // The one live view the HTTP layer opened, once it has.
  std::shared_ptr<test_support::FakeLiveFeed> feed() {
    std::shared_ptr<test_support::FakeLiveFeed> out;
    eventually([&] {
      auto feeds = service.liveFeeds();
      if (feeds.size() == 1) out = feeds.front();
      return out != nullptr;
    });
    return out;
  }
};

TEST_F(LiveViewTest, CamerasListIsTheServices) {
  service.cameras_json = json::array({json{{"name", "main"}, {"width", 8}}});
  EXPECT_EQ(curlRequest("GET", url("/api/v1/cameras")).status, 401);
  const auto r = curlRequest("GET", url("/api/v1/cameras"), authed());
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(r.bodyJson(), service.cameras_json);
}

TEST_F(LiveViewTest, PatchPassesTheControlsAndItsRefusals) {
  auto r = curlRequest("PATCH", url("/api/v1/cameras/main"), authed(R"({"exposure_us": 5000})"));
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(service.last_camera, "main");
  EXPECT_EQ(service.last_controls, json({{"exposure_us", 5000}}));

  r = curlRequest("PATCH", url("/api/v1/cameras/main"), authed("{not json"));
  EXPECT_EQ(r.status, 400);
  EXPECT_NE(r.body.find("not valid JSON"), std::string::npos) << r.body;
  r = curlRequest("PATCH", url("/api/v1/cameras/main"), authed("[1]"));
  EXPECT_EQ(r.status, 400);

  service.camera_error = ServiceError(400, "gain: 99 is out of camera main's range [1, 16]");
  r = curlRequest("PATCH", url("/api/v1/cameras/main"), authed(R"({"gain": 99})"));
  EXPECT_EQ(r.status, 400);
  EXPECT_NE(r.body.find("gain"), std::string::npos);
  service.camera_error = ServiceError(409, "scan x is running");
  EXPECT_EQ(curlRequest("PATCH", url("/api/v1/cameras/main"), authed(R"({"gain": 2})")).status,
            409);

  // The camera path takes PATCH only; a bad camera name is 404.
  r = curlRequest("GET", url("/api/v1/cameras/main"), authed());
  EXPECT_EQ(r.status, 405);
  EXPECT_EQ(r.header("allow"), "PATCH");
  EXPECT_EQ(curlRequest("GET", url("/api/v1/cameras/main/other.jpg"), authed()).status, 404);
}

TEST_F(LiveViewTest, FringeCheckPassesItsAnswerAndPictures) {
  service.fringe_reply = json{{"frames", 8}, {"cameras", json::array({{{"name", "main"}}})}};
  service.fringe_pictures["main"] = "\xff\xd8 not really a JPEG";
  EXPECT_EQ(curlRequest("POST", url("/api/v1/fringe-check")).status, 401);
  auto r = curlRequest("POST", url("/api/v1/fringe-check"), authed(R"({"scene": "s.toml"})"));
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(r.bodyJson(), service.fringe_reply);
  EXPECT_EQ(service.last_fringe_body, json({{"scene", "s.toml"}}));
  // No body is an empty one.
  r = curlRequest("POST", url("/api/v1/fringe-check"), authed(""));
  EXPECT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(service.last_fringe_body, json::object());

  r = curlRequest("GET", url("/api/v1/fringe-check/main.jpg"), authed());
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(r.header("content-type"), "image/jpeg");
  EXPECT_EQ(r.body, service.fringe_pictures["main"]);
  EXPECT_EQ(curlRequest("GET", url("/api/v1/fringe-check/main.jpg")).status, 401);
  EXPECT_EQ(curlRequest("GET", url("/api/v1/fringe-check/aux.jpg"), authed()).status, 404);

  service.camera_error = ServiceError(409, "scan x is running");
  r = curlRequest("POST", url("/api/v1/fringe-check"), authed("{}"));
  EXPECT_EQ(r.status, 409);
  EXPECT_NE(r.body.find("scan x is running"), std::string::npos) << r.body;
  r = curlRequest("POST", url("/api/v1/fringe-check"), authed("{not json"));
  EXPECT_EQ(r.status, 400) << r.body;
}

TEST_F(LiveViewTest, SnapshotWaitsForItsPicture) {
  auto s = rawGet("/api/v1/cameras/aux/snapshot.jpg?overlay=saturation");
  auto f = feed();
  ASSERT_TRUE(f);
  ASSERT_EQ(service.live_requests.size(), 1u);
  EXPECT_EQ(service.live_requests[0].camera, "aux");
  EXPECT_TRUE(service.live_requests[0].saturation_overlay);
  // No answer before the picture.
  EXPECT_EQ(s->readHead(std::chrono::milliseconds(200)), "");
  FakeService::pushPicture(*f, picture(1, std::string("\xff\xd8jpeg\xff\xd9", 8)));
  const std::string text = s->readUntil(
      [](const std::string& t) { return t.find("jpeg\xff\xd9") != std::string::npos; });
  EXPECT_EQ(statusOf(text), 200) << text;
  EXPECT_NE(text.find("Content-Type: image/jpeg"), std::string::npos) << text;
  EXPECT_NE(text.find("X-Cylscan-Focus: 12.5"), std::string::npos) << text;
  EXPECT_NE(text.find("X-Cylscan-Saturated: 0.25"), std::string::npos) << text;
  // The live view is given back once answered.
  f.reset();
  EXPECT_TRUE(eventually([&] { return service.liveFeeds().empty(); }));
}

TEST_F(LiveViewTest, SnapshotRefusals) {
  EXPECT_EQ(curlRequest("GET", url("/api/v1/cameras/main/snapshot.jpg")).status, 401);
  auto r = curlRequest("GET", url("/api/v1/cameras/main/snapshot.jpg?overlay=focus"), authed());
  EXPECT_EQ(r.status, 400);
  EXPECT_NE(r.body.find("overlay"), std::string::npos);
  service.camera_error = ServiceError(409, "scan x is running");
  r = curlRequest("GET", url("/api/v1/cameras/main/snapshot.jpg"), authed());
  EXPECT_EQ(r.status, 409);
  EXPECT_NE(r.body.find("scan x is running"), std::string::npos) << r.body;
  service.camera_error.reset();

  // A scan that starts while the snapshot waits: its status and reason.
  auto s = rawGet("/api/v1/cameras/main/snapshot.jpg");
  auto f = feed();
  ASSERT_TRUE(f);
  FakeService::endLive(*f, 409, "a scan started");
  const std::string text =
      s->readUntil([](const std::string& t) { return t.find("}") != std::string::npos; });
  EXPECT_EQ(statusOf(text), 409) << text;
  EXPECT_NE(text.find("a scan started"), std::string::npos) << text;
}

TEST_F(LiveViewTest, StreamSendsPartsUntilItEnds) {
  auto s = rawGet("/api/v1/cameras/main/stream.mjpg");
  const std::string head = s->readHead();
  EXPECT_EQ(statusOf(head), 200) << head;
  EXPECT_NE(head.find("Content-Type: multipart/x-mixed-replace; boundary=cylscanframe"),
            std::string::npos)
      << head;
  auto f = feed();
  ASSERT_TRUE(f);
  EXPECT_FALSE(service.live_requests.at(0).saturation_overlay);
  FakeService::pushPicture(*f, picture(1, "first-picture"));
  s->readUntil([](const std::string& t) { return t.find("first-picture") != std::string::npos; });
  FakeService::pushPicture(*f, picture(2, "second-picture"));
  s->readUntil([](const std::string& t) { return t.find("second-picture") != std::string::npos; });
  FakeService::endLive(*f, 409, "a scan started");
  const std::string text = s->readUntil(
      [](const std::string& t) { return t.find("\r\n0\r\n\r\n") != std::string::npos; });
  EXPECT_EQ(countOf(text, "--cylscanframe\r\nContent-Type: image/jpeg\r\n"), 2u) << text;
  EXPECT_NE(text.find("Content-Length: 13\r\n"), std::string::npos) << text;  // "first-picture"
  EXPECT_NE(text.find("X-Cylscan-Sequence: 2\r\n"), std::string::npos) << text;
  EXPECT_NE(text.find("--cylscanframe--\r\n"), std::string::npos) << text;
  f.reset();
  EXPECT_TRUE(eventually([&] { return service.liveFeeds().empty(); }));
}

TEST_F(LiveViewTest, StreamOfAClientThatLeavesIsReleased) {
  auto s = rawGet("/api/v1/cameras/main/stream.mjpg");
  EXPECT_EQ(statusOf(s->readHead()), 200);
  ASSERT_TRUE(feed());
  s->close();
  EXPECT_TRUE(eventually([&] { return service.liveFeeds().empty(); }));
}

TEST_F(LiveViewTest, StreamRefusedWhileAScanRuns) {
  service.camera_error = ServiceError(409, "scan x is running");
  const auto r = curlRequest("GET", url("/api/v1/cameras/main/stream.mjpg"), authed());
  EXPECT_EQ(r.status, 409);
  EXPECT_NE(r.body.find("no live view"), std::string::npos) << r.body;
}

TEST_F(LiveViewTest, ShutdownAnswersAWaitingSnapshot) {
  auto s = rawGet("/api/v1/cameras/main/snapshot.jpg");
  ASSERT_TRUE(feed());
  const auto t0 = std::chrono::steady_clock::now();
  api.reset();
  const std::string text = s->readAll(std::chrono::seconds(3));
  EXPECT_EQ(statusOf(text), 503) << text;
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(3));
}

}  // namespace
}  // namespace cylscan::firmware
