// SPDX-License-Identifier: Apache-2.0
// HttpApi on 127.0.0.1 (port 0) against a scripted HeadService, with libcurl
// and raw sockets: routes and codes, auth, limits, paths, static files.
#include "firmware/http/http_api.hpp"

#include <filesystem>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "tests/http/http_test_support.hpp"
#include "tests/support/temp_dir.hpp"

namespace cylscan::firmware {
namespace {

using nlohmann::json;
using test_support::curlRequest;
using test_support::FakeService;
using test_support::HttpResult;
using test_support::RawSocket;
using test_support::RequestOptions;
using test_support::statusOf;

constexpr const char* kToken = "0123456789abcdef-secret";
const std::string kAuth = std::string("Authorization: Bearer ") + kToken;

class HttpApiTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::filesystem::create_directories(dir.path() / "web/assets/dir");
    write(dir.path() / "web/index.html", "<html>cylscan page</html>");
    write(dir.path() / "web/assets/app.js", "console.log('app');");
    write(dir.path() / "web/.env", "HIDDEN-MARKER");
    write(dir.path() / "secret.txt", "SECRET-MARKER");
    std::filesystem::create_symlink(dir.path() / "secret.txt", dir.path() / "web/assets/link");
    options.port = 0;
    options.token = kToken;
    options.web_root = dir.path() / "web";
    options.log = [this](std::string_view line) { logged += std::string(line) + "\n"; };
  }
  void start() { api = std::make_unique<HttpApi>(service, options); }
  std::string url(const std::string& path) const {
    return "http://127.0.0.1:" + std::to_string(api->port()) + path;
  }
  HttpResult get(const std::string& path, bool auth = true) {
    RequestOptions o;
    if (auth) o.headers.push_back(kAuth);
    return curlRequest("GET", url(path), o);
  }
  HttpResult send(const std::string& method, const std::string& path, const std::string& body,
                  bool auth = true) {
    RequestOptions o;
    if (auth) o.headers.push_back(kAuth);
    o.body = body;
    o.has_body = true;
    return curlRequest(method, url(path), o);
  }
  // A raw request (request line and headers as given, then `body`).
  std::string raw(const std::string& head, const std::string& body = "") {
    RawSocket s("127.0.0.1", api->port());
    EXPECT_TRUE(s.ok());
    s.send(head + "\r\n" + body);
    return s.readAll(std::chrono::seconds(3));
  }
  static void write(const std::filesystem::path& p, const std::string& text) {
    std::ofstream(p, std::ios::binary) << text;
  }
  static std::string errorOf(const HttpResult& r) {
    const json j = r.bodyJson();
    return j.is_object() && j.contains("error") && j["error"].is_string()
               ? j["error"].get<std::string>()
               : std::string();
  }

  test_support::TempDir dir;
  FakeService service;
  HttpOptions options;
  std::string logged;
  std::unique_ptr<HttpApi> api;
};

TEST_F(HttpApiTest, StatusNeedsNoToken) {
  start();
  const HttpResult r = get("/api/v1/status", false);
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.header("content-type"), "application/json");
  EXPECT_EQ(r.bodyJson(), service.status_json);
  EXPECT_EQ(curlRequest("HEAD", url("/api/v1/status")).status, 200);
}

// The system report names the machine: it needs the token.
TEST_F(HttpApiTest, SystemNeedsTheToken) {
  start();
  EXPECT_EQ(get("/api/v1/system", false).status, 401);
  const HttpResult r = get("/api/v1/system");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.bodyJson(), service.system());
}

