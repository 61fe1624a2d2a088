// SPDX-License-Identifier: Apache-2.0
// What the daemon's HTTP layer sees of the head: one scan at a time, the
// stored scans and their files, the installed calibration, live events and
// the metrics of the real-time loop. `ScanService` (firmware/daemon/scan_service.hpp) is the
// implementation on a drivers::Board; the HTTP layer (firmware/http/http_api.hpp) knows only
// this interface, so it never touches the board, the real-time thread or the
// file system of the data directory itself.
//
// Every call is thread-safe and returns quickly: nothing here waits for a
// scan, a frame or the stage. JSON shapes are those of docs/http-api.md.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <future>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace cylscan::firmware {

// A request the service refuses, with the HTTP status that says why:
// 400 bad options, 404 no such scan, 409 another scan runs (or the scan to
// delete is running), 413 too large, 422 a calibration that does not fit the
// board, 507 no room on the disk for one more scan, 503 the head is in a
// state that cannot scan (e.g. shutting down).
class ServiceError : public std::runtime_error {
 public:
  ServiceError(int http_status, const std::string& message)
      : std::runtime_error(message), status_(http_status) {}
  int httpStatus() const { return status_; }

 private:
  int status_;
};

// One server-sent event: `event: <name>` and `data: <json>` (one line).
// Its implicit move constructor is noexcept, as nlohmann::json's is; the
// exception-escape check follows json's move into its invariant assertions,
// which never throw.
struct HeadEvent {        // NOLINT(bugprone-exception-escape)
  std::uint64_t seq = 0;  // increasing, for `id:` and Last-Event-ID
  std::string name;       // "state" | "progress" | "scan" | "error"
  nlohmann::json data;
};

// A subscriber's bounded queue of events. When a slow subscriber's queue is
// full the oldest events are dropped and `dropped()` counts them; the service
// never blocks on a subscriber.
class EventStream {
 public:
  virtual ~EventStream() = default;
  // The next event, or nullopt when none came within `timeout` (or the
  // service is stopping: then `closed()` is true).
  virtual std::optional<HeadEvent> next(std::chrono::milliseconds timeout) = 0;
  virtual bool closed() const = 0;
  virtual std::uint64_t dropped() const = 0;
};

// One picture of a camera's live view: a JPEG and the figures of the frame
// it shows (firmware/live_picture.hpp).
struct LiveFrame {
  std::uint64_t sequence = 0;  // counts the pictures of this stream from 1
  std::string jpeg;
  double focus = 0.0;      // variance of the Laplacian over the central half
  double saturated = 0.0;  // share of the pixels at full scale
};

// What a client of the live view asks for.
struct LiveViewRequest {
  std::string camera;
  bool saturation_overlay = false;
};

// A subscription to one camera's live view. It holds only the newest
// picture: a slow reader skips pictures, it never makes the head wait. It
// ends when a scan or a capture starts, when the camera fails and when the
// service stops.
class LiveStream {
 public:
  virtual ~LiveStream() = default;
  // The next picture taken after the last one returned (the first: one
  // exposed after the stream opened); nullopt when none came within
  // `timeout` or the stream has ended.
  virtual std::optional<LiveFrame> next(std::chrono::milliseconds timeout) = 0;
  virtual bool ended() const = 0;
  // Why it ended ("a scan started", ...); empty while it runs.
  virtual std::string endReason() const = 0;
  // The HTTP status that says why it ended, as ServiceError's: 409 a scan
  // or a capture started, 503 the camera failed or the service stops.
  virtual int endStatus() const = 0;
};

// A system update being received (PUT /api/v1/system/update): the HTTP
// layer hands it the body as it arrives, then finish() once every byte of
// Content-Length is in. Destroyed unfinished (the connection closed early),
// it removes what it wrote and records the update failed ("truncated upload").
class UpdateUpload {
 public:
  virtual ~UpdateUpload() = default;
  // Appends to the file; a write error is kept and reported by finish().
  virtual void write(std::string_view bytes) = 0;
  // The whole bundle is in: checks it with the updater and starts the
  // install in the background. Returns the 202 answer ({"state":
  // "installing", "version"}); ServiceError 422 a bundle the updater refuses
  // or made for another head, 503 no updater, 507 it could not be written.
  virtual nlohmann::json finish() = 0;
};

