// SPDX-License-Identifier: Apache-2.0
#include "firmware/daemon/scan_store.hpp"

#include <fcntl.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <system_error>

#include "common/vocabulary.hpp"
#include "firmware/daemon/head_service.hpp"
#include "firmware/daemon/log.hpp"
#include "formats/atomic_file.hpp"
#include "formats/file_reading.hpp"

namespace cylscan::firmware {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr std::uintmax_t kMaxScanJsonBytes = 1 << 20;
constexpr std::string_view kPartialPrefix = ".partial-";
constexpr std::string_view kBrokenPrefix = ".broken-";

[[noreturn]] void throwErrno(const std::string& what, const fs::path& path) {
  throw std::system_error(errno, std::generic_category(), what + " " + path.string());
}

void syncFile(const fs::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throwErrno("cannot open", path);
  if (::fsync(fd) != 0) {
    const int err = errno;
    ::close(fd);
    errno = err;
    throwErrno("cannot fsync", path);
  }
  ::close(fd);
}

// The record of a scan dir, checked: ScanRecordError saying why it is unusable.
ScanRecord readRecord(const fs::path& file, const std::string& id) {
  const json text = formats::readJsonFile(file, kMaxScanJsonBytes);
  ScanRecord scan;
  try {
    scan = text.get<ScanRecord>();
  } catch (const ScanRecordError& e) {
    throw ScanRecordError(std::string("scan.json: ") + e.what());
  }
  if (scan.id != id) throw ScanRecordError("scan.json's id is not the directory's");
  if (!scan.finishedScan())
    throw ScanRecordError("scan.json's state is '" + toString(scan.state) + "'");
  return scan;
}

}  // namespace

std::uint64_t directoryBytes(const fs::path& dir) {
  std::error_code ec;
  std::uint64_t total = 0;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code e2;
    if (it->is_regular_file(e2)) total += it->file_size(e2);
  }
  return total;
}

void syncTree(const fs::path& dir) {
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    if (entry.is_symlink()) continue;
    if (entry.is_regular_file())
      syncFile(entry.path());
    else if (entry.is_directory())
      formats::syncDirectory(entry.path());
  }
  formats::syncDirectory(dir);
}

ScanStore::ScanStore(fs::path data_dir) : dir_(std::move(data_dir)) {
  fs::create_directories(dir_ / "scans");
  fs::create_directories(dir_ / "calibration");
  load();
}

void ScanStore::load() {
  for (const auto& entry : fs::directory_iterator(scansDir())) {
    const std::string name = entry.path().filename().string();
    if (name.starts_with(kPartialPrefix)) {
      logWarn("removing the unfinished scan " + entry.path().string() + " (left by a crash)");
      std::error_code ec;
      fs::remove_all(entry.path(), ec);
      if (ec) logError("cannot remove " + entry.path().string() + ": " + ec.message());
      continue;
    }
    if (name.starts_with(kBrokenPrefix)) continue;
    if (!entry.is_directory() || !isValidScanId(name)) {
      logWarn("ignoring " + entry.path().string() + ": not a scan directory");
      continue;
    }
    std::string fault;
    ScanRecord scan;
    try {
      scan = readRecord(entry.path() / "scan.json", name);
    } catch (const std::exception& e) {
      fault = e.what();
    }
    if (!fault.empty()) {
      const fs::path aside = scansDir() / (std::string(kBrokenPrefix) + name);
      std::error_code ec;
      fs::remove_all(aside, ec);
      fs::rename(entry.path(), aside, ec);
      // One log line per broken scan found at startup: not a hot path.
      // NOLINTNEXTLINE(performance-inefficient-string-concatenation)
      logWarn("scan " + name + " skipped: " + fault + "; moved to " + aside.string() +
              (ec ? " failed: " + ec.message() : ""));
      continue;
    }
    scans_[name] = Entry{std::move(scan), directoryBytes(entry.path())};
  }
}

fs::path ScanStore::beginScan(const std::string& id) {
  if (!isValidScanId(id)) throw std::invalid_argument("not a scan id: '" + id + "'");
  fs::path partial = scansDir() / (std::string(kPartialPrefix) + id);
  fs::remove_all(partial);
  fs::create_directory(partial);
  return partial;
}

void ScanStore::discard(const std::string& id) {
  if (!isValidScanId(id)) return;
  std::error_code ec;
  fs::remove_all(scansDir() / (std::string(kPartialPrefix) + id), ec);
}

void ScanStore::commit(const ScanRecord& scan, bool keep_files) {
  const std::string& id = scan.id;
  if (!isValidScanId(id)) throw std::invalid_argument("not a scan id: '" + id + "'");
  if (!scan.finishedScan()) throw std::invalid_argument("scan " + id + " has not finished");
  const fs::path partial = scansDir() / (std::string(kPartialPrefix) + id);
  const fs::path final_dir = scansDir() / id;
  if (!fs::is_directory(partial)) fs::create_directory(partial);
  if (!keep_files) {
    for (const auto& entry : fs::directory_iterator(partial))
      fs::remove_all(entry.path());
  }
  formats::writeFileAtomically(partial / "scan.json", json(scan).dump(2) + "\n");
  syncTree(partial);
  if (fs::exists(final_dir)) throw std::runtime_error("scan " + id + " exists already");
  fs::rename(partial, final_dir);
  formats::syncDirectory(scansDir());
  const std::uint64_t bytes = directoryBytes(final_dir);
  const std::lock_guard lock(mutex_);
  scans_[id] = Entry{scan, bytes};
}

