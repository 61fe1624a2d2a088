// SPDX-License-Identifier: Apache-2.0
#include "formats/head_extrinsics.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "common/vocabulary.hpp"
#include "formats/atomic_file.hpp"
#include "formats/file_reading.hpp"
#include "formats/input_error.hpp"
#include "formats/rotation.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr double kMaxTranslationMm = 1e5;

class Checker {
 public:
  explicit Checker(fs::path source) : source_(std::move(source)) {}

  [[noreturn]] void fail(const std::string& field, const std::string& fault) const {
    throw InputError(source_, "\"" + field + "\": " + fault);
  }

  double number(const json& value, const std::string& field) const {
    if (!value.is_number()) fail(field, "must be a number");
    const double v = value.get<double>();
    if (!std::isfinite(v)) fail(field, "must be finite");
    return v;
  }

  std::array<double, 3> vector3(const json& value, const std::string& field) const {
    if (!value.is_array() || value.size() != 3) fail(field, "must be an array of 3 numbers");
    std::array<double, 3> out{};
    for (std::size_t i = 0; i < 3; ++i)
      out[i] = number(value[i], field + "[" + std::to_string(i) + "]");
    return out;
  }

  CameraPose pose(const json& value, const std::string& field) const {
    if (!value.is_object()) fail(field, "must be an object with \"R\" and \"T\"");
    for (const char* key : {"R", "T"}) {
      if (!value.contains(key)) fail(field, std::string("has no \"") + key + "\"");
    }
    CameraPose pose;
    const json& r = value["R"];
    if (!r.is_array() || r.size() != 3) fail(field + ".R", "must be 3 rows of 3 numbers");
    for (std::size_t i = 0; i < 3; ++i)
      pose.R[i] = vector3(r[i], field + ".R[" + std::to_string(i) + "]");
    pose.T = vector3(value["T"], field + ".T");
    checkRotation(pose, field + ".R");
    for (double t : pose.T) {
      if (std::abs(t) > kMaxTranslationMm) fail(field + ".T", "is beyond 100 m");
    }
    return pose;
  }

 private:
  void checkRotation(const CameraPose& pose, const std::string& field) const {
    const auto& m = pose.R;
    const cv::Matx33d r(m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0], m[2][1],
                        m[2][2]);
    if (auto fault = rotationFault(r)) fail(field, *fault);
  }

  fs::path source_;
};

bool isIdentity(const CameraPose& pose) {
  for (std::size_t i = 0; i < 3; ++i) {
    if (std::abs(pose.T[i]) > 1e-9) return false;
    for (std::size_t j = 0; j < 3; ++j) {
      if (std::abs(pose.R[i][j] - (i == j ? 1.0 : 0.0)) > 1e-9) return false;
    }
  }
  return true;
}

HeadExtrinsics parseJson(const json& root, const fs::path& source) {
  const Checker check(source);
  if (!root.is_object()) check.fail("(top level)", "must be a JSON object");
  if (!root.contains("format") || root["format"] != kHeadFormat) {
    check.fail("format", "must be \"" + std::string(kHeadFormat) + "\"");
  }
  HeadExtrinsics head;
  for (const auto& [key, value] : root.items()) {
    if (key == "format") continue;
    if (key == "frame") {
      if (!value.is_string()) check.fail("frame", "must be a camera name");
      head.frame = value.get<std::string>();
    } else if (key == "method") {
      if (!value.is_string()) check.fail("method", "must be a string");
      head.method = value.get<std::string>();
    } else if (key == "cameras") {
      if (!value.is_object() || value.empty())
        check.fail("cameras", "must be a non-empty object of camera poses");
      for (const auto& [name, pose] : value.items()) {
        if (!isCameraName(name))
          check.fail("cameras." + name,
                     "is not a camera name (" + std::string(kCameraNameRule) + ")");
        head.cameras[name] = check.pose(pose, "cameras." + name);
      }
    } else if (key == "rms_mm") {
      const double rms = check.number(value, "rms_mm");
      if (rms < 0) check.fail("rms_mm", "must be ≥ 0");
      head.rms_mm = rms;
    } else if (key == "turntable_axis") {
      if (!value.is_object() || !value.contains("point") || !value.contains("direction"))
        check.fail("turntable_axis", "must be an object with \"point\" and \"direction\"");
      AxisRecord axis;
      axis.point = check.vector3(value["point"], "turntable_axis.point");
      axis.direction = check.vector3(value["direction"], "turntable_axis.direction");
      const double norm = std::hypot(axis.direction[0], axis.direction[1], axis.direction[2]);
      if (std::abs(norm - 1.0) > 1e-6)
        check.fail("turntable_axis.direction", "must be a unit vector");
      head.turntable_axis = axis;
    } else {
      head.extra[key] = value;
    }
  }
  if (head.cameras.empty()) check.fail("cameras", "is missing");
  if (!head.hasCamera(head.frame))
    check.fail("frame", "names '" + head.frame + "', which is not in \"cameras\"");
  if (!isIdentity(head.cameras.at(head.frame)))
    check.fail("cameras." + head.frame,
               "is the head frame's camera: its pose must be the identity");
  return head;
}

json arrayOf(const std::array<double, 3>& v) {
  return json::array({v[0], v[1], v[2]});
}

}  // namespace

std::array<double, 3> CameraPose::apply(const std::array<double, 3>& x) const {
  std::array<double, 3> out{};
  for (std::size_t i = 0; i < 3; ++i)
    out[i] = R[i][0] * x[0] + R[i][1] * x[1] + R[i][2] * x[2] + T[i];
  return out;
}

const CameraPose& HeadExtrinsics::pose(std::string_view camera) const {
  const auto it = cameras.find(camera);
  if (it == cameras.end())
    throw std::out_of_range("head.json has no camera '" + std::string(camera) + "'");
  return it->second;
}

HeadExtrinsics parseHeadExtrinsics(std::string_view text, const fs::path& source) {
  if (text.size() > kMaxHeadFileBytes) throw InputError(source, "larger than 1 MiB");
  json root;
  try {
    root = json::parse(text);
  } catch (const json::parse_error& e) {
    throw InputError(source, std::string("not valid JSON: ") + e.what());
  }
  return parseJson(root, source);
}

HeadExtrinsics readHeadExtrinsics(const fs::path& file) {
  return parseJson(readJsonFile(file, kMaxHeadFileBytes), file);
}

std::string headExtrinsicsJson(const HeadExtrinsics& head) {
  json root = head.extra.is_object() ? head.extra : json::object();
  root["format"] = kHeadFormat;
  root["frame"] = head.frame;
  root["method"] = head.method;
  json cameras = json::object();
  for (const auto& [name, pose] : head.cameras) {
    json r = json::array();
    for (const auto& row : pose.R)
      r.push_back(arrayOf(row));
    cameras[name] = {{"R", r}, {"T", arrayOf(pose.T)}};
  }
  root["cameras"] = cameras;
  if (head.rms_mm) root["rms_mm"] = *head.rms_mm;
  if (head.turntable_axis) {
    root["turntable_axis"] = {{"point", arrayOf(head.turntable_axis->point)},
                              {"direction", arrayOf(head.turntable_axis->direction)}};
  }
  std::string text = root.dump(2) + "\n";
  try {
    parseHeadExtrinsics(text, "head.json");
  } catch (const InputError& e) {
    throw std::invalid_argument(std::string("head extrinsics to write: ") + e.what());
  }
  return text;
}

void writeHeadExtrinsics(const fs::path& file, const HeadExtrinsics& head) {
  writeFileAtomically(file, headExtrinsicsJson(head));
}

}  // namespace cylscan::formats