class HeadService {
 public:
  virtual ~HeadService() = default;

  // GET /api/v1/status.
  virtual nlohmann::json status() const = 0;
  // GET /api/v1/system: the version, host name, booted slot and data space.
  virtual nlohmann::json system() const = 0;

  // POST /api/v1/scans: starts a scan with `options` (a JSON object, may be
  // empty) and returns its id at once. ServiceError 400/409/503/507.
  virtual std::string startScan(const nlohmann::json& options) = 0;

  // GET /api/v1/scans: newest first.
  virtual nlohmann::json listScans() const = 0;

  // GET /api/v1/scans/{id}: nullopt when there is no such scan. `id` is
  // checked by isValidScanId() first; an invalid one is simply not found.
  virtual std::optional<nlohmann::json> scan(std::string_view id) const = 0;

  // A finished scan's file: `name` is one of scanFileNames(); nullopt when
  // the scan or the file does not exist (yet). The path is inside the data
  // directory and is never built from an unchecked string.
  virtual std::optional<std::filesystem::path> scanFile(std::string_view id,
                                                        std::string_view name) const = 0;

  // DELETE /api/v1/scans/{id}: false when there is no such scan;
  // ServiceError 409 while it runs.
  virtual bool deleteScan(std::string_view id) = 0;

  // PUT /api/v1/calibration: validates the quasi-calibration file's bytes
  // (magic, version, size, CRC, the board's image size for `camera`) and
  // installs it atomically in place of the old one. ServiceError 400/422.
  // Returns calibrationInfo(camera).
  virtual nlohmann::json installCalibration(std::string_view camera, std::string_view bytes) = 0;
  // GET /api/v1/calibration (JSON) and its file.
  virtual nlohmann::json calibrationInfo(std::string_view camera) const = 0;
  virtual std::optional<std::filesystem::path> calibrationFile(std::string_view camera) const = 0;

  // The 360° head (docs/http-api.md). PUT /api/v1/head: validates head.json's text
  // (format, rotations; the cameras named must be the board's, the frame
  // main) and installs it atomically. ServiceError 400/422. Returns headInfo().
  virtual nlohmann::json installHead(std::string_view /*text*/) {
    throw ServiceError(404, "this head has no extrinsics to install");
  }
  // GET /api/v1/head: the installed head.json, nullopt when none is.
  virtual std::optional<nlohmann::json> headInfo() const { return std::nullopt; }
  // GET /api/v1/scans/{id}/clouds/{camera}.ply: a ring scan's per-camera cloud
  // (its camera's own frame); nullopt when the scan or the file does not exist.
  virtual std::optional<std::filesystem::path> scanCameraCloud(std::string_view /*id*/,
                                                               std::string_view /*camera*/) const {
    return std::nullopt;
  }

  // GET /api/v1/cameras: the board's cameras with their exposure and gain.
  virtual nlohmann::json cameras() const = 0;
  // PATCH /api/v1/cameras/{name}: `controls` holds exposure_us and/or gain.
  // ServiceError 400 (a value out of range or of the wrong type, naming the
  // key; an unknown key), 404 no such camera, 409 a scan runs. The values are
  // kept across restarts and used by scans and the live view. Returns the
  // camera as cameras() lists it.
  virtual nlohmann::json setCameraControls(std::string_view camera,
                                           const nlohmann::json& controls) = 0;
  // GET /api/v1/cameras/{name}/stream.mjpg and snapshot.jpg (its first
  // picture). ServiceError 404 no such camera, 409 a scan runs, 503 the
  // service is stopping.
  virtual std::unique_ptr<LiveStream> openLiveView(const LiveViewRequest& request) = 0;