TEST_F(HttpApiTest, MissingWrongOrMisplacedTokensAre401) {
  start();
  const auto with = [&](const std::string& header, const std::string& path = "/api/v1/scans") {
    RequestOptions o;
    if (!header.empty()) o.headers.push_back(header);
    return curlRequest("GET", url(path), o);
  };
  HttpResult r = with("");
  EXPECT_EQ(r.status, 401);
  EXPECT_EQ(r.header("www-authenticate"), "Bearer");
  EXPECT_NE(errorOf(r).find("Authorization"), std::string::npos);
  std::string same_length(kToken);
  same_length.back() = 'X';
  EXPECT_EQ(with("Authorization: Bearer " + same_length).status, 401);
  EXPECT_EQ(with("Authorization: Bearer 0123").status, 401);                      // shorter
  EXPECT_EQ(with(kAuth + "-and-more").status, 401);                               // longer
  EXPECT_EQ(with(std::string("Authorization: Basic ") + kToken).status, 401);     // not Bearer
  EXPECT_EQ(with("", std::string("/api/v1/scans?token=") + kToken).status, 401);  // query
  EXPECT_EQ(with("", std::string("/api/v1/scans?access_token=") + kToken).status, 401);
  // A token in the query string is refused even beside a good header.
  EXPECT_EQ(with(kAuth, std::string("/metrics?token=") + kToken).status, 401);
  for (const char* path : {"/metrics", "/api/v1/events", "/api/v1/calibration",
                           "/api/v1/scans/20261201-160102-3f9a"}) {
    EXPECT_EQ(with("", path).status, 401) << path;
  }
  EXPECT_EQ(send("POST", "/api/v1/scans", "{}", false).status, 401);
  EXPECT_EQ(service.start_calls, 0);
  EXPECT_EQ(with(kAuth).status, 200);
  EXPECT_EQ(with("Authorization: bearer " + std::string(kToken)).status, 200);
  // The page needs no token.
  EXPECT_EQ(with("", "/").status, 200);
  // Nothing logged names the token.
  EXPECT_EQ(logged.find(kToken), std::string::npos);
}

TEST_F(HttpApiTest, NoTokenConfiguredNeedsNone) {
  options.token.clear();
  start();
  EXPECT_EQ(get("/api/v1/scans", false).status, 200);
  EXPECT_EQ(get("/metrics", false).status, 200);
}

TEST_F(HttpApiTest, LoopbackExemptionOnlyFor127001) {
  options.allow_loopback_without_token = true;
  start();
  EXPECT_EQ(get("/api/v1/scans", false).status, 200);
  // From 127.0.0.2 (another loopback address, not 127.0.0.1): a token is needed.
  RequestOptions o;
  o.interface = "127.0.0.2";
  EXPECT_EQ(curlRequest("GET", url("/api/v1/scans"), o).status, 401);
  o.headers.push_back(kAuth);
  EXPECT_EQ(curlRequest("GET", url("/api/v1/scans"), o).status, 200);
}

TEST_F(HttpApiTest, WithoutExemptionLoopbackNeedsTheToken) {
  start();
  EXPECT_EQ(get("/api/v1/scans", false).status, 401);
}

TEST_F(HttpApiTest, StartScan) {
  start();
  const HttpResult r = send("POST", "/api/v1/scans", R"({"mode": "stop", "frames": 5})");
  EXPECT_EQ(r.status, 202);
  EXPECT_EQ(r.bodyJson(), (json{{"id", service.next_id}}));
  EXPECT_EQ(r.header("location"), "/api/v1/scans/" + service.next_id);
  EXPECT_EQ(service.last_options, (json{{"mode", "stop"}, {"frames", 5}}));
  // No body: empty options.
  EXPECT_EQ(send("POST", "/api/v1/scans", "").status, 202);
  EXPECT_EQ(service.last_options, json::object());
  EXPECT_EQ(service.start_calls, 2);
}

TEST_F(HttpApiTest, StartScanRefusals) {
  start();
  HttpResult r = send("POST", "/api/v1/scans", R"({"mode": )");
  EXPECT_EQ(r.status, 400);
  EXPECT_NE(errorOf(r).find("JSON"), std::string::npos) << r.body;
  r = send("POST", "/api/v1/scans", "[1, 2]");
  EXPECT_EQ(r.status, 400);
  EXPECT_NE(errorOf(r).find("object"), std::string::npos) << r.body;
  EXPECT_EQ(service.start_calls, 0);
  for (const int code : {400, 409, 503, 507}) {
    service.start_error = ServiceError(code, "refused with " + std::to_string(code));
    r = send("POST", "/api/v1/scans", "{}");
    EXPECT_EQ(r.status, code);
    EXPECT_EQ(errorOf(r), "refused with " + std::to_string(code));
  }
}

