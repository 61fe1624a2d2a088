// SPDX-License-Identifier: Apache-2.0
#include "formats/capture_bundle.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <stdexcept>
#include <system_error>
#include <utility>

#include "formats/atomic_file.hpp"
#include "formats/file_reading.hpp"
#include "formats/input_error.hpp"
#include "formats/png.hpp"
#include "formats/size_text.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr std::uintmax_t kMaxCaptureJsonBytes = 64u << 20;
constexpr std::string_view kCaptureJson = "capture.json";

std::string inQuotes(std::string_view s) {
  return "\"" + std::string(s) + "\"";
}

std::string jsonTypeName(const json& value) {
  return value.type_name();
}

std::optional<std::string> cameraNameFault(std::string_view name) {
  if (name.empty()) return "is empty";
  if (name == "." || name == "..") return "is not a directory name";
  if (name.find_first_of(std::string_view("/\\\0", 3)) != std::string_view::npos) {
    return "must be a single path component (no '/', '\\' or NUL)";
  }
  return std::nullopt;
}

constexpr const char* kMainInCameraSets =
    "\"camera_sets\" has camera \"main\", whose sets are the top-level \"sets\"";

// Where a camera's set is in capture.json: "sets.high" or "camera_sets.cam90.high".
std::string setWhere(std::string_view camera, FringeSet id, bool own = true) {
  if (!own) return "sets." + std::string(toString(id));
  return "camera_sets." + std::string(camera) + "." + std::string(toString(id));
}

std::optional<std::string> setFault(const FringeSetInfo& set, const std::string& where) {
  if (!std::isfinite(set.period_deg) || set.period_deg <= 0) {
    return inQuotes(where + ".period_deg") + " must be a finite number > 0";
  }
  if (set.stage_deg.size() < static_cast<std::size_t>(kMinFramesPerSet)) {
    return "set " + inQuotes(where) + " has " + std::to_string(set.stage_deg.size()) +
           " frames; at least " + std::to_string(kMinFramesPerSet) + " are needed";
  }
  for (std::size_t k = 0; k < set.stage_deg.size(); ++k) {
    if (!std::isfinite(set.stage_deg[k])) {
      return inQuotes(where + ".stage_deg[" + std::to_string(k) + "]") + " is not finite";
    }
  }
  return std::nullopt;
}

// Fault of a pair of sets: the top-level "sets", or `camera`'s "camera_sets"
// entry when `own`. A set may be absent only where `required` allows it, and
// never both.
std::optional<std::string> setPairFault(const CaptureInfo& info, std::string_view camera, bool own,
                                        SetsRequired required) {
  const std::string where = own ? "camera_sets." + std::string(camera) : "sets";
  bool any = false;
  for (const FringeSet id : kFringeSets) {
    const FringeSetInfo& set = own ? info.setOf(camera, id) : info.set(id);
    const bool absent = set.stage_deg.empty() && set.period_deg == 0;
    if (absent && required == SetsRequired::OneOrBoth) continue;
    if (auto fault = setFault(set, setWhere(camera, id, own))) return fault;
    any = true;
  }
  if (!any) return "neither set \"high\" nor set \"low\" in " + inQuotes(where);
  return std::nullopt;
}

// Fault of the info itself (shared by reader and writer), in capture.json terms.
std::optional<std::string> captureInfoFault(const CaptureInfo& info, SetsRequired required) {
  if (info.cameras.empty()) return "\"cameras\" is empty (it must contain \"main\")";
  for (std::size_t i = 0; i < info.cameras.size(); ++i) {
    const std::string& name = info.cameras[i];
    if (auto fault = cameraNameFault(name)) {
      return "camera name " + inQuotes(name) + " in \"cameras\" " + *fault;
    }
    for (std::size_t j = 0; j < i; ++j) {
      if (info.cameras[j] == name)
        return "camera " + inQuotes(name) + " is listed twice in \"cameras\"";
    }
  }
  if (std::find(info.cameras.begin(), info.cameras.end(), "main") == info.cameras.end()) {
    return "\"cameras\" does not contain \"main\"";
  }
  if (auto fault = setPairFault(info, "main", false, required)) return fault;
  for (const auto& [camera, sets] : info.camera_sets) {
    if (std::find(info.cameras.begin(), info.cameras.end(), camera) == info.cameras.end()) {
      return "\"camera_sets\" has camera " + inQuotes(camera) + ", which is not in \"cameras\"";
    }
    if (camera == "main") return kMainInCameraSets;
    if (auto fault = setPairFault(info, camera, true, required)) return fault;
  }
  return std::nullopt;
}

