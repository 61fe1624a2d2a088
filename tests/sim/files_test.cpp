// SPDX-License-Identifier: Apache-2.0
// The virtual head's files: board/sim/head.toml, scene files and PLY meshes.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "drivers/sim/head_config.hpp"
#include "drivers/sim/scene.hpp"
#include "drivers/sim/triangle_mesh.hpp"
#include "drivers/toml_reader.hpp"
#include "tests/support/temp_dir.hpp"

namespace cylscan::sim {
namespace {

namespace fs = std::filesystem;
using drivers::ConfigError;
using test_support::TempDir;
const fs::path kBoard = fs::path(CYLSCAN_SOURCE_DIR) / "board" / "sim";

// The error names the file, the line and the key.
void expectConfigError(const std::function<void()>& f, int line, const std::string& key) {
  try {
    f();
    FAIL() << "no error for " << key;
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_EQ(e.key(), key) << e.what();
    EXPECT_NE(std::string(e.what()).find(":" + std::to_string(line) + ": " + key),
              std::string::npos)
        << e.what();
  }
}

// board/sim is the built-in head with a real head's imperfections: without
// them it is the built-in one, and it has every one the cylinder and stage can.
TEST(HeadFile, BoardSimHeadIsTheBuiltInDefaultMadeImperfect) {
  const HeadConfig shipped = loadHeadConfig(kBoard / "head.toml");
  EXPECT_GT(shipped.projector.low_half_offset_deg, 0);
  EXPECT_GT(shipped.projector.slot_pitch_error_deg, 0);
  EXPECT_GT(shipped.projector.slot_width_error, 0);
  EXPECT_GT(shipped.projector.source_warmup_drop, 0);
  EXPECT_GT(shipped.stage.backlash_deg, 0);
  EXPECT_GT(shipped.stage.home_repeatability_deg, 0);
  EXPECT_EQ(idealOf(defaultHeadConfig()), defaultHeadConfig());
  const HeadConfig file = idealOf(shipped);
  const HeadConfig builtin = defaultHeadConfig();
  EXPECT_EQ(file.projector, builtin.projector);
  EXPECT_EQ(file.stage, builtin.stage);
  EXPECT_EQ(file.noise, builtin.noise);
  EXPECT_EQ(file.lines, builtin.lines);
  EXPECT_EQ(file.render, builtin.render);
  ASSERT_EQ(file.cameras.size(), 2u);
  EXPECT_EQ(file.cameras[0], builtin.cameras[0]);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(file.cameras[1].rotation_deg[static_cast<std::size_t>(i)],
                builtin.cameras[1].rotation_deg[static_cast<std::size_t>(i)], 1e-12);
  }
  HeadConfig aux_fixed = file;
  aux_fixed.cameras[1].rotation_deg = builtin.cameras[1].rotation_deg;
  EXPECT_EQ(aux_fixed, builtin);
}

TEST(HeadFile, ErrorsNameFileLineAndKey) {
  TempDir tmp;
  const auto unknown = tmp.write("a.toml", "[projector]\nradius_mm = 30\nradius = 3\n");
  expectConfigError([&] { loadHeadConfig(unknown); }, 3, "projector.radius");
  const auto bad = tmp.write("b.toml", "[stage]\n\nmax_speed_deg_s = -1\n");
  expectConfigError([&] { loadHeadConfig(bad); }, 3, "stage.max_speed_deg_s");
  const auto type = tmp.write("c.toml", "[noise]\nscale = \"high\"\n");
  expectConfigError([&] { loadHeadConfig(type); }, 2, "noise.scale");
  const auto cam = tmp.write("d.toml",
                             "[[camera]]\nname = \"main\"\n[[camera]]\nname = \"aux\"\n"
                             "bit_depth = 11\n");
  expectConfigError([&] { loadHeadConfig(cam); }, 5, "camera[1].bit_depth");
  const auto syntax = tmp.write("e.toml", "[stage\n");
  EXPECT_THROW(loadHeadConfig(syntax), ConfigError);
  EXPECT_THROW(loadHeadConfig(tmp.path() / "missing.toml"), ConfigError);
  // A [sim] section of a board profile reads the same way.
  const toml::table board = toml::parse("[sim.stage]\nmicrosteps = 16\n");
  const HeadConfig c = parseHeadConfig(*board["sim"].as_table(), "board.toml", "sim");
  EXPECT_EQ(c.stage.microsteps, 16);
}

// The ranges of a camera's exposure and gain: read like its other keys,
// defaulted, and checked against each other and the camera's defaults.
TEST(HeadFile, CameraControlRangesAreReadAndChecked) {
  TempDir tmp;
  const std::string main = "[[camera]]\nname = \"main\"\n";
  const HeadConfig plain = loadHeadConfig(tmp.write("plain.toml", main));
  EXPECT_EQ(plain.cameras[0].exposure_min_us, 20.0);
  EXPECT_EQ(plain.cameras[0].exposure_max_us, 200000.0);
  EXPECT_EQ(plain.cameras[0].gain_min, 1.0);
  EXPECT_EQ(plain.cameras[0].gain_max, 16.0);
  const HeadConfig set = loadHeadConfig(
      tmp.write("set.toml", main + "exposure_us = 900000.0\nexposure_min_us = 50.0\n"
                                   "exposure_max_us = 1e6\ngain = 0.5\ngain_min = 0.25\n"
                                   "gain_max = 64.0\n"));
  EXPECT_EQ(set.cameras[0].exposure_us, 900000.0);
  EXPECT_EQ(set.cameras[0].exposure_min_us, 50.0);
  EXPECT_EQ(set.cameras[0].exposure_max_us, 1e6);
  EXPECT_EQ(set.cameras[0].gain, 0.5);
  EXPECT_EQ(set.cameras[0].gain_min, 0.25);
  EXPECT_EQ(set.cameras[0].gain_max, 64.0);

  auto bad = [&](const std::string& name, const std::string& lines) {
    return tmp.write(name, main + lines);
  };
  // A default outside the range names the default ...
  const auto long_default = bad("a.toml", "exposure_us = 300000.0\n");
  expectConfigError([&] { loadHeadConfig(long_default); }, 3, "camera[0].exposure_us");
  const auto high_gain = bad("b.toml", "gain = 20.0\n");
  expectConfigError([&] { loadHeadConfig(high_gain); }, 3, "camera[0].gain");
  // ... or, when only the range is given, the bound that excludes it.
  const auto short_max = bad("c.toml", "\nexposure_max_us = 5000.0\n");
  expectConfigError([&] { loadHeadConfig(short_max); }, 4, "camera[0].exposure_max_us");
  const auto high_min = bad("d.toml", "gain_min = 2.0\n");
  expectConfigError([&] { loadHeadConfig(high_min); }, 3, "camera[0].gain_min");
  // Bounds out of order, and bounds that are not positive.
  const auto inverted = bad("e.toml", "exposure_min_us = 500.0\nexposure_max_us = 400.0\n");
  expectConfigError([&] { loadHeadConfig(inverted); }, 4, "camera[0].exposure_max_us");
  const auto zero = bad("f.toml", "gain_min = 0.0\n");
  expectConfigError([&] { loadHeadConfig(zero); }, 3, "camera[0].gain_min");
  // The parameters' own check (for heads built in code) names the key too.
  CameraParams p;
  p.gain_max = 0.5;
  try {
    validate(p);
    ADD_FAILURE() << "gain_max < gain_min accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("gain_max"), std::string::npos) << e.what();
  }
}

TEST(SceneFile, BoardScenesLoad) {
  int count = 0;
  for (const auto& entry : fs::directory_iterator(kBoard / "scenes")) {
    if (entry.path().extension() != ".toml") continue;
    const Scene s = loadScene(entry.path());
    EXPECT_FALSE(s.objects.empty()) << entry.path();
    ++count;
  }
  EXPECT_GE(count, 1);
}

TEST(SceneFile, AllShapesAndErrors) {
  TempDir tmp;
  tmp.write("tri.ply",
            "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
            "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
            "end_header\n-10 -10 0\n10 -10 0\n10 10 0\n-10 10 0\n4 0 1 2 3\n3 0 2 1\n");
  const auto file = tmp.write("s.toml", R"(
name = "all"
ambient = 0.05
[[object]]
type = "sphere"
center = [0, 0, 580]
radius = 50
[[object]]
type = "plane"
point = [0, 0, 700]
normal = [0, 0, -1]
extent = [300, 200]
albedo = 0.5
[[object]]
type = "box"
center = [40, 0, 560]
size = [10, 20, 30]
rotation_deg = [0, 30, 0]
[[object]]
type = "checkerboard"
cols = 7
rows = 5
square_mm = 10
center = [0, 0, 650]
[[object]]
type = "mesh"
file = "tri.ply"
position = [0, 0, 500]
scale = 2
)");
  const Scene s = loadScene(file);
  ASSERT_EQ(s.objects.size(), 5u);
  EXPECT_EQ(s.name, "all");
  EXPECT_DOUBLE_EQ(s.ambient, 0.05);
  // The mesh square (±20 mm at z = 500) is hit first on the axis.
  const auto hit = s.firstHit({Vec3(0, 0, 0), Vec3(0, 0, 1)}, 1e9);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->t, 500, 1e-9);
  EXPECT_EQ(hit->object, 4);
  const auto side = s.firstHit({Vec3(0, 30, 0), Vec3(0, 0, 1)}, 1e9);
  ASSERT_TRUE(side);
  EXPECT_NEAR(side->t, 580 - std::sqrt(50.0 * 50 - 30 * 30), 1e-9);