// Found by fuzz/fuzz_scan_options: nlohmann::json reports a number beyond a
// double's range as out_of_range, not parse_error; the body is still bad
// JSON from the client (400), not an internal error (500).
TEST_F(HttpApiTest, NumberOverflowInTheBodyIs400) {
  start();
  const HttpResult r = send("POST", "/api/v1/scans", R"({"frames": 1e400})");
  EXPECT_EQ(r.status, 400) << r.body;
  EXPECT_NE(errorOf(r).find("not valid JSON"), std::string::npos) << r.body;
  EXPECT_EQ(service.start_calls, 0);
}

TEST_F(HttpApiTest, ListGetAndDeleteScans) {
  service.scans["20261201-100000-aaaa"] = json{{"id", "20261201-100000-aaaa"}, {"state", "done"}};
  service.scans["20261201-110000-bbbb"] = json{{"id", "20261201-110000-bbbb"}, {"state", "done"}};
  start();
  HttpResult r = get("/api/v1/scans");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.bodyJson(), service.listScans());
  r = get("/api/v1/scans/20261201-100000-aaaa");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.bodyJson()["state"], "done");
  r = get("/api/v1/scans/20261201-120000-cccc");
  EXPECT_EQ(r.status, 404);
  EXPECT_NE(errorOf(r).find("20261201-120000-cccc"), std::string::npos);

  r = curlRequest("DELETE", url("/api/v1/scans/20261201-100000-aaaa"),
                  test_support::withHeader(kAuth));
  EXPECT_EQ(r.status, 204);
  EXPECT_TRUE(r.body.empty());
  EXPECT_EQ(service.scans.count("20261201-100000-aaaa"), 0u);
  r = curlRequest("DELETE", url("/api/v1/scans/20261201-100000-aaaa"),
                  test_support::withHeader(kAuth));
  EXPECT_EQ(r.status, 404);
  service.delete_error = ServiceError(409, "scan 20261201-110000-bbbb is running");
  r = curlRequest("DELETE", url("/api/v1/scans/20261201-110000-bbbb"),
                  test_support::withHeader(kAuth));
  EXPECT_EQ(r.status, 409);
  EXPECT_EQ(errorOf(r), "scan 20261201-110000-bbbb is running");
}

TEST_F(HttpApiTest, InvalidIdsNeverReachTheService) {
  start();
  for (const char* path :
       {"/api/v1/scans/UPPER", "/api/v1/scans/-dash", "/api/v1/scans/a_b/cloud.ply",
        "/api/v1/scans/abc/secret.txt", "/api/v1/scans/abc/..%2fcloud.ply",
        "/api/v1/scans/..%2f..%2fetc/cloud.ply", "/api/v1/scans/%2e%2e/cloud.ply"}) {
    const HttpResult r = get(path);
    EXPECT_TRUE(r.status == 404 || r.status == 400) << path << " " << r.status;
    EXPECT_FALSE(errorOf(r).empty()) << path;
  }
  // Only "abc" (a valid id, with a bad file name) was... not even looked up.
  EXPECT_TRUE(service.lookups.empty()) << service.lookups.front();
}

TEST_F(HttpApiTest, WrongMethodsAre405AndGetsChangeNothing) {
  start();
  HttpResult r = send("PUT", "/api/v1/scans", "{}");
  EXPECT_EQ(r.status, 405);
  EXPECT_EQ(r.header("allow"), "GET, HEAD, POST");
  EXPECT_NE(errorOf(r).find("PUT"), std::string::npos);
  r = send("POST", "/api/v1/status", "{}", false);
  EXPECT_EQ(r.status, 405);
  EXPECT_EQ(r.header("allow"), "GET, HEAD");
  r = send("DELETE", "/api/v1/calibration", "");
  EXPECT_EQ(r.status, 405);
  EXPECT_EQ(r.header("allow"), "GET, HEAD, PUT");
  for (const char* path :
       {"/api/v1/status", "/api/v1/scans", "/api/v1/scans/abc", "/api/v1/scans/abc/cloud.ply",
        "/api/v1/calibration", "/api/v1/calibration/main", "/metrics", "/"}) {
    get(path);
    curlRequest("HEAD", url(path), test_support::withHeader(kAuth));
  }
  EXPECT_EQ(service.start_calls + service.delete_calls + service.install_calls, 0);
}

