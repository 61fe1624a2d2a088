// SPDX-License-Identifier: Apache-2.0
#include "firmware/http/router.hpp"

#include <algorithm>
#include <array>
#include <utility>

#include "common/vocabulary.hpp"
#include "firmware/daemon/head_service.hpp"

namespace cylscan::firmware::http {
namespace {

// Path segments after the leading '/', or a reason the path is refused.
struct Split {
  std::vector<std::string_view> segments;
  std::string error;
};

Split splitPath(std::string_view path) {
  Split out;
  if (path.empty() || path.front() != '/') {
    out.error = "the path must start with '/'";
    return out;
  }
  for (const char c : path) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7f) {
      out.error = "the path contains a control character";
      return out;
    }
    if (c == '\\') {
      out.error = "the path contains a backslash";
      return out;
    }
    if (c == '%') {
      out.error = "the path contains a percent-encoded separator or NUL";
      return out;
    }
  }
  if (path == "/") return out;  // no segments: the page's index
  std::string_view rest = path.substr(1);
  while (true) {
    const auto slash = rest.find('/');
    const std::string_view segment = rest.substr(0, slash);
    if (segment.empty()) {
      out.error = "the path has an empty segment (no trailing or double slashes)";
      return out;
    }
    if (segment == "." || segment == "..") {
      out.error = "the path contains '.' or '..'";
      return out;
    }
    out.segments.push_back(segment);
    if (slash == std::string_view::npos) break;
    rest = rest.substr(slash + 1);
  }
  return out;
}

bool isGet(std::string_view method) {
  return method == "GET" || method == "HEAD";
}

// Checks `method` against the path's methods: 0 or 405 with Allow.
Route withMethods(Endpoint endpoint, std::string_view method, bool get, bool post, bool put,
                  bool del, bool patch = false) {
  Route r;
  r.endpoint = endpoint;
  std::string allow;
  const auto add = [&allow](std::string_view m) {
    if (!allow.empty()) allow += ", ";
    allow += m;
  };
  if (get) add("GET, HEAD");
  if (post) add("POST");
  if (put) add("PUT");
  if (del) add("DELETE");
  if (patch) add("PATCH");
  const bool ok = (get && isGet(method)) || (post && method == "POST") ||
                  (put && method == "PUT") || (del && method == "DELETE") ||
                  (patch && method == "PATCH");
  if (!ok) {
    r.status = 405;
    r.error = "method " + std::string(method) + " is not allowed here (allowed: " + allow + ")";
  }
  r.allow = std::move(allow);
  return r;
}

std::string scanFileNameList() {
  std::string list;
  for (const auto name : kScanFileNames) {
    if (!list.empty()) list += ", ";
    list += name;
  }
  return list;
}

// `r` refused with 404 for a path parameter (id, file or camera name) that
// breaks its rule: after the method check, so a bad method stays 405.
Route parameterNotFound(Route r, std::string error) {
  r.param_status = 404;
  r.error = std::move(error);
  return r;
}

// `r` for the camera `name`: 404 after the method check when the name
// breaks the board's rule (isCameraName).
Route withCamera(Route r, std::string_view name) {
  if (r.status != 0) return r;
  if (!isCameraName(name)) {
    return parameterNotFound(std::move(r), "no such camera: the name is not a valid camera name");
  }
  r.name = std::string(name);
  return r;
}

constexpr const char* kNotAScanId = "no such scan: the id is not a valid scan id";

Route notFound(std::string_view path) {
  Route r;
  r.status = 404;
  r.error = "no such endpoint: " + std::string(path);
  return r;
}

}  // namespace