// Turns the parsed capture.json into CaptureInfo, or InputError naming the file.
class CaptureJsonParser {
 public:
  CaptureJsonParser(fs::path file, SetsRequired required)
      : file_(std::move(file)), required_(required) {}

  CaptureInfo parse(const json& doc) const {
    if (!doc.is_object()) fail("the top level is a " + jsonTypeName(doc) + ", not a JSON object");
    CaptureInfo info;
    checkFormat(doc);
    info.cameras = cameras(doc);
    readSets(doc, info);
    readCameraSets(doc, info);
    info.extra = doc;
    info.extra.erase("format");
    info.extra.erase("cameras");
    info.extra.erase("sets");
    info.extra.erase("camera_sets");
    info.extra.erase("frame_sizes");
    if (json extras = setExtras(doc.at("sets")); !extras.empty()) info.extra["sets"] = extras;
    if (const auto own = doc.find("camera_sets"); own != doc.end()) {
      json camera_extras = json::object();
      for (const auto& [camera, sets] : own->items()) {
        if (json extras = setExtras(sets); !extras.empty()) camera_extras[camera] = extras;
      }
      if (!camera_extras.empty()) info.extra["camera_sets"] = std::move(camera_extras);
    }
    // The rules shared with the writer.
    if (auto fault = captureInfoFault(info, required_)) fail(*fault);
    readFrameSizes(doc, info);
    return info;
  }

 private:
  [[noreturn]] void fail(const std::string& fault) const { throw InputError(file_, fault); }

  // The unknown fields of a {"high": {...}, "low": {...}} object, by set.
  static json setExtras(const json& sets) {
    json out = json::object();
    for (const FringeSet id : kFringeSets) {
      const auto set = sets.find(std::string(toString(id)));
      if (set == sets.end()) continue;  // the absent set of a one-set bundle
      json extra = *set;
      extra.erase("period_deg");
      extra.erase("stage_deg");
      if (!extra.empty()) out[std::string(toString(id))] = std::move(extra);
    }
    return out;
  }

  void checkFormat(const json& doc) const {
    const auto it = doc.find("format");
    if (it == doc.end()) fail("missing \"format\" (expected " + inQuotes(kCaptureFormat) + ")");
    if (!it->is_string()) fail("\"format\" is a " + jsonTypeName(*it) + ", not a string");
    if (it->get_ref<const std::string&>() != kCaptureFormat) {
      fail("unsupported format " + inQuotes(it->get_ref<const std::string&>()) + " (expected " +
           inQuotes(kCaptureFormat) + ")");
    }
  }

  std::vector<std::string> cameras(const json& doc) const {
    const auto it = doc.find("cameras");
    if (it == doc.end()) fail("missing \"cameras\" (a list of camera names with \"main\")");
    if (!it->is_array()) fail("\"cameras\" is a " + jsonTypeName(*it) + ", not a list of names");
    std::vector<std::string> names;
    for (std::size_t i = 0; i < it->size(); ++i) {
      const json& name = (*it)[i];
      if (!name.is_string()) {
        fail("\"cameras[" + std::to_string(i) + "]\" is a " + jsonTypeName(name) +
             ", not a string");
      }
      names.push_back(name.get<std::string>());
    }
    return names;
  }