TEST_F(HttpApiTest, UnknownPathsAre404Json) {
  start();
  for (const char* path : {"/api/v1/nope", "/api/v2/status", "/api/v1/status/more"}) {
    const HttpResult r = get(path);
    EXPECT_EQ(r.status, 404) << path;
    EXPECT_EQ(r.header("content-type"), "application/json");
    EXPECT_NE(errorOf(r).find(path), std::string::npos) << r.body;
  }
  const HttpResult r = get("/api/v1/scans/");
  EXPECT_EQ(r.status, 400);
  EXPECT_NE(errorOf(r).find("slash"), std::string::npos) << r.body;
}

TEST_F(HttpApiTest, ScanFilesStreamedWithTheirTypes) {
  const std::string id = "20261201-160102-3f9a";
  std::string ply = "ply\nformat binary_little_endian 1.0\nend_header\n";
  for (int i = 0; i < 300000; ++i)
    ply.push_back(static_cast<char>(i * 7));  // binary, NULs too
  write(dir.path() / "cloud.ply", ply);
  write(dir.path() / "depth.tiff", "II*\0tiff");
  write(dir.path() / "texture.png", "\x89PNG texture");
  service.files[id] = {{"cloud.ply", dir.path() / "cloud.ply"},
                       {"depth.tiff", dir.path() / "depth.tiff"},
                       {"texture.png", dir.path() / "texture.png"},
                       {"phase.png", dir.path() / "missing.png"},
                       {"depth.png", dir.path()}};  // a directory, not a file
  start();
  HttpResult r = get("/api/v1/scans/" + id + "/cloud.ply");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.header("content-type"), "application/octet-stream");
  EXPECT_EQ(r.body.size(), ply.size());
  EXPECT_TRUE(r.body == ply);
  r = get("/api/v1/scans/" + id + "/depth.tiff");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.header("content-type"), "image/tiff");
  r = get("/api/v1/scans/" + id + "/texture.png");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.header("content-type"), "image/png");
  EXPECT_EQ(r.body, "\x89PNG texture");
  for (const char* name : {"phase.png", "depth.png", "scan.json"}) {
    r = get("/api/v1/scans/" + id + "/" + name);
    EXPECT_EQ(r.status, 404) << name;
    EXPECT_NE(errorOf(r).find(name), std::string::npos) << r.body;
  }
}

TEST_F(HttpApiTest, Calibration) {
  write(dir.path() / "calib.bin", std::string("CYLQ\0\1binary", 12));
  start();
  HttpResult r = get("/api/v1/calibration");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.bodyJson(), (json{{"main", service.calibrationInfo("main")}}));
  r = get("/api/v1/calibration/main");
  EXPECT_EQ(r.status, 404);
  service.calibration_files["main"] = dir.path() / "calib.bin";
  r = get("/api/v1/calibration/main");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.header("content-type"), "application/octet-stream");
  EXPECT_EQ(r.body, std::string("CYLQ\0\1binary", 12));

  const std::string bytes = std::string("\0\1\2calibration", 14);
  r = send("PUT", "/api/v1/calibration", bytes);
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.bodyJson()["bytes"], bytes.size());
  EXPECT_EQ(service.last_camera, "main");
  EXPECT_TRUE(service.last_bytes == bytes);
  r = send("PUT", "/api/v1/calibration?camera=aux", "x");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(service.last_camera, "aux");
  r = send("PUT", "/api/v1/calibration?camera=..", "x");
  EXPECT_EQ(r.status, 400);
  EXPECT_NE(errorOf(r).find("camera"), std::string::npos);
  service.install_error = ServiceError(422, "calibration is 640x512, the board's camera 320x256");
  r = send("PUT", "/api/v1/calibration", "x");
  EXPECT_EQ(r.status, 422);
  EXPECT_EQ(errorOf(r), "calibration is 640x512, the board's camera 320x256");
  EXPECT_EQ(service.install_calls, 3);
}