  const auto unknown = tmp.write(
      "u.toml", "[[object]]\ntype = \"sphere\"\ncenter = [0,0,1]\nradius = 3\ncolour = 1\n");
  expectConfigError([&] { loadScene(unknown); }, 5, "object[0].colour");
  const auto badr =
      tmp.write("r.toml", "[[object]]\ntype = \"sphere\"\ncenter = [0,0,1]\nradius = -3\n");
  expectConfigError([&] { loadScene(badr); }, 4, "object[0].radius");
  const auto badtype = tmp.write("t.toml", "[[object]]\ntype = \"cone\"\n");
  expectConfigError([&] { loadScene(badtype); }, 2, "object[0].type");
  const auto none = tmp.write("n.toml", "ambient = 0.1\n");
  EXPECT_THROW(loadScene(none), ConfigError);
}

TEST(Ply, BinaryAndAsciiGiveTheSameMesh) {
  TempDir tmp;
  std::string bin =
      "ply\nformat binary_little_endian 1.0\ncomment cube corner\nelement vertex 3\n"
      "property double x\nproperty double y\nproperty double z\nproperty uchar red\n"
      "element face 1\nproperty list uchar uint vertex_indices\nend_header\n";
  auto put = [&](const void* p, std::size_t n) { bin.append(static_cast<const char*>(p), n); };
  const double v[3][3] = {{0, 0, 100}, {50, 0, 100}, {0, 50, 100}};
  for (const auto& p : v) {
    put(p, sizeof p);
    const unsigned char red = 7;
    put(&red, 1);
  }
  const unsigned char n = 3;
  const unsigned int idx[3] = {0, 1, 2};
  put(&n, 1);
  put(idx, sizeof idx);
  const TriangleMesh mesh = readPlyMesh(tmp.write("b.ply", bin));
  ASSERT_EQ(mesh.triangles().size(), 1u);
  const auto hit = mesh.intersect({Vec3(10, 10, 0), Vec3(0, 0, 1)}, 1e9);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->t, 100, 1e-12);
  EXPECT_FALSE(mesh.intersect({Vec3(40, 40, 0), Vec3(0, 0, 1)}, 1e9));
  EXPECT_THROW(readPlyMesh(tmp.write("t.ply", bin.substr(0, bin.size() - 3))), ConfigError);
  EXPECT_THROW(readPlyMesh(tmp.write("x.ply", "ply\nformat binary_big_endian 1.0\nend_header\n")),
               ConfigError);
}