  void readSets(const json& doc, CaptureInfo& info) const {
    const auto it = doc.find("sets");
    if (it == doc.end()) fail("missing \"sets\" (expected \"high\" and \"low\")");
    if (!it->is_object()) fail("\"sets\" is a " + jsonTypeName(*it) + ", not an object");
    readSetPair(*it, "sets", info.high, info.low);
  }

  // The extension "camera_sets": {camera: {"high": {...}, "low": {...}}}, each
  // camera one of "cameras", its sets validated like "sets" (both, unless
  // SetsRequired::OneOrBoth).
  void readCameraSets(const json& doc, CaptureInfo& info) const {
    const auto it = doc.find("camera_sets");
    if (it == doc.end()) return;
    if (!it->is_object()) fail("\"camera_sets\" is a " + jsonTypeName(*it) + ", not an object");
    for (const auto& [camera, value] : it->items()) {
      if (std::find(info.cameras.begin(), info.cameras.end(), camera) == info.cameras.end()) {
        fail("\"camera_sets\" has camera " + inQuotes(camera) + ", which is not in \"cameras\"");
      }
      if (camera == "main") fail(kMainInCameraSets);
      const std::string where = "camera_sets." + camera;
      if (!value.is_object()) {
        fail(inQuotes(where) + " is a " + jsonTypeName(value) + ", not an object");
      }
      CameraSets& sets = info.camera_sets[camera];
      readSetPair(value, where, sets.high, sets.low);
    }
  }

  // The extension "frame_sizes": {camera: [width, height]}, each camera one of
  // "cameras", both numbers whole and in [1, 2^31).
  void readFrameSizes(const json& doc, CaptureInfo& info) const {
    const auto it = doc.find("frame_sizes");
    if (it == doc.end()) return;
    if (!it->is_object()) fail("\"frame_sizes\" is a " + jsonTypeName(*it) + ", not an object");
    for (const auto& [camera, value] : it->items()) {
      if (std::find(info.cameras.begin(), info.cameras.end(), camera) == info.cameras.end()) {
        fail("\"frame_sizes\" has camera " + inQuotes(camera) + ", which is not in \"cameras\"");
      }
      const std::string where = "frame_sizes." + camera;
      const auto whole = [](const json& v) {
        return v.is_number_integer() && v.get<std::int64_t>() >= 1 &&
               v.get<std::int64_t>() <= std::numeric_limits<std::int32_t>::max();
      };
      if (!value.is_array() || value.size() != 2 || !whole(value[0]) || !whole(value[1])) {
        fail(inQuotes(where) + " must be [width, height], two whole numbers of pixels >= 1");
      }
      info.frame_sizes[camera] =
          cv::Size(value[0].get<std::int32_t>(), value[1].get<std::int32_t>());
    }
  }

  // Exactly "high" and "low" in `sets` (the object at `where`); with
  // SetsRequired::OneOrBoth one of them may be absent, and stays empty.
  void readSetPair(const json& sets, const std::string& where, FringeSetInfo& high,
                   FringeSetInfo& low) const {
    const bool one_or_both = required_ == SetsRequired::OneOrBoth;
    for (const auto& [name, value] : sets.items()) {
      if (!parseFringeSet(name)) {
        fail("unknown fringe set " + inQuotes(name) + " in " + inQuotes(where) +
             (one_or_both ? " (expected \"high\", \"low\" or both)"
                          : " (expected exactly \"high\" and \"low\")"));
      }
    }
    if (one_or_both && sets.empty()) {
      fail("neither set \"high\" nor set \"low\" in " + inQuotes(where) +
           " (a bundle needs at least one)");
    }
    for (const FringeSet id : kFringeSets) {
      const std::string name(toString(id));
      const auto set = sets.find(name);
      if (set == sets.end() && one_or_both) continue;
      if (set == sets.end()) fail("missing set " + inQuotes(name) + " in " + inQuotes(where));
      std::string set_where = where;
      set_where += '.';
      set_where += name;
      (id == FringeSet::High ? high : low) = readSet(*set, set_where);
    }
  }