TEST_F(HttpApiTest, InternalErrorsAre500AndLogged) {
  service.fail_internally = true;
  start();
  const HttpResult r = get("/api/v1/scans");
  EXPECT_EQ(r.status, 500);
  EXPECT_NE(errorOf(r).find("scan index unreadable"), std::string::npos) << r.body;
  EXPECT_NE(logged.find("GET /api/v1/scans: scan index unreadable"), std::string::npos) << logged;
}

TEST_F(HttpApiTest, Metrics) {
  start();
  get("/api/v1/status");
  get("/api/v1/nope");
  const HttpResult r = get("/metrics");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.header("content-type"), "text/plain; version=0.0.4; charset=utf-8");
  EXPECT_EQ(r.body.rfind(service.metrics, 0), 0u) << r.body;  // the service's part first
  EXPECT_NE(r.body.find("cylscan_http_requests_total{code=\"200\"} 1\n"), std::string::npos)
      << r.body;
  EXPECT_NE(r.body.find("cylscan_http_requests_total{code=\"404\"} 1\n"), std::string::npos);
  EXPECT_NE(r.body.find("cylscan_http_request_duration_seconds_count 2\n"), std::string::npos);
  EXPECT_NE(r.body.find("cylscan_sse_clients 0\n"), std::string::npos);
}

TEST_F(HttpApiTest, StaticFiles) {
  start();
  HttpResult r = get("/", false);
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.body, "<html>cylscan page</html>");
  EXPECT_EQ(r.header("content-type"), "text/html; charset=utf-8");
  EXPECT_EQ(r.header("cache-control"), "no-cache");
  r = get("/index.html", false);
  EXPECT_EQ(r.status, 200);
  r = get("/assets/app.js", false);
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.body, "console.log('app');");
  EXPECT_EQ(r.header("content-type"), "text/javascript; charset=utf-8");
  EXPECT_EQ(r.header("cache-control"), "public, max-age=300");
  for (const char* path : {"/assets/missing.js", "/assets/dir", "/assets/link", "/.env"}) {
    r = get(path, false);
    EXPECT_EQ(r.status, 404) << path;
    EXPECT_FALSE(errorOf(r).empty());
  }
}

TEST_F(HttpApiTest, StaticPathsStayUnderTheWebRoot) {
  start();
  for (const char* path : {"/../secret.txt", "/../../etc/passwd", "/assets/../../secret.txt",
                           "/assets/%2e%2e/%2e%2e/secret.txt", "/assets/..%2f..%2fsecret.txt",
                           "/assets/%2e%2e%2f%2e%2e%2fsecret.txt", "/assets\\..\\..\\secret.txt",
                           "/assets/app.js%00.png", "/%2e%2e/secret.txt",
                           "/assets/%252e%252e/secret.txt", "/%2Fetc%2Fpasswd"}) {
    RequestOptions o;
    o.path_as_is = true;
    const HttpResult r = curlRequest("GET", url(path), o);
    EXPECT_TRUE(r.status == 400 || r.status == 404) << path << ": " << r.status;
    EXPECT_EQ(r.body.find("SECRET-MARKER"), std::string::npos) << path;
    EXPECT_EQ(r.body.find("root:"), std::string::npos) << path;
  }
  // The same with a raw request line (no client-side normalisation at all).
  const std::string response =
      raw("GET /../secret.txt HTTP/1.1\r\nHost: x\r\nConnection: close\r\n");
  EXPECT_EQ(statusOf(response), 400) << response;
  EXPECT_EQ(response.find("SECRET-MARKER"), std::string::npos);
}

TEST_F(HttpApiTest, NoWebRootNoPage) {
  options.web_root.clear();
  start();
  const HttpResult r = get("/", false);
  EXPECT_EQ(r.status, 404);
  EXPECT_NE(errorOf(r).find("web_root"), std::string::npos);
}

