// SPDX-License-Identifier: Apache-2.0
#include "drivers/sim/triangle_mesh.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

#include "drivers/toml_reader.hpp"

namespace cylscan::sim {

using drivers::ConfigError;

namespace {

constexpr std::uint32_t kLeafSize = 4;

bool slab(const Ray& ray, const Vec3& inv, const Vec3& lo, const Vec3& hi, double t_max) {
  double t0 = 0, t1 = t_max;
  for (int a = 0; a < 3; ++a) {
    double ta = (lo[a] - ray.origin[a]) * inv[a];
    double tb = (hi[a] - ray.origin[a]) * inv[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

}  // namespace

TriangleMesh::TriangleMesh(std::vector<Vec3> vertices,
                           std::vector<std::array<std::uint32_t, 3>> triangles)
    : vertices_(std::move(vertices)), triangles_(std::move(triangles)) {
  for (const auto& t : triangles_) {
    for (std::uint32_t i : t) {
      if (i >= vertices_.size()) throw std::invalid_argument("mesh: vertex index out of range");
    }
  }
  build();
}

TriangleMesh TriangleMesh::transformed(const Mat3& rotation, const Vec3& position,
                                       double scale) const {
  std::vector<Vec3> v;
  v.reserve(vertices_.size());
  for (const Vec3& p : vertices_)
    v.push_back(position + scale * (rotation * p));
  return TriangleMesh(std::move(v), triangles_);
}

void TriangleMesh::build() {
  nodes_.clear();
  if (triangles_.empty()) return;
  nodes_.reserve(2 * triangles_.size() / kLeafSize + 2);
  buildNode(0, static_cast<std::uint32_t>(triangles_.size()), 0);
}

std::uint32_t TriangleMesh::buildNode(std::uint32_t first, std::uint32_t count, int depth) {
  const auto index = static_cast<std::uint32_t>(nodes_.size());
  nodes_.push_back({});
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::max()), hi = -lo;
  for (std::uint32_t i = first; i < first + count; ++i) {
    for (std::uint32_t v : triangles_[i]) {
      lo = lo.cwiseMin(vertices_[v]);
      hi = hi.cwiseMax(vertices_[v]);
    }
  }
  nodes_[index].lo = lo;
  nodes_[index].hi = hi;
  if (count <= kLeafSize || depth > 40) {
    nodes_[index].first = first;
    nodes_[index].count = count;
    return index;
  }
  int axis = 0;
  (hi - lo).maxCoeff(&axis);
  auto centroid = [&](const std::array<std::uint32_t, 3>& t) {
    return vertices_[t[0]][axis] + vertices_[t[1]][axis] + vertices_[t[2]][axis];
  };
  const std::uint32_t half = count / 2;
  std::nth_element(triangles_.begin() + first, triangles_.begin() + first + half,
                   triangles_.begin() + first + count,
                   [&](const auto& a, const auto& b) { return centroid(a) < centroid(b); });
  const std::uint32_t left = buildNode(first, half, depth + 1);
  const std::uint32_t right = buildNode(first + half, count - half, depth + 1);
  nodes_[index].left = left;
  nodes_[index].right = right;
  return index;
}

std::optional<MeshHit> TriangleMesh::intersect(const Ray& ray, double t_max) const {
  if (nodes_.empty()) return std::nullopt;
  const Vec3 inv(1.0 / ray.dir.x(), 1.0 / ray.dir.y(), 1.0 / ray.dir.z());
  std::optional<MeshHit> best;
  double limit = t_max;
  std::uint32_t stack[96];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& n = nodes_[stack[--top]];
    if (!slab(ray, inv, n.lo, n.hi, limit)) continue;
    if (n.count > 0) {
      for (std::uint32_t i = n.first; i < n.first + n.count; ++i) {
        const Vec3& a = vertices_[triangles_[i][0]];
        const Vec3 e1 = vertices_[triangles_[i][1]] - a;
        const Vec3 e2 = vertices_[triangles_[i][2]] - a;
        const Vec3 p = ray.dir.cross(e2);
        const double det = e1.dot(p);
        if (std::abs(det) < 1e-14) continue;
        const double inv_det = 1.0 / det;
        const Vec3 s = ray.origin - a;
        const double u = s.dot(p) * inv_det;
        if (u < 0 || u > 1) continue;
        const Vec3 q = s.cross(e1);
        const double v = ray.dir.dot(q) * inv_det;
        if (v < 0 || u + v > 1) continue;
        const double t = e2.dot(q) * inv_det;
        if (t <= 1e-9 || t >= limit) continue;
        limit = t;
        best = MeshHit{t, e1.cross(e2).normalized()};
      }
    } else if (top + 2 <= 96) {
      stack[top++] = n.left;
      stack[top++] = n.right;
    }
  }
  return best;
}

// ---- PLY -------------------------------------------------------------------

namespace {

struct PlyProperty {
  std::string name;
  std::string type;        // scalar type, or the item type of a list
  std::string count_type;  // non-empty for lists
};

struct PlyElement {
  std::string name;
  std::size_t count = 0;
  std::vector<PlyProperty> properties;
};

int typeSize(const std::string& t) {
  if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
  if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
  if (t == "int" || t == "uint" || t == "int32" || t == "uint32" || t == "float" || t == "float32")
    return 4;
  if (t == "double" || t == "float64") return 8;
  return 0;
}

template <typename T>
T load(const unsigned char* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

double decode(const std::string& t, const unsigned char* p) {
  if (t == "char" || t == "int8") return load<std::int8_t>(p);
  if (t == "uchar" || t == "uint8") return load<std::uint8_t>(p);
  if (t == "short" || t == "int16") return load<std::int16_t>(p);
  if (t == "ushort" || t == "uint16") return load<std::uint16_t>(p);
  if (t == "int" || t == "int32") return load<std::int32_t>(p);
  if (t == "uint" || t == "uint32") return load<std::uint32_t>(p);
  if (t == "float" || t == "float32") return load<float>(p);
  return load<double>(p);
}

class PlyParser {
 public:
  explicit PlyParser(std::filesystem::path file) : file_(std::move(file)) {}

  TriangleMesh read() {
    std::ifstream in(file_, std::ios::binary);
    if (!in) fail("cannot open the file");
    readHeader(in);
    std::vector<Vec3> vertices;
    std::vector<std::array<std::uint32_t, 3>> triangles;
    for (const PlyElement& e : elements_) {
      for (std::size_t i = 0; i < e.count; ++i) {
        readItem(in, e);
        if (e.name == "vertex") {
          vertices.emplace_back(scalar_[0], scalar_[1], scalar_[2]);
        } else if (e.name == "face") {
          if (list_.size() < 3) fail("a face has fewer than 3 vertices");
          for (std::size_t k = 1; k + 1 < list_.size(); ++k) {
            triangles.push_back({list_[0], list_[k], list_[k + 1]});
          }
        }
      }
    }
    for (const auto& t : triangles) {
      for (std::uint32_t v : t) {
        if (v >= vertices.size()) fail("a face refers to a missing vertex");
      }
    }
    if (triangles.empty()) fail("no faces");
    return TriangleMesh(std::move(vertices), std::move(triangles));
  }

 private:
  [[noreturn]] void fail(const std::string& fault) const {
    throw ConfigError(file_.string(), 0, "", "PLY: " + fault);
  }

  void readHeader(std::istream& in) {
    std::string line;
    if (!std::getline(in, line) || line.rfind("ply", 0) != 0) fail("not a PLY file");
    bool end = false;
    while (!end && std::getline(in, line)) {
      if (!line.empty() && line.back() == '\r') line.pop_back();
      std::istringstream words(line);
      std::string word;
      words >> word;
      if (word == "format") {
        std::string fmt;
        words >> fmt;
        if (fmt == "ascii") {
          ascii_ = true;
        } else if (fmt != "binary_little_endian") {
          fail("format '" + fmt + "' not supported (ascii or binary_little_endian)");
        }
      } else if (word == "element") {
        PlyElement e;
        long long count = -1;
        words >> e.name >> count;
        if (count < 0 || count > 100'000'000) fail("bad element count in '" + line + "'");
        e.count = static_cast<std::size_t>(count);
        elements_.push_back(e);
      } else if (word == "property") {
        if (elements_.empty()) fail("property before element");
        PlyProperty p;
        std::string type;
        words >> type;
        if (type == "list") {
          words >> p.count_type >> p.type;
          if (typeSize(p.count_type) == 0 || typeSize(p.type) == 0) fail("bad list type");
        } else {
          p.type = type;
          if (typeSize(p.type) == 0) fail("bad property type '" + type + "'");
        }
        words >> p.name;
        elements_.back().properties.push_back(p);
      } else if (word == "end_header") {
        end = true;
      } else if (word != "comment" && word != "obj_info" && !word.empty()) {
        fail("unexpected header line '" + line + "'");
      }
    }
    if (!end) fail("no end_header");
    for (const PlyElement& e : elements_) {
      if (e.name == "vertex") {
        int found = 0;
        for (const char* axis : {"x", "y", "z"}) {
          for (const auto& p : e.properties)
            found += (p.name == axis && p.count_type.empty());
        }
        if (found != 3) fail("vertex needs scalar x, y, z");
      } else if (e.name == "face") {
        bool ok = false;
        for (const auto& p : e.properties) {
          ok |= (p.name == "vertex_indices" || p.name == "vertex_index") && !p.count_type.empty();
        }
        if (!ok) fail("face needs a list vertex_indices");
      }
    }
  }

  double next(std::istream& in, const std::string& type) {
    if (ascii_) {
      double v;
      if (!(in >> v)) fail("truncated or bad ascii data");
      return v;
    }
    unsigned char buf[8];
    const int n = typeSize(type);
    if (!in.read(reinterpret_cast<char*>(buf), n)) fail("truncated binary data");
    return decode(type, buf);
  }

  void readItem(std::istream& in, const PlyElement& e) {
    list_.clear();
    for (const PlyProperty& p : e.properties) {
      if (p.count_type.empty()) {
        const double v = next(in, p.type);
        if (p.name == "x") scalar_[0] = v;
        if (p.name == "y") scalar_[1] = v;
        if (p.name == "z") scalar_[2] = v;
        continue;
      }
      const double count = next(in, p.count_type);
      if (count < 0 || count > 1000) fail("bad list length");
      const bool indices = p.name == "vertex_indices" || p.name == "vertex_index";
      for (int k = 0; k < static_cast<int>(count); ++k) {
        const double v = next(in, p.type);
        if (indices) {
          if (v < 0 || v > 4e9) fail("bad vertex index");
          list_.push_back(static_cast<std::uint32_t>(v));
        }
      }
    }
  }

  std::filesystem::path file_;
  bool ascii_ = false;
  std::vector<PlyElement> elements_;
  double scalar_[3] = {0, 0, 0};
  std::vector<std::uint32_t> list_;
};

}  // namespace

TriangleMesh readPlyMesh(const std::filesystem::path& file) {
  static_assert(std::endian::native == std::endian::little, "the PLY reader assumes little endian");
  return PlyParser(file).read();
}

}  // namespace cylscan::sim
