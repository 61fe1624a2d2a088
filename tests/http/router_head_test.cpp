// SPDX-License-Identifier: Apache-2.0
// Routing of the 360° head's endpoints (docs/http-api.md): /api/v1/head and a ring
// scan's per-camera clouds.
#include <gtest/gtest.h>

#include "firmware/http/router.hpp"

namespace cylscan::firmware::http {
namespace {

TEST(RouterHead, HeadTakesGetAndPut) {
  EXPECT_EQ(route("GET", "/api/v1/head").endpoint, Endpoint::Head);
  EXPECT_EQ(route("PUT", "/api/v1/head").status, 0);
  const Route post = route("POST", "/api/v1/head");
  EXPECT_EQ(post.status, 405);
  EXPECT_EQ(post.allow, "GET, HEAD, PUT");
  EXPECT_EQ(route("GET", "/api/v1/head/main").status, 404);
  EXPECT_TRUE(needsToken(Endpoint::Head));
}

TEST(RouterHead, CameraCloudsNameTheCamera) {
  const Route r = route("GET", "/api/v1/scans/20261201-160102-3f9a/clouds/cam90.ply");
  EXPECT_EQ(r.endpoint, Endpoint::ScanCameraCloud);
  EXPECT_EQ(r.status, 0);
  EXPECT_EQ(r.param_status, 0);
  EXPECT_EQ(r.id, "20261201-160102-3f9a");
  EXPECT_EQ(r.name, "cam90");
  EXPECT_TRUE(needsToken(Endpoint::ScanCameraCloud));
  EXPECT_EQ(route("DELETE", "/api/v1/scans/20261201-160102-3f9a/clouds/cam90.ply").status, 405);
}

TEST(RouterHead, BadCameraCloudNamesAreNotFound) {
  for (const char* file : {"cam90", "cam90.png", ".ply", "CAM90.ply", "-cam.ply", "cam.90.ply",
                           "_x.ply", "cam90.ply.ply", "a23456789012345678901234567890123.ply"}) {
    const Route r = route("GET", std::string("/api/v1/scans/20261201-160102-3f9a/clouds/") + file);
    EXPECT_EQ(r.param_status, 404) << file;
    EXPECT_TRUE(r.name.empty()) << file;
  }
  EXPECT_EQ(route("GET", "/api/v1/scans/BAD/clouds/main.ply").param_status, 404);
  EXPECT_EQ(route("GET", "/api/v1/scans/20261201-160102-3f9a/clouds/../main.ply").status, 400);
  EXPECT_EQ(route("GET", "/api/v1/scans/20261201-160102-3f9a/other/main.ply").status, 404);
}

// The board's camera-name rule (isCameraName), the same for every
// route that names a camera: what a board may call a camera can be reached.
TEST(RouterHead, EveryNameABoardMayGiveACameraIsRouted) {
  for (const char* camera :
       {"main", "cam_90", "side-left", "0", "a2345678901234567890123456789012"}) {
    const std::string id = "/api/v1/scans/20261201-160102-3f9a/clouds/";
    const Route cloud = route("GET", id + camera + ".ply");
    EXPECT_EQ(cloud.param_status, 0) << camera << ": " << cloud.error;
    EXPECT_EQ(cloud.name, camera);
    const Route calibration = route("GET", std::string("/api/v1/calibration/") + camera);
    EXPECT_EQ(calibration.endpoint, Endpoint::CalibrationFile);
    EXPECT_EQ(calibration.param_status, 0) << camera << ": " << calibration.error;
    EXPECT_EQ(calibration.name, camera);
  }
  EXPECT_EQ(route("GET", "/api/v1/calibration/cam.90").param_status, 404);
}

// The fringe check of the set-up page: POST runs it, GET its pictures by
// camera; the camera names follow the board's rule as everywhere.
TEST(RouterHead, FringeCheckAndItsPictures) {
  EXPECT_EQ(route("POST", "/api/v1/fringe-check").endpoint, Endpoint::FringeCheck);
  EXPECT_EQ(route("POST", "/api/v1/fringe-check").status, 0);
  const Route get = route("GET", "/api/v1/fringe-check");
  EXPECT_EQ(get.status, 405);
  EXPECT_EQ(get.allow, "POST");
  const Route picture = route("GET", "/api/v1/fringe-check/cam_90.jpg");
  EXPECT_EQ(picture.endpoint, Endpoint::FringePicture);
  EXPECT_EQ(picture.param_status, 0) << picture.error;
  EXPECT_EQ(picture.name, "cam_90");
  EXPECT_EQ(route("POST", "/api/v1/fringe-check/main.jpg").status, 405);
  for (const char* file : {"main", "main.png", ".jpg", "cam.90.jpg"})
    EXPECT_EQ(route("GET", std::string("/api/v1/fringe-check/") + file).param_status, 404) << file;
  EXPECT_EQ(route("GET", "/api/v1/fringe-check/main/x.jpg").status, 404);
  EXPECT_TRUE(needsToken(Endpoint::FringeCheck));
  EXPECT_TRUE(needsToken(Endpoint::FringePicture));
}

}  // namespace
}  // namespace cylscan::firmware::http
