// SPDX-License-Identifier: Apache-2.0
// The HTTP API's routing, without sockets: a method and a (percent-decoded)
// path give the endpoint and its parameters, or the error status that says
// why there is none. Paths are exact (no trailing slash); `..`, `.`, empty
// segments, backslashes, NUL and control characters are refused (400), and so
// is any '%' left after decoding (the server leaves encoded separators
// such as %2F encoded, so they never become path separators).
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace cylscan::firmware::http {

enum class Endpoint {
  None,                 // no such path (404) or a refused path (400)
  Status,               // /api/v1/status
  System,               // /api/v1/system
  SystemUpdate,         // /api/v1/system/update
  Scans,                // /api/v1/scans
  Scan,                 // /api/v1/scans/{id}
  ScanFile,             // /api/v1/scans/{id}/{name}
  ScanCameraCloud,      // /api/v1/scans/{id}/clouds/{camera}.ply (name = the camera)
  Head,                 // /api/v1/head
  Calibration,          // /api/v1/calibration
  CalibrationFile,      // /api/v1/calibration/{camera}
  CalibrationSession,   // /api/v1/calibration/session
  CalibrationBoards,    // /api/v1/calibration/session/boards
  CalibrationPlanes,    // /api/v1/calibration/session/planes
  CalibrationSolve,     // /api/v1/calibration/session/solve
  CalibrationInstall,   // /api/v1/calibration/session/install
  CalibrationRollback,  // /api/v1/calibration/rollback
  Cameras,              // /api/v1/cameras
  Camera,               // /api/v1/cameras/{name} (name = the camera)
  CameraSnapshot,       // /api/v1/cameras/{name}/snapshot.jpg
  CameraStream,         // /api/v1/cameras/{name}/stream.mjpg
  Checks,               // /api/v1/checks
  FringeCheck,          // /api/v1/fringe-check
  FringePicture,        // /api/v1/fringe-check/{camera}.jpg (name = the camera)
  Events,               // /api/v1/events
  Metrics,              // /metrics
  Static,               // anything else outside /api/: a file under web_root
};

struct Route {
  Endpoint endpoint = Endpoint::None;
  // 0 when the request may go on; else 400 (refused path), 404 (no such
  // path, scan id, file or camera name) or 405 (wrong method, see `allow`).
  int status = 0;
  std::string error;  // what is wrong, for {"error": …}
  std::string allow;  // the methods the path takes ("GET, HEAD, DELETE")
  // A 404 found in the parameters (an invalid id, an unknown file name) is
  // reported after authentication: `status` stays 0 and this is set.
  int param_status = 0;
  std::string id;    // scan id (valid when param_status == 0)
  std::string name;  // scan file name, camera, or the static file's relative path
};

// GET and HEAD are the same request here; other methods are case-sensitive.
Route route(std::string_view method, std::string_view path);

// Whether `endpoint` needs the bearer token (everything but status and the
// static files).
bool needsToken(Endpoint endpoint);

// The MIME type a static file gets from its extension (a small table;
// application/octet-stream for anything else).
std::string_view staticContentType(std::string_view file_name);

// The MIME type of a scan file (one of kScanFileNames).
std::string_view scanFileContentType(std::string_view name);

}  // namespace cylscan::firmware::http