Route route(std::string_view method, std::string_view path) {
  const Split split = splitPath(path);
  if (!split.error.empty()) {
    Route r;
    r.status = 400;
    r.error = split.error;
    return r;
  }
  const auto& s = split.segments;
  if (!s.empty() && s[0] == "api") {
    if (s.size() < 3 || s[1] != "v1") return notFound(path);
    const std::string_view what = s[2];
    if (what == "status" && s.size() == 3) {
      return withMethods(Endpoint::Status, method, true, false, false, false);
    }
    if (what == "system" && s.size() == 3) {
      return withMethods(Endpoint::System, method, true, false, false, false);
    }
    if (what == "system" && s.size() == 4 && s[3] == "update") {
      return withMethods(Endpoint::SystemUpdate, method, false, false, true, false);
    }
    if (what == "checks" && s.size() == 3) {
      return withMethods(Endpoint::Checks, method, true, true, false, false);
    }
    if (what == "fringe-check" && s.size() == 3) {
      return withMethods(Endpoint::FringeCheck, method, false, true, false, false);
    }
    if (what == "fringe-check" && s.size() == 4) {
      Route r = withMethods(Endpoint::FringePicture, method, true, false, false, false);
      const std::string_view file = s[3];
      if (r.status != 0) return r;
      if (!file.ends_with(".jpg"))
        return parameterNotFound(
            std::move(r), "no such picture: " + std::string(file) + " (fringe-check/<camera>.jpg)");
      return withCamera(std::move(r), file.substr(0, file.size() - 4));
    }
    if (what == "events" && s.size() == 3) {
      return withMethods(Endpoint::Events, method, true, false, false, false);
    }
    if (what == "scans") {
      if (s.size() == 3) return withMethods(Endpoint::Scans, method, true, true, false, false);
      if (s.size() == 4 || s.size() == 5) {
        Route r = s.size() == 4
                      ? withMethods(Endpoint::Scan, method, true, false, false, true)
                      : withMethods(Endpoint::ScanFile, method, true, false, false, false);
        if (r.status != 0) return r;
        if (!isValidScanId(s[3])) return parameterNotFound(std::move(r), kNotAScanId);
        r.id = std::string(s[3]);
        if (s.size() == 5) {
          if (!isScanFileName(s[4])) {
            return parameterNotFound(std::move(r), "no such scan file: " + std::string(s[4]) +
                                                       " (one of " + scanFileNameList() + ")");
          }
          r.name = std::string(s[4]);
        }
        return r;
      }
      if (s.size() == 6 && s[4] == "clouds") {
        Route r = withMethods(Endpoint::ScanCameraCloud, method, true, false, false, false);
        if (r.status != 0) return r;
        if (!isValidScanId(s[3])) return parameterNotFound(std::move(r), kNotAScanId);
        r.id = std::string(s[3]);
        // <camera>.ply, the camera name by the board's rule (isCameraName).
        const std::string_view file = s[5];
        const std::string_view camera =
            file.ends_with(".ply") ? file.substr(0, file.size() - 4) : std::string_view{};
        if (!isCameraName(camera)) {
          return parameterNotFound(std::move(r), "no such camera cloud: " + std::string(file) +
                                                     " (clouds/<camera>.ply)");
        }
        r.name = std::string(camera);
        return r;
      }
      return notFound(path);
    }
    if (what == "cameras") {
      if (s.size() == 3) return withMethods(Endpoint::Cameras, method, true, false, false, false);
      if (s.size() == 4 || s.size() == 5) {
        Route r;
        if (s.size() == 4) {
          r = withMethods(Endpoint::Camera, method, false, false, false, false, true);
        } else if (s[4] == "snapshot.jpg") {
          r = withMethods(Endpoint::CameraSnapshot, method, true, false, false, false);
        } else if (s[4] == "stream.mjpg") {
          r = withMethods(Endpoint::CameraStream, method, true, false, false, false);
        } else {
          return notFound(path);
        }
        return withCamera(std::move(r), s[3]);
      }
      return notFound(path);
    }
    if (what == "head" && s.size() == 3) {
      return withMethods(Endpoint::Head, method, true, false, true, false);
    }
    if (what == "calibration") {
      if (s.size() == 3) {
        return withMethods(Endpoint::Calibration, method, true, false, true, false);
      }
      // "session" and "rollback" are the session's: a camera of that name
      // cannot be reached here (board profiles name cameras main, aux, …).
      if (s.size() == 4 && s[3] == "session") {
        return withMethods(Endpoint::CalibrationSession, method, true, true, false, false);
      }
      if (s.size() == 4 && s[3] == "rollback") {
        return withMethods(Endpoint::CalibrationRollback, method, false, true, false, false);
      }
      if (s.size() == 4) {
        Route r = withMethods(Endpoint::CalibrationFile, method, true, false, false, false);
        return withCamera(std::move(r), s[3]);
      }
      if (s.size() == 5 && s[3] == "session") {
        if (s[4] == "boards")
          return withMethods(Endpoint::CalibrationBoards, method, false, true, false, false);
        if (s[4] == "planes")
          return withMethods(Endpoint::CalibrationPlanes, method, false, true, false, false);
        if (s[4] == "solve")
          return withMethods(Endpoint::CalibrationSolve, method, false, true, false, false);
        if (s[4] == "install")
          return withMethods(Endpoint::CalibrationInstall, method, false, true, false, false);
      }
    }
    return notFound(path);
  }
  if (s.size() == 1 && s[0] == "metrics") {
    return withMethods(Endpoint::Metrics, method, true, false, false, false);
  }
  // The page: "/" is index.html; hidden files (".name") are never served.
  Route r = withMethods(Endpoint::Static, method, true, false, false, false);
  if (r.status != 0) return r;
  for (const auto segment : s) {
    if (segment.front() == '.') {
      r.param_status = 404;
      r.error = "no such file: " + std::string(path);
      return r;
    }
    if (!r.name.empty()) r.name += '/';
    r.name += segment;
  }
  if (r.name.empty()) r.name = "index.html";
  return r;
}

bool needsToken(Endpoint endpoint) {
  return endpoint != Endpoint::Status && endpoint != Endpoint::Static;
}

std::string_view staticContentType(std::string_view file_name) {
  static constexpr std::array<std::pair<std::string_view, std::string_view>, 15> kTypes{{
      {".html", "text/html; charset=utf-8"},
      {".htm", "text/html; charset=utf-8"},
      {".js", "text/javascript; charset=utf-8"},
      {".mjs", "text/javascript; charset=utf-8"},
      {".css", "text/css; charset=utf-8"},
      {".json", "application/json"},
      {".map", "application/json"},
      {".svg", "image/svg+xml"},
      {".png", "image/png"},
      {".jpg", "image/jpeg"},
      {".jpeg", "image/jpeg"},
      {".ico", "image/x-icon"},
      {".woff2", "font/woff2"},
      {".txt", "text/plain; charset=utf-8"},
      {".wasm", "application/wasm"},
  }};
  const auto dot = file_name.rfind('.');
  const auto slash = file_name.rfind('/');
  if (dot != std::string_view::npos && (slash == std::string_view::npos || dot > slash)) {
    const std::string_view ext = file_name.substr(dot);
    for (const auto& [e, type] : kTypes) {
      if (ext.size() == e.size() &&
          std::equal(ext.begin(), ext.end(), e.begin(), [](char a, char b) {
            return (a >= 'A' && a <= 'Z' ? static_cast<char>(a - 'A' + 'a') : a) == b;
          })) {
        return type;
      }
    }
  }
  return "application/octet-stream";
}

std::string_view scanFileContentType(std::string_view name) {
  if (name == "depth.tiff") return "image/tiff";
  if (name.ends_with(".png")) return "image/png";
  if (name.ends_with(".json")) return "application/json";
  return "application/octet-stream";  // cloud.ply
}

}  // namespace cylscan::firmware::http
