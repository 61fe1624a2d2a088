// SPDX-License-Identifier: Apache-2.0
// Point clouds (docs/formats.md, point clouds): binary little-endian PLY,
// float x y z in mm in the main camera frame, then optional extra properties.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace cylscan::formats {

// How an extra property is stored in the file (its values are float in memory).
enum class PlyScalar { Float32, UInt8 };

struct PointCloud {
  std::vector<float> xyz;  // 3 per point
  // Extra float properties, one value per point each, written after x y z.
  std::vector<std::string> property_names;
  std::vector<std::vector<float>> properties;
  // Empty (all float) or one per property. A UInt8 property's values must be
  // integers 0..255. readPly sets UInt8 for uchar/uint8 properties.
  std::vector<PlyScalar> property_types;
  // Header comment lines, without the "comment " keyword (single lines of
  // printable text), e.g. "camera 0 main" (the merged 360° cloud).
  std::vector<std::string> comments;

  std::size_t size() const { return xyz.size() / 3; }
};

// The merged cloud of several cameras (a 360° head): a `uchar camera` property
// holding each point's index into the camera list, named by the header lines
// `comment camera <index> <name>`.
inline constexpr std::string_view kCameraProperty = "camera";
// The names of the `comment camera <i> <name>` lines, by index (empty if none;
// InputError-free: malformed camera comments are ignored here, refused by readPly).
std::vector<std::string> cameraNamesOf(const PointCloud& cloud);
// Appends `cloud_of_camera`'s points to `merged` with camera index `index`
// (adds the camera property, as uchar, and its comment line). Both clouds must
// have the same property names apart from `camera` (std::invalid_argument).
void appendCameraCloud(PointCloud& merged, const PointCloud& cloud_of_camera, std::size_t index,
                       const std::string& camera);

// Header: ply / format binary_little_endian 1.0 / the comment lines / element vertex N / property
// float x, y, z / one `property float|uchar <name>` per extra property / end_header.
// std::invalid_argument if the cloud is inconsistent (xyz not a multiple of 3,
// a property of another length, a name that is empty, has spaces, is x/y/z or
// repeats).
void writePly(const std::filesystem::path& file, const PointCloud& cloud);  // atomic
// Reads binary little-endian and ASCII PLY with float/double x y z; other
// vertex properties of scalar types are kept as float. InputError on faults.
// Also reads binary_big_endian. Properties may be of any PLY scalar type (char
// uchar short ushort int uint float double, int8 … float64); all become float.
// The vertex element must come first; elements after it (faces…) are checked
// for length and skipped. The data must be exactly as long as the header says:
// a shorter file is reported truncated before anything is allocated.
PointCloud readPly(const std::filesystem::path& file);

}  // namespace cylscan::formats