TEST_F(HttpApiTest, OversizedJsonBodyIs413) {
  start();
  const HttpResult r = send("POST", "/api/v1/scans", std::string(70000, ' ') + "{}");
  EXPECT_EQ(r.status, 413);
  EXPECT_NE(errorOf(r).find("65536"), std::string::npos) << r.body;
  EXPECT_EQ(service.start_calls, 0);
}

TEST_F(HttpApiTest, ContentLengthPastTheLimitIs413BeforeTheBody) {
  options.max_calibration_bytes = 1000;
  start();
  // Only the head is sent: the answer comes without the body ever being read.
  RawSocket s("127.0.0.1", api->port());
  ASSERT_TRUE(s.ok());
  s.send("PUT /api/v1/calibration HTTP/1.1\r\nHost: x\r\n" + kAuth +
         "\r\nContent-Length: 100000000\r\n\r\n");
  const std::string response = s.readHead();
  EXPECT_EQ(statusOf(response), 413) << response;
  EXPECT_EQ(service.install_calls, 0);
  // Within the limit it is accepted.
  EXPECT_EQ(send("PUT", "/api/v1/calibration", std::string(1000, 'c')).status, 200);
  EXPECT_EQ(service.last_bytes.size(), 1000u);
}

TEST_F(HttpApiTest, EarlyRefusalIsReadByAClientThatSendsItsWholeBodyFirst) {
  options.max_calibration_bytes = 1000;
  start();
  // Browsers send the whole body before they read: the refused body is
  // drained, so the sending goes through and the 413 is there to read
  // (closing at once reset the connection: the send failed, the answer was lost).
  RawSocket s("127.0.0.1", api->port());
  ASSERT_TRUE(s.ok());
  const std::size_t body = 8u << 20;
  ASSERT_TRUE(s.send("PUT /api/v1/calibration HTTP/1.1\r\nHost: x\r\n" + kAuth +
                     "\r\nContent-Length: " + std::to_string(body) + "\r\n\r\n"));
  EXPECT_TRUE(s.send(std::string(body, 'c')));
  const std::string response = s.readHead();
  EXPECT_EQ(statusOf(response), 413) << response;
  EXPECT_EQ(service.install_calls, 0);
}

TEST_F(HttpApiTest, OneCalibrationUploadAtATime) {
  start();
  RawSocket first("127.0.0.1", api->port());
  ASSERT_TRUE(first.ok());
  // The head alone, asking to continue: the server's "100 Continue" says it
  // has taken the upload (the slot is claimed when the head is accepted), so
  // the second upload cannot overtake it. (Sent with the head and no wait, a
  // loaded machine could serve the second first: the first then got the 409.)
  first.send("PUT /api/v1/calibration HTTP/1.1\r\nHost: x\r\n" + kAuth +
             "\r\nContent-Length: 10\r\nExpect: 100-continue\r\n\r\n");
  const std::string interim = first.readHead();
  ASSERT_EQ(statusOf(interim), 100) << interim;
  first.send("12345");
  // The first is being read: a second one is refused (its body never read).
  EXPECT_EQ(send("PUT", "/api/v1/calibration", "abc").status, 409);
  first.send("67890");
  const std::string received = first.readUntil([&](const std::string& s) {
    return s.size() > interim.size() && s.find("\r\n\r\n", interim.size()) != std::string::npos;
  });
  EXPECT_EQ(statusOf(received.substr(interim.size())), 200) << received;
  EXPECT_EQ(service.last_bytes, "1234567890");
  // Done: the next one is taken.
  EXPECT_EQ(send("PUT", "/api/v1/calibration", "abc").status, 200);
  EXPECT_EQ(service.last_bytes, "abc");
}