std::vector<std::string> ScanStore::orderLocked() const {
  std::vector<std::pair<std::string, std::string>> keys;
  for (const auto& [id, e] : scans_)
    keys.emplace_back(e.scan.created, id);
  std::sort(keys.begin(), keys.end());
  std::vector<std::string> ids;
  ids.reserve(keys.size());
  for (auto& k : keys)
    ids.push_back(std::move(k.second));
  return ids;
}

std::vector<ScanRecord> ScanStore::list() const {
  const std::lock_guard lock(mutex_);
  std::vector<ScanRecord> out;
  const auto ids = orderLocked();
  for (auto it = ids.rbegin(); it != ids.rend(); ++it)
    out.push_back(scans_.find(*it)->second.scan);
  return out;
}

std::optional<ScanRecord> ScanStore::get(std::string_view id) const {
  if (!isValidScanId(id)) return std::nullopt;
  const std::lock_guard lock(mutex_);
  auto it = scans_.find(id);
  if (it == scans_.end()) return std::nullopt;
  return it->second.scan;
}

std::optional<fs::path> ScanStore::file(std::string_view id, std::string_view name) const {
  if (!isValidScanId(id) || !isScanFileName(name)) return std::nullopt;
  {
    const std::lock_guard lock(mutex_);
    if (scans_.find(id) == scans_.end()) return std::nullopt;
  }
  const fs::path path = scansDir() / std::string(id) / std::string(name);
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return std::nullopt;
  return path;
}

std::optional<fs::path> ScanStore::cameraCloud(std::string_view id, std::string_view camera) const {
  if (!isValidScanId(id) || !isCameraName(camera)) return std::nullopt;
  {
    const std::lock_guard lock(mutex_);
    if (scans_.find(id) == scans_.end()) return std::nullopt;
  }
  const fs::path path = scansDir() / std::string(id) / "clouds" / (std::string(camera) + ".ply");
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return std::nullopt;
  return path;
}

bool ScanStore::remove(std::string_view id) {
  if (!isValidScanId(id)) return false;
  const std::lock_guard lock(mutex_);
  auto it = scans_.find(id);
  if (it == scans_.end()) return false;
  // Renamed out of the index's names first, so a crash mid-way leaves a
  // partial dir (cleaned at the next start), never a half-deleted scan.
  const fs::path dir = scansDir() / std::string(id);
  const fs::path doomed = scansDir() / (std::string(kPartialPrefix) + std::string(id));
  std::error_code ec;
  fs::remove_all(doomed, ec);
  fs::rename(dir, doomed);
  formats::syncDirectory(scansDir());
  scans_.erase(it);
  fs::remove_all(doomed, ec);
  if (ec) logWarn("cannot remove " + doomed.string() + ": " + ec.message());
  return true;
}

std::size_t ScanStore::count() const {
  const std::lock_guard lock(mutex_);
  return scans_.size();
}

std::uint64_t ScanStore::totalBytes() const {
  const std::lock_guard lock(mutex_);
  std::uint64_t total = 0;
  for (const auto& [id, e] : scans_)
    total += e.bytes;
  return total;
}

std::vector<std::string> ScanStore::applyRetention(const RetentionConfig& retention,
                                                   const std::string& keep) {
  std::vector<std::string> doomed;
  {
    const std::lock_guard lock(mutex_);
    std::uint64_t count = scans_.size();
    std::uint64_t bytes = 0;
    for (const auto& [id, e] : scans_)
      bytes += e.bytes;
    for (const std::string& id : orderLocked()) {
      const bool over = (retention.max_scans > 0 && count > retention.max_scans) ||
                        (retention.max_bytes > 0 && bytes > retention.max_bytes);
      if (!over) break;
      if (id == keep) continue;
      doomed.push_back(id);
      --count;
      bytes -= scans_.find(id)->second.bytes;
    }
  }
  for (const auto& id : doomed) {
    remove(id);
    logInfo("retention: removed scan " + id);
  }
  return doomed;
}

std::uint64_t ScanStore::freeBytes() const {
  struct statvfs s {};
  if (::statvfs(dir_.c_str(), &s) != 0) throwErrno("cannot statvfs", dir_);
  return static_cast<std::uint64_t>(s.f_bavail) * static_cast<std::uint64_t>(s.f_frsize);
}

fs::path ScanStore::calibrationPath(std::string_view camera) const {
  return calibrations().calibrationFile(camera);
}

namespace {

fs::path previousOf(const fs::path& file) {
  fs::path previous = file;
  previous += ".previous";
  return previous;
}

std::optional<std::string> readWhole(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream bytes;
  bytes << in.rdbuf();
  if (!in.good() && !in.eof())
    throw std::system_error(errno, std::generic_category(), "cannot read " + file.string());
  return bytes.str();
}

}  // namespace

void ScanStore::installCalibration(std::string_view camera, std::span<const std::byte> bytes) {
  const fs::path file = calibrationPath(camera);
  if (const auto installed = readWhole(file))
    formats::writeFileAtomically(previousOf(file), std::string_view(*installed));
  formats::writeFileAtomically(file, bytes);
}

bool ScanStore::rollbackCalibration(std::string_view camera) {
  const fs::path file = calibrationPath(camera);
  const auto previous = readWhole(previousOf(file));
  if (!previous) return false;
  const auto installed = readWhole(file);
  formats::writeFileAtomically(file, std::string_view(*previous));
  if (installed) {
    formats::writeFileAtomically(previousOf(file), std::string_view(*installed));
  } else {
    fs::remove(previousOf(file));
  }
  return true;
}

void ScanStore::installHead(std::string_view text) {
  formats::writeFileAtomically(headPath(), text);
}

}  // namespace cylscan::firmware
