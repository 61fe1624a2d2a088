// SPDX-License-Identifier: Apache-2.0
#include "formats/point_cloud.hpp"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string_view>

#include "formats/atomic_file.hpp"
#include "formats/file_reading.hpp"
#include "formats/input_error.hpp"

namespace cylscan::formats {
namespace {

namespace fs = std::filesystem;

constexpr std::uintmax_t kMaxPlyBytes = std::uintmax_t{16} << 30;
constexpr std::size_t kMaxHeaderBytes = 1 << 16;

// ----------------------------------------------------------------------------- writing

std::optional<std::string> cloudFault(const PointCloud& cloud) {
  if (cloud.xyz.size() % 3 != 0)
    return "xyz holds " + std::to_string(cloud.xyz.size()) + " values, not a multiple of 3";
  if (cloud.property_names.size() != cloud.properties.size()) {
    return std::to_string(cloud.property_names.size()) + " property names for " +
           std::to_string(cloud.properties.size()) + " properties";
  }
  std::set<std::string> seen{"x", "y", "z"};
  for (std::size_t i = 0; i < cloud.property_names.size(); ++i) {
    const std::string& name = cloud.property_names[i];
    const bool printable = !name.empty() && std::all_of(name.begin(), name.end(),
                                                        [](char c) { return c > ' ' && c < 0x7F; });
    if (!printable)
      return "property name \"" + name + "\" is empty or has spaces/control characters";
    if (!seen.insert(name).second) return "property name \"" + name + "\" is used twice";
    if (cloud.properties[i].size() != cloud.size()) {
      return "property \"" + name + "\" has " + std::to_string(cloud.properties[i].size()) +
             " values for " + std::to_string(cloud.size()) + " points";
    }
    if (!cloud.property_types.empty() && cloud.property_types[i] == PlyScalar::UInt8) {
      for (float v : cloud.properties[i]) {
        if (!(v >= 0 && v <= 255 && v == std::floor(v)))
          return "uchar property \"" + name + "\" holds " + std::to_string(v);
      }
    }
  }
  if (!cloud.property_types.empty() && cloud.property_types.size() != cloud.properties.size()) {
    return std::to_string(cloud.property_types.size()) + " property types for " +
           std::to_string(cloud.properties.size()) + " properties";
  }
  for (const std::string& comment : cloud.comments) {
    if (!std::all_of(comment.begin(), comment.end(), [](char c) { return c >= ' ' && c < 0x7F; }))
      return "comment \"" + comment + "\" has control characters";
  }
  return std::nullopt;
}

void appendFloatLe(std::string& out, float v) {
  const auto bits = std::bit_cast<std::uint32_t>(v);
  for (int shift = 0; shift < 32; shift += 8)
    out.push_back(static_cast<char>((bits >> shift) & 0xFFu));
}

// ----------------------------------------------------------------------------- reading

enum class Encoding { Ascii, BinaryLittleEndian, BinaryBigEndian };

enum class ScalarType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

std::optional<ScalarType> scalarType(std::string_view name) {
  static const std::pair<std::string_view, ScalarType> kNames[] = {
      {"char", ScalarType::Int8},      {"int8", ScalarType::Int8},
      {"uchar", ScalarType::UInt8},    {"uint8", ScalarType::UInt8},
      {"short", ScalarType::Int16},    {"int16", ScalarType::Int16},
      {"ushort", ScalarType::UInt16},  {"uint16", ScalarType::UInt16},
      {"int", ScalarType::Int32},      {"int32", ScalarType::Int32},
      {"uint", ScalarType::UInt32},    {"uint32", ScalarType::UInt32},
      {"float", ScalarType::Float32},  {"float32", ScalarType::Float32},
      {"double", ScalarType::Float64}, {"float64", ScalarType::Float64}};
  for (const auto& [text, type] : kNames) {
    if (text == name) return type;
  }
  return std::nullopt;
}

std::size_t sizeOf(ScalarType type) {
  switch (type) {
    case ScalarType::Int8:
    case ScalarType::UInt8:
      return 1;
    case ScalarType::Int16:
    case ScalarType::UInt16:
      return 2;
    case ScalarType::Int32:
    case ScalarType::UInt32:
    case ScalarType::Float32:
      return 4;
    case ScalarType::Float64:
      return 8;
  }
  return 0;
}

bool isInteger(ScalarType type) {
  return type != ScalarType::Float32 && type != ScalarType::Float64;
}

struct Property {
  std::string name;
  ScalarType type = ScalarType::Float32;
  bool is_list = false;
  ScalarType count_type = ScalarType::UInt8;  // of a list
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
};

struct Header {
  Encoding encoding = Encoding::BinaryLittleEndian;
  std::vector<std::string> comments;
  std::vector<Element> elements;
  std::size_t data_offset = 0;
};

std::vector<std::string_view> splitWords(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t at = 0;
  while (at < line.size()) {
    const std::size_t begin = line.find_first_not_of(" \t\r", at);
    if (begin == std::string_view::npos) break;
    const std::size_t end = std::min(line.find_first_of(" \t\r", begin), line.size());
    words.push_back(line.substr(begin, end - begin));
    at = end;
  }
  return words;
}

class PlyParser {
 public:
  PlyParser(fs::path file, std::string_view data) : file_(std::move(file)), data_(data) {}