// The calibration upload's slot belongs to PUT /api/v1/calibration alone,
// also when its body limit equals the other endpoints' (65536, a legal
// max_calibration_bytes): a head.json sent meanwhile is installed, and a
// calibration sent while a head.json is being read is not refused.
TEST_F(HttpApiTest, TheCalibrationUploadSlotIsTheCalibrationEndpointsAlone) {
  options.max_calibration_bytes = options.max_json_bytes;
  start();
  // A PUT of 10 bytes whose head was accepted ("100 Continue": an upload
  // slot would be taken by now) and half of whose body was sent.
  const auto begin = [&](const std::string& path) {
    auto s = std::make_unique<RawSocket>("127.0.0.1", api->port());
    EXPECT_TRUE(s->ok());
    s->send("PUT " + path + " HTTP/1.1\r\nHost: x\r\n" + kAuth +
            "\r\nContent-Length: 10\r\nExpect: 100-continue\r\n\r\n");
    const std::string interim = s->readHead();
    EXPECT_EQ(statusOf(interim), 100) << path << ": " << interim;
    s->send("12345");
    return std::make_pair(std::move(s), interim.size());
  };
  // The rest of its body, and its answer.
  const auto finish = [](RawSocket& s, std::size_t interim) {
    s.send("67890");
    const std::string received = s.readUntil([&](const std::string& t) {
      return t.size() > interim && t.find("\r\n\r\n", interim) != std::string::npos;
    });
    return statusOf(received.substr(interim));
  };

  auto [calibration, calibration_interim] = begin("/api/v1/calibration");
  const HttpResult head = send("PUT", "/api/v1/head", "{}");
  EXPECT_EQ(head.status, 200) << head.body;
  EXPECT_EQ(service.head_installs, 1);
  EXPECT_EQ(finish(*calibration, calibration_interim), 200);
  EXPECT_EQ(service.last_bytes, "1234567890");

  auto [head_upload, head_interim] = begin("/api/v1/head");
  const HttpResult next = send("PUT", "/api/v1/calibration", "abc");
  EXPECT_EQ(next.status, 200) << next.body;
  EXPECT_EQ(service.last_bytes, "abc");
  EXPECT_EQ(finish(*head_upload, head_interim), 200);
  EXPECT_EQ(service.last_head, "1234567890");
}

TEST_F(HttpApiTest, ChunkedBodiesAre411) {
  start();
  // The limit is checked before the body: its size must be known.
  RawSocket s("127.0.0.1", api->port());
  ASSERT_TRUE(s.ok());
  s.send("PUT /api/v1/calibration HTTP/1.1\r\nHost: x\r\n" + kAuth +
         "\r\nTransfer-Encoding: chunked\r\n\r\n");
  const std::string response =
      s.readUntil([](const std::string& t) { return t.find("}") != std::string::npos; });
  EXPECT_EQ(statusOf(response), 411) << response;
  EXPECT_NE(response.find("Content-Length"), std::string::npos);
  EXPECT_EQ(service.install_calls, 0);
}

TEST_F(HttpApiTest, OversizedHeadersAre431) {
  start();
  // Past max_header_bytes (8 KiB), within libmicrohttpd's memory: our 431.
  std::string response =
      raw("GET /api/v1/status HTTP/1.1\r\nHost: x\r\nX-Big: " + std::string(10000, 'a') +
          "\r\nConnection: close\r\n");
  EXPECT_EQ(statusOf(response), 431) << response.substr(0, 200);
  EXPECT_NE(response.find("8192"), std::string::npos);
  // Far past it (beyond the connection's memory pool) libmicrohttpd answers itself.
  response = raw("GET /api/v1/status HTTP/1.1\r\nHost: x\r\nX-Big: " + std::string(100000, 'a') +
                 "\r\nConnection: close\r\n");
  EXPECT_EQ(statusOf(response), 431) << response.substr(0, 200);
  // The same for a long request line.
  response = raw("GET /api/v1/status?x=" + std::string(10000, 'a') +
                 " HTTP/1.1\r\nHost: x\r\nConnection: close\r\n");
  EXPECT_EQ(statusOf(response), 431) << response.substr(0, 200);
  response = raw("GET /api/v1/" + std::string(100000, 'a') +
                 " HTTP/1.1\r\nHost: x\r\nConnection: close\r\n");
  EXPECT_EQ(statusOf(response), 414) << response.substr(0, 200);
  // Just within the limit is fine.
  response = raw("GET /api/v1/status HTTP/1.1\r\nHost: x\r\nX-Big: " + std::string(7000, 'a') +
                 "\r\nConnection: close\r\n");
  EXPECT_EQ(statusOf(response), 200) << response.substr(0, 200);
}

