// Point clouds (spec §4): binary little-endian PLY, float x y z in mm in the
// main camera frame, then optional extra properties.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace cylscan::formats {

struct PointCloud {
  std::vector<float> xyz;  // 3 per point
  // Extra float properties, one value per point each, written after x y z.
  std::vector<std::string> property_names;
  std::vector<std::vector<float>> properties;

  std::size_t size() const { return xyz.size() / 3; }
};

// Header: ply / format binary_little_endian 1.0 / element vertex N / property
// float x, y, z / one `property float <name>` per extra property / end_header.
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