  PointCloud parse() {
    const Header header = parseHeader();
    const Element& vertex = header.elements.front();
    checkVertexElement(vertex);
    if (header.encoding == Encoding::Ascii) {
      AsciiCursor cursor{data_, header.data_offset};
      PointCloud cloud = readAsciiVertices(vertex, cursor);
      for (std::size_t e = 1; e < header.elements.size(); ++e)
        skipAscii(header.elements[e], cursor);
      if (cursor.next()) fail("data beyond the elements declared in the header");
      describe(cloud, header);
      return cloud;
    }
    std::size_t at = header.data_offset;
    PointCloud cloud = readBinaryVertices(vertex, header.encoding, at);
    for (std::size_t e = 1; e < header.elements.size(); ++e) {
      skipBinary(header.elements[e], header.encoding, at);
    }
    if (at != data_.size()) {
      fail(std::to_string(data_.size() - at) +
           " bytes of data beyond the elements declared in the header");
    }
    describe(cloud, header);
    return cloud;
  }

  // The comments, and which extra properties are uchar.
  static void describe(PointCloud& cloud, const Header& header) {
    cloud.comments = header.comments;
    for (const Property& p : header.elements.front().properties) {
      if (p.name == "x" || p.name == "y" || p.name == "z") continue;
      cloud.property_types.push_back(p.type == ScalarType::UInt8 ? PlyScalar::UInt8
                                                                 : PlyScalar::Float32);
    }
  }

 private:
  [[noreturn]] void fail(const std::string& fault) const { throw InputError(file_, fault); }