  FringeSetInfo readSet(const json& set, const std::string& where) const {
    if (!set.is_object()) fail(inQuotes(where) + " is a " + jsonTypeName(set) + ", not an object");
    FringeSetInfo info;
    const auto period = set.find("period_deg");
    if (period == set.end()) fail("missing " + inQuotes(where + ".period_deg"));
    info.period_deg = finiteNumber(*period, where + ".period_deg");
    if (info.period_deg <= 0) {
      fail(inQuotes(where + ".period_deg") + " is " + std::to_string(info.period_deg) +
           "; it must be > 0");
    }
    const auto stage = set.find("stage_deg");
    if (stage == set.end()) fail("missing " + inQuotes(where + ".stage_deg"));
    if (!stage->is_array()) {
      fail(inQuotes(where + ".stage_deg") + " is a " + jsonTypeName(*stage) + ", not a list");
    }
    for (std::size_t k = 0; k < stage->size(); ++k) {
      info.stage_deg.push_back(
          finiteNumber((*stage)[k], where + ".stage_deg[" + std::to_string(k) + "]"));
    }
    if (info.stage_deg.size() < static_cast<std::size_t>(kMinFramesPerSet)) {
      fail(inQuotes(where + ".stage_deg") + " lists " + std::to_string(info.stage_deg.size()) +
           " frames; a set needs at least " + std::to_string(kMinFramesPerSet));
    }
    return info;
  }

  double finiteNumber(const json& value, const std::string& where) const {
    if (!value.is_number())
      fail(inQuotes(where) + " is a " + jsonTypeName(value) + ", not a number");
    const double v = value.get<double>();
    if (!std::isfinite(v)) fail(inQuotes(where) + " is not a finite number");
    return v;
  }

  fs::path file_;
  SetsRequired required_;
};

// Frame files of a set directory: names made of digits + ".png", with their index.
std::vector<std::pair<std::string, std::uintmax_t>> frameFilesIn(const fs::path& set_dir) {
  std::vector<std::pair<std::string, std::uintmax_t>> files;
  std::error_code ec;
  if (!fs::is_directory(set_dir, ec)) return files;
  fs::directory_iterator it(set_dir, ec);
  for (; !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() <= 4 || name.substr(name.size() - 4) != ".png") continue;
    const std::string digits = name.substr(0, name.size() - 4);
    if (digits.find_first_not_of("0123456789") != std::string::npos) continue;
    std::uintmax_t index = 0;
    for (const char c : digits) {
      index = std::min<std::uintmax_t>(index * 10 + static_cast<std::uintmax_t>(c - '0'), 1u << 30);
    }
    files.emplace_back(name, index);
  }
  if (ec) throw InputError(set_dir, "cannot list the directory: " + ec.message());
  return files;
}

PngLimits pngLimits(const FrameLimits& limits) {
  return PngLimits{limits.max_width, limits.max_height, limits.max_pixels};
}

// The header checks of a frame: single channel, 8/16 bit, within limits.
PngHeader checkFrameHeader(const fs::path& file, const FrameLimits& limits) {
  const PngHeader header = readPngHeader(file, pngLimits(limits));
  if (header.colour_type != 0) {
    throw InputError(
        file, "frame has " + std::to_string(header.channels()) + " channel(s) (PNG colour type " +
                  std::to_string(header.colour_type) + "); frames must be single-channel grey");
  }
  if (header.bit_depth != 8 && header.bit_depth != 16) {
    throw InputError(file, "frame has " + std::to_string(header.bit_depth) +
                               "-bit samples; frames must be 8-bit or 16-bit");
  }
  return header;
}

}  // namespace

const FringeSetInfo& CaptureInfo::setOf(std::string_view camera, FringeSet id) const {
  const auto it = camera_sets.find(camera);
  return it == camera_sets.end() ? set(id) : it->second.set(id);
}

std::string frameFileName(int k, int n) {
  if (n < 1 || k < 0 || k >= n) {
    throw std::invalid_argument("frameFileName: frame " + std::to_string(k) +
                                " is outside a set of " + std::to_string(n));
  }
  const std::size_t width = n >= 100 ? std::to_string(n).size() : 2;
  const std::string digits = std::to_string(k);
  return std::string(width - std::min(width, digits.size()), '0') + digits;
}

