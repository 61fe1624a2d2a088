// SPDX-License-Identifier: Apache-2.0
// The calibration session's and the checks' endpoints of the HTTP layer on
// a scripted service: the routes and their methods, the bodies passed on,
// a checkerboard pair answered only once the head has taken it, and the
// service's refusals passed through with their status.
#include <future>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "firmware/http/http_api.hpp"
#include "tests/http/http_test_support.hpp"

namespace cylscan::firmware {
namespace {

using nlohmann::json;
using test_support::curlRequest;
using test_support::eventually;
using test_support::FakeService;
using test_support::RawSocket;
using test_support::RequestOptions;
using test_support::statusOf;

class SessionHttpTest : public test_support::TokenApiTest {
 protected:
  SessionHttpTest() : TokenApiTest("session-token-0123456789") {}
};

TEST_F(SessionHttpTest, SessionRoutesAndMethods) {
  EXPECT_EQ(curlRequest("POST", url("/api/v1/calibration/session")).status, 401);
  auto r = curlRequest("GET", url("/api/v1/calibration/session"), authed());
  EXPECT_EQ(r.status, 404) << r.body;
  r = curlRequest("POST", url("/api/v1/calibration/session"),
                  authed(R"({"board": {"cols": 9, "rows": 6, "square_mm": 12}})"));
  ASSERT_EQ(r.status, 201) << r.body;
  EXPECT_EQ(r.header("location"), "/api/v1/calibration/session");
  EXPECT_EQ(service.last_session_body["board"]["cols"], 9);
  r = curlRequest("GET", url("/api/v1/calibration/session"), authed());
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(r.bodyJson()["state"], "capturing");

  r = curlRequest("POST", url("/api/v1/calibration/session"), authed("{oops"));
  EXPECT_EQ(r.status, 400);
  EXPECT_NE(r.body.find("not valid JSON"), std::string::npos) << r.body;

  for (const char* path :
       {"/api/v1/calibration/session/boards", "/api/v1/calibration/session/planes",
        "/api/v1/calibration/session/solve", "/api/v1/calibration/session/install",
        "/api/v1/calibration/rollback"}) {
    r = curlRequest("GET", url(path), authed());
    EXPECT_EQ(r.status, 405) << path;
    EXPECT_EQ(r.header("allow"), "POST") << path;
  }
  EXPECT_EQ(curlRequest("POST", url("/api/v1/calibration/session/other"), authed()).status, 404);
  // The camera files' path is unchanged beside the session's.
  EXPECT_EQ(curlRequest("POST", url("/api/v1/calibration/main"), authed()).status, 405);

  r = curlRequest("POST", url("/api/v1/calibration/session/planes"),
                  authed(R"({"scene": "calibration/plane03.toml"})"));
  EXPECT_EQ(r.status, 202) << r.body;
  EXPECT_EQ(r.bodyJson(), json({{"index", 0}}));
  EXPECT_EQ(service.last_session_body["scene"], "calibration/plane03.toml");
  r = curlRequest("POST", url("/api/v1/calibration/session/solve"), authed());
  EXPECT_EQ(r.status, 202) << r.body;
  r = curlRequest("POST", url("/api/v1/calibration/session/install"), authed());
  EXPECT_EQ(r.status, 200) << r.body;
  r = curlRequest("POST", url("/api/v1/calibration/rollback"), authed());
  EXPECT_EQ(r.status, 200) << r.body;
}

TEST_F(SessionHttpTest, TheServicesRefusalsKeepTheirStatus) {
  for (int status : {400, 404, 409, 503, 507}) {
    service.session_error = ServiceError(status, "refused for the test");
    for (const char* path :
         {"/api/v1/calibration/session", "/api/v1/calibration/session/boards",
          "/api/v1/calibration/session/planes", "/api/v1/calibration/session/solve",
          "/api/v1/calibration/session/install", "/api/v1/calibration/rollback"}) {
      const auto r = curlRequest("POST", url(path), authed());
      EXPECT_EQ(r.status, status) << path;
      EXPECT_NE(r.body.find("refused for the test"), std::string::npos) << path << r.body;
    }
  }
}

TEST_F(SessionHttpTest, ABoardPairIsAnsweredOnceTaken) {
  service.hold_board = true;
  RawSocket s("127.0.0.1", api->port());
  ASSERT_TRUE(s.ok());
  const std::string body = R"({"scene": "calibration/board00.toml"})";
  s.send("POST /api/v1/calibration/session/boards HTTP/1.1\r\nHost: x\r\n" + authHeader() +
         "\r\nContent-Type: application/json\r\nContent-Length: " + std::to_string(body.size()) +
         "\r\n\r\n" + body);
  ASSERT_TRUE(eventually([&] { return service.heldBoard(1) != nullptr; }));
  // No answer before the head has taken the pair.
  EXPECT_EQ(s.readHead(std::chrono::milliseconds(200)), "");
  service.heldBoard(1)->set_value(json{{"index", 4}, {"found", {{"main", true}, {"aux", false}}}});
  const std::string text = s.readUntil(
      [](const std::string& t) { return t.find("\"aux\":false") != std::string::npos; });
  EXPECT_EQ(statusOf(text), 201) << text;
  EXPECT_NE(text.find("\"index\":4"), std::string::npos) << text;

  // A capture that fails answers with its ServiceError.
  RawSocket t("127.0.0.1", api->port());
  t.send("POST /api/v1/calibration/session/boards HTTP/1.1\r\nHost: x\r\n" + authHeader() +
         "\r\nContent-Length: 0\r\n\r\n");
  ASSERT_TRUE(eventually([&] { return service.heldBoard(2) != nullptr; }));
  service.heldBoard(2)->set_exception(
      std::make_exception_ptr(ServiceError(503, "the capture failed: camera aux timed out")));
  const std::string failed =
      t.readUntil([](const std::string& x) { return x.find("timed out") != std::string::npos; });
  EXPECT_EQ(statusOf(failed), 503) << failed;
}

TEST_F(SessionHttpTest, ChecksPassTheBodyAndTheList) {
  service.checks_json = json::array({json{{"id", "a"}, {"state", "done"}, {"pass", true}}});
  auto r = curlRequest("GET", url("/api/v1/checks"), authed());
  ASSERT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(r.bodyJson(), service.checks_json);
  r = curlRequest("POST", url("/api/v1/checks"),
                  authed(R"({"artifact": "sphere", "radius_mm": 50})"));
  ASSERT_EQ(r.status, 202) << r.body;
  EXPECT_EQ(service.last_check["radius_mm"], 50);
  EXPECT_EQ(r.header("location"), "/api/v1/scans/" + r.bodyJson()["id"].get<std::string>());
  r = curlRequest("POST", url("/api/v1/checks"), authed("[1]"));
  EXPECT_EQ(r.status, 400);
  r = curlRequest("POST", url("/api/v1/checks"), authed("{bad"));
  EXPECT_EQ(r.status, 400);
  EXPECT_EQ(curlRequest("DELETE", url("/api/v1/checks"), authed()).status, 405);
  service.start_error = ServiceError(409, "camera main has no calibration");
  r = curlRequest("POST", url("/api/v1/checks"),
                  authed(R"({"artifact": "sphere", "radius_mm": 50})"));
  EXPECT_EQ(r.status, 409);
  EXPECT_NE(r.body.find("calibration"), std::string::npos);
}

}  // namespace
}  // namespace cylscan::firmware