  Header parseHeader() const {
    const std::size_t limit = std::min(data_.size(), kMaxHeaderBytes);
    if (data_.substr(0, 4) != "ply\n" && data_.substr(0, 5) != "ply\r\n") {
      fail("not a PLY file (it does not start with \"ply\")");
    }
    Header header;
    bool format_seen = false;
    std::size_t at = 0;
    for (int line_number = 1;; ++line_number) {
      const std::size_t end = data_.find('\n', at);
      if (end == std::string_view::npos || end >= limit) {
        fail("no \"end_header\" line within the first " + std::to_string(limit) +
             " bytes (truncated or not a PLY file)");
      }
      const std::string_view line = data_.substr(at, end - at);
      at = end + 1;
      const std::vector<std::string_view> words = splitWords(line);
      const auto bad_line = [&](const std::string& why) {
        fail("header line " + std::to_string(line_number) + " \"" + std::string(line) +
             "\": " + why);
      };
      if (!words.empty() && words[0] == "comment") {
        const std::size_t text = line.find("comment") + 7;
        std::string comment(line.substr(std::min(line.size(), text + 1)));
        while (!comment.empty() && (comment.back() == '\r' || comment.back() == ' '))
          comment.pop_back();
        if (words.size() >= 2 && words[1] == "camera") checkCameraComment(words, bad_line);
        header.comments.push_back(std::move(comment));
        continue;
      }
      if (line_number == 1 || words.empty() || words[0] == "obj_info") {
        continue;
      }
      if (words[0] == "end_header") {
        if (words.size() != 1) bad_line("unexpected words after end_header");
        break;
      }
      if (words[0] == "format") {
        if (format_seen) bad_line("a second format line");
        if (words.size() != 3 || words[2] != "1.0") bad_line("expected \"format <encoding> 1.0\"");
        if (words[1] == "ascii") {
          header.encoding = Encoding::Ascii;
        } else if (words[1] == "binary_little_endian") {
          header.encoding = Encoding::BinaryLittleEndian;
        } else if (words[1] == "binary_big_endian") {
          header.encoding = Encoding::BinaryBigEndian;
        } else {
          bad_line("unknown encoding");
        }
        format_seen = true;
      } else if (words[0] == "element") {
        if (words.size() != 3) bad_line("expected \"element <name> <count>\"");
        Element element;
        element.name = words[1];
        const auto [ptr, ec] =
            std::from_chars(words[2].data(), words[2].data() + words[2].size(), element.count);
        if (ec != std::errc() || ptr != words[2].data() + words[2].size()) {
          bad_line("the count is not a non-negative integer");
        }
        if (header.elements.empty() && element.name != "vertex") {
          fail("element \"" + element.name +
               "\" comes before \"vertex\"; the vertex element must come first");
        }
        header.elements.push_back(std::move(element));
      } else if (words[0] == "property") {
        if (header.elements.empty()) bad_line("a property before any element");
        Property property;
        if (words.size() == 5 && words[1] == "list") {
          const auto count_type = scalarType(words[2]);
          const auto item_type = scalarType(words[3]);
          if (!count_type || !item_type) bad_line("unknown property type");
          if (!isInteger(*count_type)) bad_line("a list count must be of an integer type");
          property = Property{std::string(words[4]), *item_type, true, *count_type};
        } else if (words.size() == 3) {
          const auto type = scalarType(words[1]);
          if (!type) bad_line("unknown property type \"" + std::string(words[1]) + "\"");
          property = Property{std::string(words[2]), *type, false, ScalarType::UInt8};
        } else {
          bad_line("expected \"property <type> <name>\" or \"property list <type> <type> <name>\"");
        }
        header.elements.back().properties.push_back(std::move(property));
      } else {
        bad_line("unknown keyword \"" + std::string(words[0]) + "\"");
      }
    }
    if (!format_seen) fail("the header has no \"format\" line");
    if (header.elements.empty()) fail("the header declares no \"vertex\" element");
    header.data_offset = at;
    return header;
  }

  // "comment camera <index> <name>" (a merged cloud's camera names): an
  // index 0..255 and one name word. Other comments that start with "camera"
  // (e.g. another program's "camera model …") are ordinary comments.
  template <class BadLine>
  static void checkCameraComment(const std::vector<std::string_view>& words,
                                 const BadLine& bad_line) {
    if (words.size() < 3) return;
    unsigned long index = 0;
    const auto [ptr, ec] =
        std::from_chars(words[2].data(), words[2].data() + words[2].size(), index);
    if (ptr != words[2].data() + words[2].size() || ec == std::errc::invalid_argument) return;
    if (ec != std::errc() || index > 255) bad_line("the camera index is not an integer 0..255");
    if (words.size() != 4) bad_line("expected \"comment camera <index> <name>\"");
  }