// ----------------------------------------------------------------------------- reader

CaptureBundleReader::CaptureBundleReader(fs::path dir, FrameLimits limits, SetsRequired sets)
    : dir_(std::move(dir)), limits_(limits) {
  const fs::path json_file = dir_ / kCaptureJson;
  std::error_code ec;
  if (!fs::exists(json_file, ec) && fs::is_directory(dir_, ec)) {
    throw InputError(json_file, "missing: " + dir_.string() + " is not a capture bundle");
  }
  const json doc = readJsonFile(json_file, kMaxCaptureJsonBytes);
  info_ = CaptureJsonParser(json_file, sets).parse(doc);

  for (const std::string& camera : info_.cameras) {
    std::optional<cv::Size> first;
    fs::path first_path;
    for (const FringeSet id : kFringeSets) {
      const std::size_t n = info_.setOf(camera, id).stage_deg.size();
      const std::string where = setWhere(camera, id, info_.hasOwnSets(camera));
      const fs::path set_dir = dir_ / camera / std::string(toString(id));
      for (const auto& [name, index] : frameFilesIn(set_dir)) {
        if (index >= n) {
          throw InputError(
              json_file, "fewer angles than frames: " + inQuotes(where + ".stage_deg") + " lists " +
                             std::to_string(n) + " angles but frame " +
                             (fs::path(camera) / toString(id) / name).string() + " exists");
        }
      }
      for (int k = 0; k < static_cast<int>(n); ++k) {
        const fs::path frame = framePath(camera, id, k);
        if (!fs::exists(frame, ec)) {
          throw InputError(
              frame, "frame is missing (capture.json lists " + std::to_string(n) +
                         " frames in set " + inQuotes(toString(id)) +
                         (info_.hasOwnSets(camera) ? " of " + inQuotes("camera_sets." + camera)
                                                   : std::string()) +
                         ")");
        }
        const PngHeader header = checkFrameHeader(frame, limits_);
        const cv::Size size(header.width, header.height);
        if (const auto declared = info_.frame_sizes.find(camera);
            declared != info_.frame_sizes.end() && size != declared->second) {
          throw InputError(frame, "frame size " + sizeText(size) + " differs from the " +
                                      sizeText(declared->second) + " that capture.json declares (" +
                                      inQuotes("frame_sizes." + camera) + ")");
        }
        if (!first) {
          first = size;
          first_path = frame;
        } else if (size != *first) {
          throw InputError(frame, "frame size " + sizeText(size) + " differs from the " +
                                      sizeText(*first) + " of the camera's first frame " +
                                      first_path.string());
        }
      }
    }
    frame_sizes_.emplace(camera, *first);
  }
}

bool CaptureBundleReader::hasCamera(std::string_view camera) const {
  return frame_sizes_.find(camera) != frame_sizes_.end();
}

int CaptureBundleReader::frameCount(FringeSet set) const {
  return static_cast<int>(info_.set(set).stage_deg.size());
}

void CaptureBundleReader::requireCamera(std::string_view camera) const {
  if (std::find(info_.cameras.begin(), info_.cameras.end(), camera) == info_.cameras.end()) {
    std::string list;
    for (const std::string& name : info_.cameras)
      list += (list.empty() ? "" : ", ") + name;
    throw InputError(dir_ / kCaptureJson,
                     "the bundle has no camera " + inQuotes(camera) + " (cameras: " + list + ")");
  }
}

int CaptureBundleReader::frameCount(std::string_view camera, FringeSet set) const {
  requireCamera(camera);
  return static_cast<int>(info_.setOf(camera, set).stage_deg.size());
}

