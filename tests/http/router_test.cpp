// SPDX-License-Identifier: Apache-2.0
// The HTTP layer's pure parts: routing, the token check, content types and
// the metrics text, without sockets.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <chrono>
#include <cstring>
#include <string>

#include <gtest/gtest.h>

#include "firmware/http/auth.hpp"
#include "firmware/http/http_metrics.hpp"
#include "firmware/http/router.hpp"

namespace cylscan::firmware::http {
namespace {

TEST(Router, KnownPathsGiveTheirEndpoints) {
  EXPECT_EQ(route("GET", "/api/v1/status").endpoint, Endpoint::Status);
  EXPECT_EQ(route("GET", "/api/v1/system").endpoint, Endpoint::System);
  EXPECT_EQ(route("POST", "/api/v1/system").status, 405);
  EXPECT_EQ(route("PUT", "/api/v1/system/update").endpoint, Endpoint::SystemUpdate);
  EXPECT_EQ(route("POST", "/api/v1/system/update").status, 405);
  EXPECT_EQ(route("PUT", "/api/v1/system/updates").status, 404);
  EXPECT_EQ(route("GET", "/api/v1/scans").endpoint, Endpoint::Scans);
  EXPECT_EQ(route("POST", "/api/v1/scans").endpoint, Endpoint::Scans);
  EXPECT_EQ(route("GET", "/api/v1/events").endpoint, Endpoint::Events);
  EXPECT_EQ(route("GET", "/metrics").endpoint, Endpoint::Metrics);
  EXPECT_EQ(route("PUT", "/api/v1/calibration").endpoint, Endpoint::Calibration);
  const Route scan = route("DELETE", "/api/v1/scans/20261201-160102-3f9a");
  EXPECT_EQ(scan.endpoint, Endpoint::Scan);
  EXPECT_EQ(scan.status, 0);
  EXPECT_EQ(scan.param_status, 0);
  EXPECT_EQ(scan.id, "20261201-160102-3f9a");
  const Route file = route("HEAD", "/api/v1/scans/abc/depth.tiff");
  EXPECT_EQ(file.endpoint, Endpoint::ScanFile);
  EXPECT_EQ(file.status, 0);
  EXPECT_EQ(file.id, "abc");
  EXPECT_EQ(file.name, "depth.tiff");
  const Route cal = route("GET", "/api/v1/calibration/main");
  EXPECT_EQ(cal.endpoint, Endpoint::CalibrationFile);
  EXPECT_EQ(cal.name, "main");
}

TEST(Router, UnknownPathsAre404) {
  for (const char* path : {"/api", "/api/v1", "/api/v2/status", "/api/v1/nope", "/api/v1/status/x",
                           "/api/v1/scans/a/cloud.ply/x", "/api/v1/calibration/main/x"}) {
    const Route r = route("GET", path);
    EXPECT_EQ(r.status, 404) << path;
    EXPECT_NE(r.error.find(path), std::string::npos) << r.error;
  }
}

TEST(Router, WrongMethodIs405WithAllow) {
  Route r = route("PUT", "/api/v1/scans");
  EXPECT_EQ(r.status, 405);
  EXPECT_EQ(r.allow, "GET, HEAD, POST");
  r = route("POST", "/api/v1/status");
  EXPECT_EQ(r.status, 405);
  EXPECT_EQ(r.allow, "GET, HEAD");
  r = route("POST", "/api/v1/scans/abc");
  EXPECT_EQ(r.status, 405);
  EXPECT_EQ(r.allow, "GET, HEAD, DELETE");
  r = route("DELETE", "/api/v1/calibration");
  EXPECT_EQ(r.status, 405);
  EXPECT_EQ(r.allow, "GET, HEAD, PUT");
  r = route("get", "/api/v1/status");  // methods are case-sensitive
  EXPECT_EQ(r.status, 405);
  r = route("POST", "/index.html");
  EXPECT_EQ(r.status, 405);
  EXPECT_NE(r.error.find("POST"), std::string::npos);
}

TEST(Router, RefusedPathsAre400) {
  for (const char* path :
       {"", "api/v1/status", "/api/v1/scans/", "/api//v1/status",
        "/api/v1/scans/../../etc/cloud.ply", "/../../etc/passwd", "/assets/./app.js",
        "/assets\\..\\x", "/api/v1/scans/a%2fb", "/assets/%2e%2e/x", "/a\x01"}) {
    const Route r = route("GET", path);
    EXPECT_EQ(r.status, 400) << path;
    EXPECT_FALSE(r.error.empty());
  }
}

TEST(Router, InvalidIdsAndNamesAreNotFoundAfterAuth) {
  for (const char* path :
       {"/api/v1/scans/ABC", "/api/v1/scans/-x", "/api/v1/scans/.x", "/api/v1/scans/a_b/cloud.ply",
        "/api/v1/scans/a/secret.txt", "/api/v1/scans/a/cloud.PLY", "/api/v1/calibration/Main"}) {
    const Route r = route("GET", path);
    EXPECT_EQ(r.status, 0) << path;  // the path exists: auth comes first
    EXPECT_EQ(r.param_status, 404) << path;
    EXPECT_FALSE(r.error.empty());
  }
  const std::string long_id(65, 'a');
  EXPECT_EQ(route("GET", "/api/v1/scans/" + long_id).param_status, 404);
  EXPECT_EQ(route("GET", "/api/v1/scans/" + std::string(64, 'a')).param_status, 0);
}

TEST(Router, StaticPaths) {
  Route r = route("GET", "/");
  EXPECT_EQ(r.endpoint, Endpoint::Static);
  EXPECT_EQ(r.name, "index.html");
  r = route("GET", "/assets/js/app.js");
  EXPECT_EQ(r.endpoint, Endpoint::Static);
  EXPECT_EQ(r.name, "assets/js/app.js");
  r = route("GET", "/.env");
  EXPECT_EQ(r.param_status, 404);
  r = route("GET", "/assets/.git/config");
  EXPECT_EQ(r.param_status, 404);
}

TEST(Router, TokenIsNeededEverywhereButStatusAndThePage) {
  EXPECT_FALSE(needsToken(Endpoint::Status));
  EXPECT_TRUE(needsToken(Endpoint::System));
  EXPECT_FALSE(needsToken(Endpoint::Static));
  for (const auto e : {Endpoint::Scans, Endpoint::Scan, Endpoint::ScanFile, Endpoint::Calibration,
                       Endpoint::CalibrationFile, Endpoint::Events, Endpoint::Metrics}) {
    EXPECT_TRUE(needsToken(e));
  }
}

TEST(ContentTypes, StaticAndScanFiles) {
  EXPECT_EQ(staticContentType("index.html"), "text/html; charset=utf-8");
  EXPECT_EQ(staticContentType("assets/app.JS"), "text/javascript; charset=utf-8");
  EXPECT_EQ(staticContentType("assets/s.css"), "text/css; charset=utf-8");
  EXPECT_EQ(staticContentType("assets/i.svg"), "image/svg+xml");
  EXPECT_EQ(staticContentType("assets.d/noext"), "application/octet-stream");
  EXPECT_EQ(scanFileContentType("cloud.ply"), "application/octet-stream");
  EXPECT_EQ(scanFileContentType("depth.tiff"), "image/tiff");
  EXPECT_EQ(scanFileContentType("phase.png"), "image/png");
  EXPECT_EQ(scanFileContentType("scan.json"), "application/json");
}

TEST(Auth, TokenEquals) {
  EXPECT_TRUE(tokenEquals("s3cret-token", "s3cret-token"));
  EXPECT_FALSE(tokenEquals("s3cret-token", "s3cret-tokeN"));
  EXPECT_FALSE(tokenEquals("s3cret-token", "s3cret"));
  EXPECT_FALSE(tokenEquals("s3cret-token", "s3cret-token-and-more"));
  EXPECT_FALSE(tokenEquals("s3cret-token", ""));
  // A given token that is the expected one padded with NULs is still wrong.
  EXPECT_FALSE(tokenEquals("abc", std::string("abc\0", 4)));
  EXPECT_FALSE(tokenEquals(std::string("abc\0", 4), "abc"));
}

TEST(Auth, BearerToken) {
  EXPECT_EQ(bearerToken("Bearer abc"), "abc");
  EXPECT_EQ(bearerToken("bearer  abc "), "abc");
  EXPECT_FALSE(bearerToken("Basic YWJjOmRlZg=="));
  EXPECT_FALSE(bearerToken("Bearer "));
  EXPECT_FALSE(bearerToken("Bearerabc"));
  EXPECT_FALSE(bearerToken(""));
}

TEST(Auth, LoopbackPeers) {
  sockaddr_in v4{};
  v4.sin_family = AF_INET;
  inet_pton(AF_INET, "127.0.0.1", &v4.sin_addr);
  EXPECT_TRUE(isLoopbackPeer(reinterpret_cast<const sockaddr*>(&v4)));
  inet_pton(AF_INET, "127.0.0.2", &v4.sin_addr);
  EXPECT_FALSE(isLoopbackPeer(reinterpret_cast<const sockaddr*>(&v4)));
  inet_pton(AF_INET, "192.168.1.5", &v4.sin_addr);
  EXPECT_FALSE(isLoopbackPeer(reinterpret_cast<const sockaddr*>(&v4)));
  sockaddr_in6 v6{};
  v6.sin6_family = AF_INET6;
  inet_pton(AF_INET6, "::1", &v6.sin6_addr);
  EXPECT_TRUE(isLoopbackPeer(reinterpret_cast<const sockaddr*>(&v6)));
  inet_pton(AF_INET6, "::ffff:127.0.0.1", &v6.sin6_addr);
  EXPECT_TRUE(isLoopbackPeer(reinterpret_cast<const sockaddr*>(&v6)));
  inet_pton(AF_INET6, "fe80::1", &v6.sin6_addr);
  EXPECT_FALSE(isLoopbackPeer(reinterpret_cast<const sockaddr*>(&v6)));
  EXPECT_FALSE(isLoopbackPeer(nullptr));
}

TEST(HttpMetrics, CountsByCodeAndHistogram) {
  HttpMetrics m;
  m.record(200, std::chrono::milliseconds(2));
  m.record(200, std::chrono::milliseconds(30));
  m.record(404, std::chrono::seconds(10));
  const std::string text = m.text(3);
  EXPECT_NE(text.find("cylscan_http_requests_total{code=\"200\"} 2\n"), std::string::npos);
  EXPECT_NE(text.find("cylscan_http_requests_total{code=\"404\"} 1\n"), std::string::npos);
  // Cumulative buckets: 2 ms falls in le=0.0025, 30 ms in le=0.05, 10 s only in +Inf.
  EXPECT_NE(text.find("_bucket{le=\"0.001\"} 0\n"), std::string::npos);
  EXPECT_NE(text.find("_bucket{le=\"0.0025\"} 1\n"), std::string::npos);
  EXPECT_NE(text.find("_bucket{le=\"0.05\"} 2\n"), std::string::npos);
  EXPECT_NE(text.find("_bucket{le=\"5\"} 2\n"), std::string::npos);
  EXPECT_NE(text.find("_bucket{le=\"+Inf\"} 3\n"), std::string::npos);
  EXPECT_NE(text.find("cylscan_http_request_duration_seconds_count 3\n"), std::string::npos);
  EXPECT_NE(text.find("cylscan_sse_clients 3\n"), std::string::npos);
}

}  // namespace
}  // namespace cylscan::firmware::http