  void checkVertexElement(const Element& vertex) const {
    std::set<std::string> names;
    for (const Property& p : vertex.properties) {
      if (p.is_list)
        fail("vertex property \"" + p.name + "\" is a list; only scalars are supported");
      if (!names.insert(p.name).second)
        fail("vertex property \"" + p.name + "\" is declared twice");
    }
    for (const char* axis : {"x", "y", "z"}) {
      if (names.count(axis) == 0)
        fail(std::string("the vertex element has no property \"") + axis + "\"");
    }
  }

  // Maps each vertex property to its destination: 0..2 for x y z, 3+i for extra i.
  static std::vector<std::size_t> destinations(const Element& vertex, PointCloud& cloud) {
    std::vector<std::size_t> dest;
    for (const Property& p : vertex.properties) {
      if (p.name == "x" || p.name == "y" || p.name == "z") {
        dest.push_back(static_cast<std::size_t>(p.name[0] - 'x'));
      } else {
        dest.push_back(3 + cloud.property_names.size());
        cloud.property_names.push_back(p.name);
      }
    }
    return dest;
  }

  static void allocate(PointCloud& cloud, std::size_t n) {
    cloud.xyz.resize(3 * n);
    cloud.properties.assign(cloud.property_names.size(), std::vector<float>(n));
  }

  static void store(PointCloud& cloud, std::size_t i, std::size_t dest, double value) {
    const auto v = static_cast<float>(value);
    if (dest < 3) {
      cloud.xyz[3 * i + dest] = v;
    } else {
      cloud.properties[dest - 3][i] = v;
    }
  }

  // Binary data.

  std::uint64_t rawBits(std::size_t at, std::size_t size, Encoding encoding) const {
    std::uint64_t bits = 0;
    for (std::size_t b = 0; b < size; ++b) {
      const std::size_t index = encoding == Encoding::BinaryLittleEndian ? size - 1 - b : b;
      bits = (bits << 8) | static_cast<unsigned char>(data_[at + index]);
    }
    return bits;
  }

  double binaryValue(std::size_t at, ScalarType type, Encoding encoding) const {
    const std::uint64_t bits = rawBits(at, sizeOf(type), encoding);
    switch (type) {
      case ScalarType::Int8:
        return static_cast<std::int8_t>(bits);
      case ScalarType::UInt8:
        return static_cast<std::uint8_t>(bits);
      case ScalarType::Int16:
        return static_cast<std::int16_t>(bits);
      case ScalarType::UInt16:
        return static_cast<std::uint16_t>(bits);
      case ScalarType::Int32:
        return static_cast<std::int32_t>(bits);
      case ScalarType::UInt32:
        return static_cast<std::uint32_t>(bits);
      case ScalarType::Float32:
        return std::bit_cast<float>(static_cast<std::uint32_t>(bits));
      case ScalarType::Float64:
        return std::bit_cast<double>(bits);
    }
    return 0;
  }

  PointCloud readBinaryVertices(const Element& vertex, Encoding encoding, std::size_t& at) const {
    std::size_t stride = 0;
    for (const Property& p : vertex.properties)
      stride += sizeOf(p.type);
    if (stride == 0) fail("the vertex element has no properties");
    const std::size_t available = data_.size() - at;
    if (vertex.count > available / stride) {
      fail("truncated: the header declares " + std::to_string(vertex.count) + " vertices of " +
           std::to_string(stride) + " bytes but only " + std::to_string(available) +
           " bytes of data follow");
    }
    PointCloud cloud;
    const std::vector<std::size_t> dest = destinations(vertex, cloud);
    const auto n = static_cast<std::size_t>(vertex.count);
    allocate(cloud, n);
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t p = 0; p < vertex.properties.size(); ++p) {
        const ScalarType type = vertex.properties[p].type;
        store(cloud, i, dest[p], binaryValue(at, type, encoding));
        at += sizeOf(type);
      }
    }
    return cloud;
  }

