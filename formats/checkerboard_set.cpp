// SPDX-License-Identifier: Apache-2.0
#include "formats/checkerboard_set.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <stdexcept>
#include <system_error>

#include <nlohmann/json.hpp>

#include "formats/atomic_file.hpp"
#include "formats/file_reading.hpp"
#include "formats/input_error.hpp"
#include "formats/png.hpp"
#include "formats/size_text.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr std::string_view kInfoFile = "checkerboard.json";
constexpr std::uintmax_t kMaxInfoBytes = 1u << 20;
constexpr int kMinCorners = 2;
constexpr int kMaxCorners = 1000;

std::optional<std::string> infoFault(const CheckerboardInfo& info) {
  const auto corners_fault = [](const char* name, int v) -> std::optional<std::string> {
    if (v < kMinCorners || v > kMaxCorners) {
      return "\"" + std::string(name) + "\" is " + std::to_string(v) + "; inner corners must be " +
             std::to_string(kMinCorners) + ".." + std::to_string(kMaxCorners);
    }
    return std::nullopt;
  };
  if (auto fault = corners_fault("cols", info.cols)) return fault;
  if (auto fault = corners_fault("rows", info.rows)) return fault;
  if (!std::isfinite(info.square_mm) || info.square_mm <= 0) {
    return "\"square_mm\" must be a finite number > 0";
  }
  return std::nullopt;
}

CheckerboardInfo parseInfo(const fs::path& file) {
  const json doc = readJsonFile(file, kMaxInfoBytes);
  if (!doc.is_object()) throw InputError(file, "the top level is not a JSON object");
  const auto field = [&](const char* name) -> const json& {
    const auto it = doc.find(name);
    if (it == doc.end()) throw InputError(file, "missing \"" + std::string(name) + "\"");
    return *it;
  };
  const auto corners = [&](const char* name) {
    const json& v = field(name);
    if (!v.is_number_integer()) {
      throw InputError(file, "\"" + std::string(name) + "\" is a " + v.type_name() +
                                 ", not an integer (inner corners)");
    }
    const auto n = v.get<std::int64_t>();
    if (n < kMinCorners || n > kMaxCorners) {
      throw InputError(file, "\"" + std::string(name) + "\" is " + std::to_string(n) +
                                 "; inner corners must be " + std::to_string(kMinCorners) + ".." +
                                 std::to_string(kMaxCorners));
    }
    return static_cast<int>(n);
  };
  CheckerboardInfo info;
  info.cols = corners("cols");
  info.rows = corners("rows");
  const json& square = field("square_mm");
  if (!square.is_number()) {
    throw InputError(file,
                     std::string("\"square_mm\" is a ") + square.type_name() + ", not a number");
  }
  info.square_mm = square.get<double>();
  if (auto fault = infoFault(info)) throw InputError(file, *fault);
  return info;
}

// NN of the files NN.png in a camera directory, mapped to their paths.
std::map<std::string, fs::path> imagesIn(const fs::path& camera_dir) {
  std::error_code ec;
  if (!fs::is_directory(camera_dir, ec)) {
    throw InputError(camera_dir, "missing directory (a checkerboard set has main/ and aux/)");
  }
  std::map<std::string, fs::path> images;
  fs::directory_iterator it(camera_dir, ec);
  for (; !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() <= 4 || name.substr(name.size() - 4) != ".png") continue;
    const std::string id = name.substr(0, name.size() - 4);
    if (id.find_first_not_of("0123456789") != std::string::npos) continue;
    images.emplace(id, it->path());
  }
  if (ec) throw InputError(camera_dir, "cannot list the directory: " + ec.message());
  return images;
}

// By the number NN: strip leading zeros, then shorter is smaller, then by digits, then by name.
bool idLess(const std::string& a, const std::string& b) {
  const auto significant = [](const std::string& s) {
    const auto first = s.find_first_not_of('0');
    return first == std::string::npos ? std::string() : s.substr(first);
  };
  const std::string sa = significant(a);
  const std::string sb = significant(b);
  if (sa.size() != sb.size()) return sa.size() < sb.size();
  if (sa != sb) return sa < sb;
  return a < b;
}

// All images of one camera must share a size (checked on the PNG headers).
class SizeCheck {
 public:
  void check(const fs::path& file) {
    const PngHeader header = readPngHeader(file);
    const cv::Size size(header.width, header.height);
    if (first_file_.empty()) {
      size_ = size;
      first_file_ = file;
    } else if (size != size_) {
      throw InputError(file, "image size " + sizeText(size) + " differs from the " +
                                 sizeText(size_) + " of " + first_file_.string());
    }
  }

 private:
  cv::Size size_;
  fs::path first_file_;
};

}  // namespace

CheckerboardSet readCheckerboardSet(const fs::path& dir) {
  CheckerboardSet set;
  set.board = parseInfo(dir / kInfoFile);
  const std::map<std::string, fs::path> main = imagesIn(dir / "main");
  const std::map<std::string, fs::path> aux = imagesIn(dir / "aux");
  for (const auto& [id, main_path] : main) {
    const auto it = aux.find(id);
    if (it != aux.end()) set.pairs.push_back(CheckerboardPair{id, main_path, it->second});
  }
  if (set.pairs.empty()) {
    throw InputError(dir, "no image pairs: no NN.png is present in both main/ (" +
                              std::to_string(main.size()) + " images) and aux/ (" +
                              std::to_string(aux.size()) + " images)");
  }
  std::sort(
      set.pairs.begin(), set.pairs.end(),
      [](const CheckerboardPair& a, const CheckerboardPair& b) { return idLess(a.id, b.id); });
  SizeCheck main_sizes;
  SizeCheck aux_sizes;
  for (const CheckerboardPair& pair : set.pairs) {
    main_sizes.check(pair.main);
    aux_sizes.check(pair.aux);
  }
  return set;
}

void writeCheckerboardInfo(const fs::path& dir, const CheckerboardInfo& info) {
  if (auto fault = infoFault(info)) {
    throw std::invalid_argument("checkerboard set " + dir.string() + ": " + *fault);
  }
  const json doc = {{"cols", info.cols}, {"rows", info.rows}, {"square_mm", info.square_mm}};
  fs::create_directories(dir);
  writeFileAtomically(dir / kInfoFile, doc.dump(2) + "\n");
}

}  // namespace cylscan::formats