TEST(Ply, ManyTrianglesThroughTheHierarchy) {
  // A tessellated sphere: hits agree with the analytic sphere to the facet error.
  std::vector<Vec3> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
  const int n = 60;
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j < 2 * n; ++j) {
      const double th = M_PI * i / n, ph = M_PI * j / n;
      vertices.emplace_back(40 * std::sin(th) * std::cos(ph), 40 * std::sin(th) * std::sin(ph),
                            580 + 40 * std::cos(th));
    }
  }
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < 2 * n; ++j) {
      const auto a = static_cast<std::uint32_t>(i * 2 * n + j);
      const auto b = static_cast<std::uint32_t>(i * 2 * n + (j + 1) % (2 * n));
      triangles.push_back({a, b, a + 2 * n});
      triangles.push_back({b, b + 2 * n, a + 2 * n});
    }
  }
  const TriangleMesh mesh(vertices, triangles);
  for (double x = -30; x <= 30; x += 7.5) {
    const auto hit = mesh.intersect({Vec3(x, 5, 0), Vec3(0, 0, 1)}, 1e9);
    ASSERT_TRUE(hit);
    EXPECT_NEAR(hit->t, 580 - std::sqrt(1600 - x * x - 25), 0.3);
  }
}

}  // namespace
}  // namespace cylscan::sim