  void skipBinary(const Element& element, Encoding encoding, std::size_t& at) const {
    if (element.properties.empty()) return;
    const auto need = [&](std::size_t bytes) {
      if (data_.size() - at < bytes) {
        fail("truncated: the file ends inside element \"" + element.name + "\"");
      }
    };
    for (std::uint64_t i = 0; i < element.count; ++i) {
      for (const Property& p : element.properties) {
        if (p.is_list) {
          need(sizeOf(p.count_type));
          const double count = binaryValue(at, p.count_type, encoding);
          at += sizeOf(p.count_type);
          if (count < 0) fail("a negative list length in element \"" + element.name + "\"");
          const auto items = static_cast<std::uint64_t>(count);
          if (items > (data_.size() - at) / sizeOf(p.type)) {
            fail("truncated: the file ends inside element \"" + element.name + "\"");
          }
          at += static_cast<std::size_t>(items) * sizeOf(p.type);
        } else {
          need(sizeOf(p.type));
          at += sizeOf(p.type);
        }
      }
    }
  }

  // ASCII data.

  struct AsciiCursor {
    std::string_view data;
    std::size_t at = 0;

    std::optional<std::string_view> next() {
      const std::size_t begin = data.find_first_not_of(" \t\r\n", at);
      if (begin == std::string_view::npos) {
        at = data.size();
        return std::nullopt;
      }
      const std::size_t end = std::min(data.find_first_of(" \t\r\n", begin), data.size());
      at = end;
      return data.substr(begin, end - begin);
    }
  };

  double asciiValue(AsciiCursor& cursor, const std::string& element) const {
    const std::optional<std::string_view> word = cursor.next();
    if (!word) fail("truncated: the file ends inside element \"" + element + "\"");
    double value = 0;
    const auto [ptr, ec] = std::from_chars(word->data(), word->data() + word->size(), value);
    if (ec != std::errc() || ptr != word->data() + word->size()) {
      fail("\"" + std::string(*word) + "\" in element \"" + element + "\" is not a number");
    }
    return value;
  }

  PointCloud readAsciiVertices(const Element& vertex, AsciiCursor& cursor) const {
    // Every value takes at least two characters (a digit and a separator).
    const std::size_t available = data_.size() - cursor.at;
    const std::size_t per_vertex = 2 * vertex.properties.size();
    if (vertex.count > (available + 1) / per_vertex) {
      fail("truncated: the header declares " + std::to_string(vertex.count) +
           " vertices but only " + std::to_string(available) + " bytes of text follow");
    }
    PointCloud cloud;
    const std::vector<std::size_t> dest = destinations(vertex, cloud);
    const auto n = static_cast<std::size_t>(vertex.count);
    allocate(cloud, n);
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t p = 0; p < vertex.properties.size(); ++p) {
        store(cloud, i, dest[p], asciiValue(cursor, vertex.name));
      }
    }
    return cloud;
  }

  void skipAscii(const Element& element, AsciiCursor& cursor) const {
    if (element.properties.empty()) return;
    for (std::uint64_t i = 0; i < element.count; ++i) {
      for (const Property& p : element.properties) {
        double items = 1;
        if (p.is_list) items = asciiValue(cursor, element.name);
        if (!(items >= 0) || items > static_cast<double>(data_.size())) {
          fail("an impossible list length in element \"" + element.name + "\"");
        }
        for (auto k = static_cast<std::size_t>(items); k > 0; --k)
          asciiValue(cursor, element.name);
      }
    }
  }

  fs::path file_;
  std::string_view data_;
};

}  // namespace

