// SPDX-License-Identifier: Apache-2.0
// The daemon's data directory (layout in docs/daemon.md):
//   scans/<id>/scan.json + its files   one finished (done or failed) scan
//   scans/.partial-<id>/               a scan being written (never listed)
//   scans/.broken-<id>/                a scan dir whose scan.json was unusable
//   calibration/<camera>.qcal          the installed quasi-calibrations
//   calibration/head.json              the installed head extrinsics (360° head)
//   scans/<id>/clouds/<camera>.ply     a ring scan's per-camera clouds
// A scan is written in its partial dir, every file and the dir fsynced, then
// renamed to <id> and the parent fsynced: a crash leaves either no scan or a
// whole one. Thread-safe (one mutex around the index; no call waits for more
// than its own file system work).
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "firmware/daemon/daemon_config.hpp"
#include "firmware/daemon/scan_record.hpp"

namespace cylscan::firmware {

class ScanStore {
 public:
  // Creates the directories when missing, removes leftover partial dirs and
  // moves scan dirs without a valid scan.json aside (both logged), and
  // indexes the scans. std::system_error naming the path when the data
  // directory cannot be made or read.
  explicit ScanStore(std::filesystem::path data_dir);

  const std::filesystem::path& dataDir() const { return dir_; }
  std::filesystem::path scansDir() const { return dir_ / "scans"; }

  // A fresh, empty partial dir for scan `id` (an isValidScanId id).
  std::filesystem::path beginScan(const std::string& id);
  // Writes `scan` (a done or failed scan; its files are the ones present) as
  // scan.json into the partial dir of its id, fsyncs everything and renames
  // it to scans/<id>. With keep_files false the partial's other files are
  // removed first (a failed scan keeps only its record).
  void commit(const ScanRecord& scan, bool keep_files = true);
  // Removes a partial dir (nothing happens when there is none).
  void discard(const std::string& id);

  std::vector<ScanRecord> list() const;  // newest first
  std::optional<ScanRecord> get(std::string_view id) const;
  // `name` one of kScanFileNames; nullopt unless the scan and the file exist.
  std::optional<std::filesystem::path> file(std::string_view id, std::string_view name) const;
  // clouds/<camera>.ply of a finished scan; nullopt unless it exists.
  std::optional<std::filesystem::path> cameraCloud(std::string_view id,
                                                   std::string_view camera) const;
  bool remove(std::string_view id);
  std::size_t count() const;
  std::uint64_t totalBytes() const;

  // Removes the oldest scans while there are more than max_scans or they take
  // more than max_bytes (0 = no limit), never `keep`. The ids removed.
  std::vector<std::string> applyRetention(const RetentionConfig& retention,
                                          const std::string& keep);

  // Free bytes for an unprivileged writer of the data directory (statvfs).
  std::uint64_t freeBytes() const;

  // calibration/: the installed calibrations and head.json.
  CalibrationDir calibrations() const { return CalibrationDir(dir_ / "calibration"); }
  // calibration/<camera>.qcal, whether or not it exists.
  std::filesystem::path calibrationPath(std::string_view camera) const;
  // Written atomically (temp, fsync, rename, fsync dir): the old one stays
  // whole until the new one is, and is then kept as <camera>.qcal.previous.
  void installCalibration(std::string_view camera, std::span<const std::byte> bytes);
  // Swaps the installed calibration and the kept one (each written
  // atomically), so a second rollback undoes the first; false when none is kept.
  bool rollbackCalibration(std::string_view camera);
  // calibration/head.json (the head's extrinsics), written the same way.
  std::filesystem::path headPath() const { return calibrations().headFile(); }
  void installHead(std::string_view text);

 private:
  struct Entry {
    ScanRecord scan;
    std::uint64_t bytes = 0;
  };
  // Oldest first: by "created", then id.
  std::vector<std::string> orderLocked() const;
  void load();

  std::filesystem::path dir_;
  mutable std::mutex mutex_;
  std::map<std::string, Entry, std::less<>> scans_;
};

// The bytes of the regular files under `dir` (0 when missing).
std::uint64_t directoryBytes(const std::filesystem::path& dir);
// fsync of every regular file and directory under `dir`, and of `dir`.
void syncTree(const std::filesystem::path& dir);

}  // namespace cylscan::firmware