TEST_F(HttpApiTest, ConnectionsAreKeptAlive) {
  start();
  // Answers, refusals included, leave the connection open for the next request.
  RawSocket s("127.0.0.1", api->port());
  ASSERT_TRUE(s.ok());
  const auto ask = [&](const std::string& path, std::size_t answers) {
    s.send("GET " + path + " HTTP/1.1\r\nHost: x\r\n\r\n");
    return s.readUntil([&](const std::string& t) {
      std::size_t n = 0;
      for (auto p = t.find("\r\n\r\n{"); p != std::string::npos; p = t.find("\r\n\r\n{", p + 1)) {
        if (t.find('}', p) != std::string::npos) ++n;
      }
      return n >= answers;
    });
  };
  ask("/api/v1/status", 1);
  ask("/api/v1/scans", 2);  // 401: no token
  const std::string all = ask("/api/v1/nope", 3);
  EXPECT_EQ(statusOf(all), 200) << all;
  EXPECT_NE(all.find("HTTP/1.1 401"), std::string::npos) << all;
  EXPECT_NE(all.find("HTTP/1.1 404"), std::string::npos) << all;
  EXPECT_EQ(all.find("Connection: close"), std::string::npos) << all;
  EXPECT_FALSE(s.closed());
}

TEST_F(HttpApiTest, BindsOnlyTheConfiguredAddress) {
  start();
  EXPECT_TRUE(RawSocket("127.0.0.1", api->port()).ok());
  EXPECT_FALSE(RawSocket("127.0.0.2", api->port()).ok());
}

TEST_F(HttpApiTest, BindsIpv6Loopback) {
  if (!RawSocket("::1", 9).ok() && errno == EADDRNOTAVAIL) GTEST_SKIP() << "no IPv6 loopback";
  options.address = "::1";
  try {
    start();
  } catch (const std::runtime_error& e) {
    GTEST_SKIP() << "no IPv6 here: " << e.what();
  }
  const HttpResult r =
      curlRequest("GET", "http://[::1]:" + std::to_string(api->port()) + "/api/v1/status");
  EXPECT_EQ(r.status, 200);
  EXPECT_FALSE(RawSocket("127.0.0.1", api->port()).ok());
}

TEST_F(HttpApiTest, BadAddressesAndBusyPortsThrow) {
  options.address = "localhost";
  EXPECT_THROW(start(), std::runtime_error);
  options.address = "127.0.0.1";
  start();
  HttpOptions again = options;
  again.port = api->port();
  try {
    HttpApi second(service, again);
    ADD_FAILURE() << "a second server bound the same port";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("127.0.0.1"), std::string::npos) << e.what();
  }
}

TEST_F(HttpApiTest, IdleConnectionsTimeOut) {
  options.connection_timeout = std::chrono::seconds(1);
  start();
  RawSocket idle("127.0.0.1", api->port());
  ASSERT_TRUE(idle.ok());
  idle.send("GET /api/v1/status HTTP/1.1\r\n");  // and nothing more
  idle.readAll(std::chrono::seconds(4));
  EXPECT_TRUE(idle.closed());
}

TEST_F(HttpApiTest, SlowClientsDoNotBlockOthers) {
  start();
  // Many clients trickling their request, a byte at a time.
  std::vector<std::unique_ptr<RawSocket>> slow;
  const std::string head = "GET /api/v1/status HTTP/1.1\r\nHost: x\r\n\r\n";
  for (int i = 0; i < 40; ++i) {
    slow.push_back(std::make_unique<RawSocket>("127.0.0.1", api->port()));
    ASSERT_TRUE(slow.back()->ok());
  }
  for (std::size_t k = 0; k + 1 < head.size() / 2; ++k) {
    for (auto& s : slow)
      s->send(head.substr(k, 1));
    EXPECT_EQ(get("/api/v1/status", false).status, 200);
  }
  // They are answered once complete.
  for (auto& s : slow)
    s->send(head.substr(head.size() / 2 - 1));
  for (auto& s : slow)
    EXPECT_EQ(statusOf(s->readHead()), 200);
}

}  // namespace
}  // namespace cylscan::firmware