void writePly(const fs::path& file, const PointCloud& cloud) {
  if (auto fault = cloudFault(cloud)) {
    throw std::invalid_argument("point cloud " + file.string() + ": " + *fault);
  }
  std::ostringstream header;
  const auto is_uchar = [&](std::size_t p) {
    return !cloud.property_types.empty() && cloud.property_types[p] == PlyScalar::UInt8;
  };
  header << "ply\nformat binary_little_endian 1.0\n";
  for (const std::string& comment : cloud.comments)
    header << "comment " << comment << "\n";
  header << "element vertex " << cloud.size()
         << "\nproperty float x\nproperty float y\nproperty float z\n";
  for (std::size_t p = 0; p < cloud.property_names.size(); ++p)
    header << "property " << (is_uchar(p) ? "uchar " : "float ") << cloud.property_names[p] << "\n";
  header << "end_header\n";
  std::string out = header.str();
  out.reserve(out.size() + cloud.size() * 4 * (3 + cloud.properties.size()));
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    for (std::size_t c = 0; c < 3; ++c)
      appendFloatLe(out, cloud.xyz[3 * i + c]);
    for (std::size_t p = 0; p < cloud.properties.size(); ++p) {
      if (is_uchar(p)) {
        out.push_back(static_cast<char>(static_cast<std::uint8_t>(cloud.properties[p][i])));
      } else {
        appendFloatLe(out, cloud.properties[p][i]);
      }
    }
  }
  writeFileAtomically(file, out);
}

std::vector<std::string> cameraNamesOf(const PointCloud& cloud) {
  std::vector<std::string> names;
  for (const std::string& comment : cloud.comments) {
    const std::vector<std::string_view> words = splitWords(comment);
    if (words.size() != 3 || words[0] != "camera") continue;
    std::size_t index = 0;
    const auto [ptr, ec] =
        std::from_chars(words[1].data(), words[1].data() + words[1].size(), index);
    if (ec != std::errc() || index > 255) continue;
    if (names.size() <= index) names.resize(index + 1);
    names[index] = std::string(words[2]);
  }
  return names;
}

void appendCameraCloud(PointCloud& merged, const PointCloud& part, std::size_t index,
                       const std::string& camera) {
  if (index > 255)
    throw std::invalid_argument("merged cloud: camera index " + std::to_string(index) + " > 255");
  if (camera.empty() || camera.find_first_of(" \t\r\n") != std::string::npos)
    throw std::invalid_argument("merged cloud: camera name \"" + camera +
                                "\" is empty or has spaces");
  std::vector<std::string> names;
  for (const std::string& name : part.property_names) {
    if (name != kCameraProperty) names.push_back(name);
  }
  const bool first = merged.property_names.empty() && merged.xyz.empty();
  if (first) {
    merged.property_names = names;
    merged.property_names.emplace_back(kCameraProperty);
    merged.properties.assign(merged.property_names.size(), {});
    merged.property_types.assign(merged.property_names.size(), PlyScalar::Float32);
    merged.property_types.back() = PlyScalar::UInt8;
  }
  std::vector<std::string> have = merged.property_names;
  std::erase(have, std::string(kCameraProperty));
  if (have != names)
    throw std::invalid_argument("merged cloud: camera '" + camera +
                                "' has other properties than the cameras before it");
  if (merged.property_types.size() != merged.property_names.size())
    merged.property_types.assign(merged.property_names.size(), PlyScalar::Float32);
  merged.xyz.insert(merged.xyz.end(), part.xyz.begin(), part.xyz.end());
  std::size_t from = 0;
  for (std::size_t p = 0; p < merged.property_names.size(); ++p) {
    std::vector<float>& values = merged.properties[p];
    if (merged.property_names[p] == kCameraProperty) {
      merged.property_types[p] = PlyScalar::UInt8;
      values.insert(values.end(), part.size(), static_cast<float>(index));
      continue;
    }
    while (part.property_names[from] == kCameraProperty)
      ++from;
    values.insert(values.end(), part.properties[from].begin(), part.properties[from].end());
    ++from;
  }
  merged.comments.push_back("camera " + std::to_string(index) + " " + camera);
}

PointCloud readPly(const fs::path& file) {
  const std::string data = readFileContents(file, kMaxPlyBytes);
  return PlyParser(file, data).parse();
}

}  // namespace cylscan::formats
