// SPDX-License-Identifier: Apache-2.0
// The extrinsics of a multi-camera head, `head.json` (format `cylscan-head-1`,
// docs/formats.md, head extrinsics): each camera's pose in the head frame,
// which is the frame of the camera named by "frame" (`main`),
// X_head = R·X_cam + T in mm.
//
//   {"format": "cylscan-head-1", "frame": "main", "method": "turntable",
//    "cameras": {"main": {"R": [[1,0,0],[0,1,0],[0,0,1]], "T": [0,0,0]},
//                "cam90": {"R": [[..],[..],[..]], "T": [..]}},
//    "rms_mm": 0.01, "turntable_axis": {"point": [..], "direction": [..]}}
//
// Other top-level fields (e.g. "residuals") are kept in `extra`.
#pragma once

#include <array>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace cylscan::formats {

inline constexpr std::string_view kHeadFormat = "cylscan-head-1";
inline constexpr std::uintmax_t kMaxHeadFileBytes = 1 << 20;

struct CameraPose {
  std::array<std::array<double, 3>, 3> R{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};  // rows
  std::array<double, 3> T{0, 0, 0};

  std::array<double, 3> apply(const std::array<double, 3>& x) const;
};

struct AxisRecord {
  std::array<double, 3> point{0, 0, 0};
  std::array<double, 3> direction{0, 1, 0};
};

struct HeadExtrinsics {
  std::string frame = "main";
  std::string method = "turntable";
  std::map<std::string, CameraPose, std::less<>> cameras;
  std::optional<double> rms_mm;
  std::optional<AxisRecord> turntable_axis;
  nlohmann::json extra = nlohmann::json::object();

  bool hasCamera(std::string_view camera) const { return cameras.contains(camera); }
  // InputError-free lookup for callers that checked: std::out_of_range otherwise.
  const CameraPose& pose(std::string_view camera) const;
};

// Parses and validates (InputError naming `source` and the field at fault):
// the format, "frame" a camera of "cameras" whose pose is the identity, every
// camera's name valid, R a 3×3 rotation (orthonormal to 1e-6, det +1), T three
// finite numbers within 100 m, rms_mm finite ≥ 0, the axis' direction a unit
// vector.
HeadExtrinsics parseHeadExtrinsics(std::string_view text, const std::filesystem::path& source);
HeadExtrinsics readHeadExtrinsics(const std::filesystem::path& file);

// The JSON text (validated first: std::invalid_argument if `head` would not read back).
std::string headExtrinsicsJson(const HeadExtrinsics& head);
void writeHeadExtrinsics(const std::filesystem::path& file, const HeadExtrinsics& head);  // atomic

}  // namespace cylscan::formats