  // POST /api/v1/fringe-check: body null or {"scene"?}. A short scan of
  // every camera at the head's settings; the future gives the figures of
  // each (firmware/fringe_check.hpp) once taken, or throws the ServiceError
  // (400 a bad body, 409 a scan or capture runs, 503 stopping or failed).
  virtual std::future<nlohmann::json> fringeCheck(const nlohmann::json& body) = 0;
  // GET /api/v1/fringe-check/{camera}.jpg: the last fringe check's picture
  // of the camera (JPEG); ServiceError 404 when there is none.
  virtual std::string fringePicture(std::string_view camera) const = 0;

  // POST /api/v1/checks: `request` is {"artifact": "sphere", "radius_mm": R,
  // "scene"?, "tolerance_mm"?}. Scans the artifact like any scan and
  // measures it; returns the check's id (the scan's). ServiceError 400 (the
  // key named), 409 a scan runs or main has no calibration, 503, 507.
  virtual std::string startCheck(const nlohmann::json& request) = 0;
  // GET /api/v1/checks: the running check, then the history, newest first.
  virtual nlohmann::json listChecks() const = 0;

  // The calibration session (docs/http-api.md, calibration session). Each
  // throws ServiceError: 404 no session, 409 the head or the session is
  // busy, 400 a bad body (naming the key), 503 stopping.
  // POST /api/v1/calibration/session: body null or {"board"?}; the session.
  virtual nlohmann::json startSession(const nlohmann::json& body) = 0;
  // GET /api/v1/calibration/session; nullopt when there is none.
  virtual std::optional<nlohmann::json> session() const = 0;
  // POST …/session/boards: queues one checkerboard pair; the future gives
  // {"index", "found"} once it is taken, or throws the ServiceError.
  virtual std::future<nlohmann::json> captureBoard(const nlohmann::json& body) = 0;
  // POST …/session/planes: queues one plane pose; {"index"}.
  virtual nlohmann::json capturePlane(const nlohmann::json& body) = 0;
  // POST …/session/solve: starts the solve in the background.
  virtual void solveSession() = 0;
  // POST …/session/install: the installed calibration's info; the one it
  // replaces is kept.
  virtual nlohmann::json installSession() = 0;
  // POST /api/v1/calibration/rollback: the kept calibration installed again
  // (and the one it replaces kept in its place); 404 none kept.
  virtual nlohmann::json rollbackCalibration() = 0;

  // PUT /api/v1/system/update: claims the update for a bundle of `bytes`
  // bytes, before any byte is read. ServiceError 413 over the configured
  // size, 503 no updater (RAUC) to install it, 409 a scan, a capture or
  // another update runs, 507 no room for it on the data file system.
  virtual std::unique_ptr<UpdateUpload> beginUpdate(std::uint64_t /*bytes*/) {
    throw ServiceError(503, "updates need RAUC");
  }

  // GET /api/v1/events.
  virtual std::unique_ptr<EventStream> subscribe() = 0;

  // The service's part of GET /metrics (Prometheus text format 0.0.4):
  // scans done/failed, scan duration, frame and step timing histograms.
  virtual std::string metricsText() const = 0;
};

// The files a scan may have, as the API names them.
inline constexpr std::string_view kScanFileNames[] = {"cloud.ply", "depth.tiff", "texture.png",
                                                      "phase.png", "depth.png",  "scan.json"};

inline bool isScanFileName(std::string_view name) {
  return std::find(std::begin(kScanFileNames), std::end(kScanFileNames), name) !=
         std::end(kScanFileNames);
}

// Scan ids are what the service makes (e.g. "20261201-160102-3f9a"):
// [0-9a-z-], 1..64 characters, not starting with '-' or '.'. Everything
// else is rejected before any lookup.
inline bool isValidScanId(std::string_view id) {
  if (id.empty() || id.size() > 64 || id.front() == '-') return false;
  for (char c : id) {
    const bool ok = (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') || c == '-';
    if (!ok) return false;
  }
  return true;
}

}  // namespace cylscan::firmware