fs::path CaptureBundleReader::framePath(std::string_view camera, FringeSet set, int k) const {
  const int n = frameCount(camera, set);
  if (k < 0 || k >= n) {
    throw std::out_of_range("frame " + std::to_string(k) + " of set " + inQuotes(toString(set)) +
                            " is outside 0.." + std::to_string(n - 1) + " in " + dir_.string());
  }
  return dir_ / camera / std::string(toString(set)) / (frameFileName(k, n) + ".png");
}

cv::Size CaptureBundleReader::frameSize(std::string_view camera) const {
  const auto it = frame_sizes_.find(camera);
  if (it == frame_sizes_.end()) {
    (void)framePath(camera, FringeSet::High, 0);  // throws the InputError for the camera
    throw std::logic_error("no frame size for camera " + inQuotes(camera));
  }
  return it->second;
}

cv::Mat CaptureBundleReader::readFrame(std::string_view camera, FringeSet set, int k) const {
  const fs::path file = framePath(camera, set, k);
  const cv::Size expected = frameSize(camera);
  const PngHeader header = checkFrameHeader(file, limits_);
  if (cv::Size(header.width, header.height) != expected) {
    throw InputError(file, "frame size " + sizeText(cv::Size(header.width, header.height)) +
                               " differs from the " + sizeText(expected) +
                               " of the camera's first frame");
  }
  PngHeader decoded_header;
  cv::Mat frame = readPng(file, pngLimits(limits_), &decoded_header);
  if (decoded_header.colour_type != 0 || frame.channels() != 1 ||
      cv::Size(decoded_header.width, decoded_header.height) != expected) {
    throw InputError(file, "changed while being read");
  }
  return frame;
}

// ----------------------------------------------------------------------------- writer

CaptureBundleWriter::CaptureBundleWriter(fs::path dir, CaptureInfo info)
    : dir_(std::move(dir)), info_(std::move(info)) {
  const fs::path json_file = dir_ / kCaptureJson;
  if (auto fault = captureInfoFault(info_, SetsRequired::Both)) {
    throw std::invalid_argument("capture bundle " + dir_.string() + ": " + *fault);
  }
  if (!info_.extra.is_object()) {
    throw std::invalid_argument("capture bundle " + dir_.string() +
                                ": CaptureInfo::extra must be a JSON object");
  }
  if (const auto sets = info_.extra.find("sets"); sets != info_.extra.end()) {
    bool ok = sets->is_object();
    if (ok) {
      for (const auto& [name, value] : sets->items()) {
        ok = ok && value.is_object() &&
             (name == toString(FringeSet::High) || name == toString(FringeSet::Low));
      }
    }
    if (!ok) {
      throw std::invalid_argument("capture bundle " + dir_.string() +
                                  ": CaptureInfo::extra[\"sets\"] may only hold objects "
                                  "\"high\" and \"low\"");
    }
  }
  if (const auto own = info_.extra.find("camera_sets"); own != info_.extra.end()) {
    bool ok = own->is_object();
    if (ok) {
      for (const auto& [camera, sets] : own->items()) {
        ok = ok && info_.hasOwnSets(camera) && sets.is_object();
        if (!ok) break;
        for (const auto& [name, value] : sets.items()) {
          ok = ok && value.is_object() &&
               (name == toString(FringeSet::High) || name == toString(FringeSet::Low));
        }
      }
    }
    if (!ok) {
      throw std::invalid_argument("capture bundle " + dir_.string() +
                                  ": CaptureInfo::extra[\"camera_sets\"] may only hold objects "
                                  "\"high\" and \"low\" of cameras in CaptureInfo::camera_sets");
    }
  }
  fs::create_directories(dir_);
  fs::remove(json_file);  // the bundle is being rewritten: not whole until commit()
  for (const std::string& camera : info_.cameras) {
    CameraProgress& progress = progress_[camera];
    for (const FringeSet id : kFringeSets) {
      progress.written[static_cast<std::size_t>(id)].assign(
          info_.setOf(camera, id).stage_deg.size(), false);
    }
  }
}

void CaptureBundleWriter::writeFrame(std::string_view camera, FringeSet set, int k,
                                     const cv::Mat& frame) {
  const auto it = progress_.find(camera);
  const std::string where = "capture bundle " + dir_.string() + ", camera " + inQuotes(camera);
  if (it == progress_.end()) throw std::invalid_argument(where + ": not in CaptureInfo::cameras");
  const int n = static_cast<int>(info_.setOf(camera, set).stage_deg.size());
  if (k < 0 || k >= n) {
    throw std::invalid_argument(where + ": frame " + std::to_string(k) + " is outside set " +
                                inQuotes(toString(set)) + " of " + std::to_string(n) + " frames");
  }
  if (frame.empty() || (frame.type() != CV_8UC1 && frame.type() != CV_16UC1)) {
    throw std::invalid_argument(where + ": frames must be non-empty CV_8UC1 or CV_16UC1 images");
  }
  CameraProgress& progress = it->second;
  const bool any_written = progress.size != cv::Size();
  if (any_written && frame.size() != progress.size) {
    throw std::invalid_argument(where + ": frame size " + sizeText(frame.size()) +
                                " differs from the camera's " + sizeText(progress.size));
  }
  const fs::path set_dir = dir_ / std::string(camera) / std::string(toString(set));
  fs::create_directories(set_dir);
  const std::vector<unsigned char> png = encodePng(frame);
  writeFileAtomically(set_dir / (frameFileName(k, n) + ".png"), std::as_bytes(std::span(png)));
  progress.size = frame.size();
  progress.written[static_cast<std::size_t>(set)][static_cast<std::size_t>(k)] = true;
}

void CaptureBundleWriter::commit() {
  for (const std::string& camera : info_.cameras) {
    const CameraProgress& progress = progress_.at(camera);
    for (const FringeSet id : kFringeSets) {
      const auto& written = progress.written[static_cast<std::size_t>(id)];
      const int n = static_cast<int>(written.size());
      for (int k = 0; k < n; ++k) {
        if (!written[static_cast<std::size_t>(k)]) {
          throw std::logic_error(
              "capture bundle " + dir_.string() + ": commit() before frame " +
              (fs::path(camera) / toString(id) / (frameFileName(k, n) + ".png")).string() +
              " was written");
        }
      }
      const fs::path set_dir = dir_ / camera / std::string(toString(id));
      for (const auto& [name, index] : frameFilesIn(set_dir)) {
        if (index >= static_cast<std::uintmax_t>(n) ||
            name != frameFileName(static_cast<int>(index), n) + ".png") {
          fs::remove(set_dir / name);  // left over from an earlier bundle in this directory
        }
      }
    }
  }
  json doc = info_.extra;
  doc["format"] = kCaptureFormat;
  doc["cameras"] = info_.cameras;
  json& sets = doc["sets"];
  if (!sets.is_object()) sets = json::object();
  for (const FringeSet id : kFringeSets) {
    json& set = sets[std::string(toString(id))];
    if (!set.is_object()) set = json::object();
    set["period_deg"] = info_.set(id).period_deg;
    set["stage_deg"] = info_.set(id).stage_deg;
  }
  json& sizes = doc["frame_sizes"];
  sizes = json::object();
  for (const std::string& camera : info_.cameras) {
    const cv::Size size = progress_.at(camera).size;
    sizes[camera] = {size.width, size.height};
  }
  if (!info_.camera_sets.empty()) {
    json& own = doc["camera_sets"];
    if (!own.is_object()) own = json::object();
    for (const auto& [camera, camera_sets] : info_.camera_sets) {
      json& sets_of = own[camera];
      if (!sets_of.is_object()) sets_of = json::object();
      for (const FringeSet id : kFringeSets) {
        json& set = sets_of[std::string(toString(id))];
        if (!set.is_object()) set = json::object();
        set["period_deg"] = camera_sets.set(id).period_deg;
        set["stage_deg"] = camera_sets.set(id).stage_deg;
      }
    }
  }
  writeFileAtomically(dir_ / kCaptureJson, doc.dump(2) + "\n");
}

}  // namespace cylscan::formats
