// The winding-number lattice mesher (tools/meshing/lattice_mesher.h) against independent truths:
// the winding number of a closed cube is 1 inside, 0 outside and 1/2 on a face, and its far-field
// approximation stays close to the exact sum; a sphere and a box meshed at rising resolution
// converge to their analytic volumes; an open box, two overlapping cubes and two apart give valid
// meshes (gf::validate) with positive angles and the expected volumes; and assimp test models
// that tetgen refuses (open, self-intersecting) become tet meshes through `mesh from-surface`.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "cli/commands.h"
#include "graphfrac/mesh.h"
#include "meshing/lattice_mesher.h"
#include "meshing/surface_reader.h"
#include "meshing/triangle_soup.h"

namespace fs = std::filesystem;
using gf::Vec3;
using gf::meshing::TriangleSoup;

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Soup {
  std::vector<double> v;
  std::vector<int32_t> f;
  void add(const Soup& o) {
    const int32_t n = static_cast<int32_t>(v.size() / 3);
    v.insert(v.end(), o.v.begin(), o.v.end());
    for (int32_t i : o.f) f.push_back(i + n);
  }
};

// Box [o, o + s], 12 outward triangles; `skip` drops the two triangles of one side (0..5:
// -x, +x, -y, +y, -z, +z), leaving a square hole.
Soup box(Vec3 o, Vec3 s, int skip = -1) {
  Soup b;
  for (int x = 0; x < 2; ++x) {
    for (int y = 0; y < 2; ++y) {
      for (int z = 0; z < 2; ++z) {
        b.v.insert(b.v.end(), {o.x + s.x * x, o.y + s.y * y, o.z + s.z * z});
      }
    }
  }
  // Corner index 4x + 2y + z; quads counter-clockwise from outside.
  const int quads[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1},
                           {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
  for (int q = 0; q < 6; ++q) {
    if (q == skip) continue;
    b.f.insert(b.f.end(), {quads[q][0], quads[q][1], quads[q][2]});
    b.f.insert(b.f.end(), {quads[q][0], quads[q][2], quads[q][3]});
  }
  return b;
}

// Icosphere of radius r: an icosahedron subdivided `levels` times, vertices on the sphere.
Soup sphere(double r, int levels) {
  const double t = (1 + std::sqrt(5.0)) / 2;
  std::vector<Vec3> v = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                         {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  std::vector<std::array<int32_t, 3>> f = {
      {0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
      {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
      {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (Vec3& p : v) p = (1 / gf::norm(p)) * p;
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int32_t, int32_t>, int32_t> mid;
    auto middle = [&](int32_t a, int32_t b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      const Vec3 m = 0.5 * (v[static_cast<size_t>(a)] + v[static_cast<size_t>(b)]);
      v.push_back((1 / gf::norm(m)) * m);
      return mid[key] = static_cast<int32_t>(v.size() - 1);
    };
    std::vector<std::array<int32_t, 3>> g;
    for (const auto& [a, b, c] : f) {
      const int32_t ab = middle(a, b), bc = middle(b, c), ca = middle(c, a);
      g.push_back({a, ab, ca});
      g.push_back({b, bc, ab});
      g.push_back({c, ca, bc});
      g.push_back({ab, bc, ca});
    }
    f = g;
  }
  Soup s;
  for (const Vec3& p : v) s.v.insert(s.v.end(), {r * p.x, r * p.y, r * p.z});
  for (const auto& t : f) s.f.insert(s.f.end(), t.begin(), t.end());
  return s;
}

gf::meshing::LatticeResult meshOf(const Soup& s, int cells) {
  const TriangleSoup soup(s.v, s.f);
  gf::meshing::LatticeOptions o;
  o.cells = cells;
  gf::Result<gf::meshing::LatticeResult> r = gf::meshing::latticeMesh(soup, o);
  EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message);
  if (!r.ok()) return {};
  // What the runtime demands of a body's mesh, checked again on a copy.
  gf::TetMesh copy = r.value().mesh;
  int flipped = -1;
  const gf::Result<void> valid = gf::validate(copy, "lattice", &flipped);
  EXPECT_TRUE(valid.ok()) << (valid.ok() ? "" : valid.error().message);
  EXPECT_EQ(flipped, 0);
  const gf::meshing::TetQuality q = gf::meshing::measureQuality(r.value().mesh);
  EXPECT_GT(q.minVolume, 0);
  EXPECT_GT(q.minDihedralDeg, 5.0);
  EXPECT_GT(q.meanRadiusRatio, 0.5);
  return std::move(r).value();
}

TEST(WindingNumber, ClosedCubeIsOneInsideZeroOutsideHalfOnAFace) {
  const Soup c = box({0, 0, 0}, {1, 1, 1});
  const TriangleSoup soup(c.v, c.f);
  for (double beta : {0.0, 2.0}) {
    EXPECT_NEAR(soup.winding({0.5, 0.5, 0.5}, beta), 1.0, 1e-12);
    EXPECT_NEAR(soup.winding({0.01, 0.99, 0.02}, beta), 1.0, 1e-12);
    EXPECT_NEAR(soup.winding({1.5, 0.5, 0.5}, beta), 0.0, 1e-12);
    EXPECT_NEAR(soup.winding({-3, 7, 2}, beta), 0.0, 1e-12);
    // On a face: inside a triangle, and on the diagonal between two.
    EXPECT_NEAR(soup.winding({0.3, 0.6, 0}, beta), 0.5, 1e-12);
    EXPECT_NEAR(soup.winding({0.5, 0.5, 1}, beta), 0.5, 1e-12);
    // Just off it, the jump: 1 inside, 0 outside.
    EXPECT_NEAR(soup.winding({0.3, 0.6, 1e-9}, beta), 1.0, 1e-12);
    EXPECT_NEAR(soup.winding({0.3, 0.6, -1e-9}, beta), 0.0, 1e-12);
  }
  // Reversed orientation reads -1 inside; the cube's enclosed volume by divergence is 1.
  Soup r = c;
  for (size_t t = 0; t < r.f.size(); t += 3) std::swap(r.f[t + 1], r.f[t + 2]);
  EXPECT_NEAR(TriangleSoup(r.v, r.f).winding({0.5, 0.5, 0.5}), -1.0, 1e-12);
  EXPECT_NEAR(soup.signedVolume(), 1.0, 1e-12);
}

// The far field (dipoles from beta = 3 cluster radii) against the exact sum over every triangle,
// on a 5120-triangle sphere and an open box, at points inside, outside and near the surface.
TEST(WindingNumber, FarFieldMatchesTheExactSum) {
  Soup s = sphere(1, 4);
  s.add(box({1.5, -0.5, -0.5}, {1, 1, 1}, 3));
  const TriangleSoup soup(s.v, s.f);
  double worst = 0;
  for (int i = 0; i < 400; ++i) {
    // Deterministic points spread over [-1.5, 3]^3.
    const Vec3 q = {-1.5 + 4.5 * std::fmod(0.6180339887 * i, 1.0),
                    -1.5 + 3.0 * std::fmod(0.7548776662 * i, 1.0),
                    -1.5 + 3.0 * std::fmod(0.5698402910 * i, 1.0)};
    worst = std::max(worst, std::abs(soup.winding(q, 3.0) - soup.winding(q, 0.0)));
  }
  std::printf("[ winding ] far field vs exact: max |error| %.2e over 400 points\n", worst);
  EXPECT_LT(worst, 0.03);
  EXPECT_NEAR(soup.winding({0, 0, 0}), 1.0, 0.02);
  EXPECT_NEAR(soup.winding({2, 0, 0}), 1.0 - 1.0 / 6, 0.05);  // a face missing: ~5/6
}

// Volume converges to 4/3 pi r^3 (the 20480-triangle icosphere itself is 0.05 % short) and
// to the box's 0.48, with the error falling as the cells shrink.
TEST(LatticeMesher, SphereAndBoxConvergeToTheirVolume) {
  const Soup ball = sphere(1, 5);
  const double exact = 4.0 / 3 * kPi;
  double last = 1;
  for (int cells : {8, 16, 32}) {
    const gf::meshing::LatticeResult r = meshOf(ball, cells);
    const double err = std::abs(r.mesh.volume() - exact) / exact;
    const gf::meshing::TetQuality q = gf::meshing::measureQuality(r.mesh);
    std::printf("[ sphere  ] %2d cells: %zu tets, volume error %.4f, min dihedral %.1f deg\n",
                cells, r.mesh.tetCount(), err, q.minDihedralDeg);
    EXPECT_LT(err, last);
    last = err;
    EXPECT_EQ(r.parts, 1u);
  }
  EXPECT_LT(last, 0.01);
  const Soup b = box({0.1, 0.2, 0.3}, {1, 0.6, 0.8});
  last = 1;
  for (int cells : {5, 10, 20}) {
    const double err = std::abs(meshOf(b, cells).mesh.volume() - 0.48) / 0.48;
    std::printf("[ box     ] %2d cells: volume error %.4f\n", cells, err);
    EXPECT_LE(err, last + 1e-12);
    last = err;
  }
  EXPECT_LT(last, 0.01);
}

// One side missing: the winding number still closes the hole (at about its plane).
TEST(LatticeMesher, OpenBoxGivesAValidMesh) {
  const gf::meshing::LatticeResult r = meshOf(box({0, 0, 0}, {1, 1, 1}, 3), 20);
  EXPECT_EQ(r.parts, 1u);
  EXPECT_NEAR(r.mesh.volume(), 1.0, 0.1);
  EXPECT_NEAR(r.mesh.volume() / r.windingVolume, 1.0, 0.03);
}

// Two cubes overlapping by half along each axis: the union, 2 - 1/8.
TEST(LatticeMesher, SelfIntersectingCubesGiveTheirUnion) {
  Soup s = box({0, 0, 0}, {1, 1, 1});
  s.add(box({0.5, 0.5, 0.5}, {1, 1, 1}));
  const gf::meshing::LatticeResult r = meshOf(s, 24);
  EXPECT_EQ(r.parts, 1u);
  EXPECT_NEAR(r.mesh.volume(), 1.875, 0.03);
  // The divergence-theorem volume counts the overlap twice; the winding number does not.
  EXPECT_NEAR(TriangleSoup(s.v, s.f).signedVolume(), 2.0, 1e-12);
  EXPECT_NEAR(r.windingVolume, 1.875, 0.02);
}

TEST(LatticeMesher, TwoPartsGiveTwoComponents) {
  Soup s = box({0, 0, 0}, {1, 1, 1});
  s.add(box({2, 0, 0}, {1, 0.5, 0.5}));
  const gf::meshing::LatticeResult r = meshOf(s, 30);
  EXPECT_EQ(r.parts, 2u);
  EXPECT_NEAR(r.mesh.volume(), 1.25, 0.02);
}

// Cubes meeting along an edge only: the kept tets touch along it; the fan is filled so the
// boundary is 2-manifold.
TEST(LatticeMesher, EdgeContactIsMadeManifold) {
  Soup s = box({0, 0, 0}, {1, 1, 1});
  s.add(box({1, 1, 0}, {1, 1, 1}));
  const gf::meshing::LatticeResult r = meshOf(s, 8);
  EXPECT_EQ(r.parts, 1u);
  EXPECT_NEAR(r.mesh.volume(), 2.0, 0.1);
}

struct Outcome {
  int code = -1;
  std::string out, err;
};

Outcome meshCommand(std::vector<std::string> args) {
  args.insert(args.begin(), "mesh");
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  Outcome r;
  r.code = gf::cli::runMeshCommand(static_cast<int>(argv.size()), argv.data());
  r.out = testing::internal::GetCapturedStdout();
  r.err = testing::internal::GetCapturedStderr();
  return r;
}

fs::path writeObj(const std::string& name, const Soup& s) {
  const fs::path dir = fs::temp_directory_path() / "gf_lattice_test";
  fs::create_directories(dir);
  const fs::path path = dir / name;
  std::FILE* f = std::fopen(path.c_str(), "w");
  for (size_t i = 0; i < s.v.size(); i += 3) {
    std::fprintf(f, "v %.17g %.17g %.17g\n", s.v[i], s.v[i + 1], s.v[i + 2]);
  }
  for (size_t i = 0; i < s.f.size(); i += 3) {
    std::fprintf(f, "f %d %d %d\n", s.f[i] + 1, s.f[i + 1] + 1, s.f[i + 2] + 1);
  }
  std::fclose(f);
  return path;
}

// `mesh from-surface` with the default method: an open surface and one that crosses itself
// (which tetgen refuses, or which is meshed anyway where tetgen is not installed) go to the
// lattice; a closed clean one still goes to tetgen when it is there.
TEST(LatticeMesher, AutoFallsBackToTheLattice) {
  const fs::path open = writeObj("open.obj", box({0, 0, 0}, {1, 1, 1}, 3));
  const std::string out = (open.parent_path() / "o.msh").string();
  Outcome r = meshCommand({"from-surface", open.string(), out});
  ASSERT_EQ(r.code, gf::cli::kExitOk) << r.err;
  EXPECT_NE(r.out.find("surface is not closed (4 open edges): using --method lattice"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("lattice: 32 cells"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("volume: mesh "), std::string::npos) << r.out;

  Soup crossing = box({0, 0, 0}, {1, 1, 1});
  crossing.add(box({0.5, 0.5, 0.5}, {1, 1, 1}));
  r = meshCommand({"from-surface", writeObj("cross.obj", crossing).string(), out});
  ASSERT_EQ(r.code, gf::cli::kExitOk) << r.err;
  EXPECT_NE(r.out.find("tetgen cannot mesh it ("), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("): using --method lattice"), std::string::npos) << r.out;
  gf::Result<gf::TetMesh> m = gf::TetMesh::fromFile(out);
  ASSERT_TRUE(m.ok()) << m.error().message;
  EXPECT_NEAR(m.value().volume(), 1.875, 0.04);

  // The lattice on request for a closed surface; the tetgen options do not mix with it.
  r = meshCommand({"from-surface", writeObj("cube.obj", box({0, 0, 0}, {1, 1, 1})).string(), out,
                   "--method", "lattice", "--cells", "4"});
  ASSERT_EQ(r.code, gf::cli::kExitOk) << r.err;
  EXPECT_NE(r.out.find("lattice: 4 cells"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("divergence-theorem volume 1"), std::string::npos) << r.out;
  r = meshCommand({"from-surface", open.string(), out, "--method", "tetgen", "--cells", "4"});
  EXPECT_EQ(r.code, gf::cli::kExitUsage);
  r = meshCommand({"from-surface", open.string(), out, "--cells", "2.5"});
  EXPECT_EQ(r.code, gf::cli::kExitUsage);
  fs::remove_all(open.parent_path());
}

// Debian's assimp-testmodels: sphereWithHole.stl is open and duck.dae crosses itself, so tetgen
// refuses both; auto goes to the lattice and the results load as a body's mesh.
TEST(LatticeMesher, AssimpModelThatTetgenRefuses) {
  const fs::path model = "/usr/share/assimp/models/STL/sphereWithHole.stl";
  if (!gf::meshing::haveAssimp() || !fs::exists(model)) {
    GTEST_SKIP() << "needs assimp and Debian's assimp-testmodels (tools/setup tools)";
  }
  const fs::path dir = fs::temp_directory_path() / "gf_lattice_test_assimp";
  fs::create_directories(dir);
  const std::string out = (dir / "hole.msh").string();
  std::vector<std::string> args = {"mesh", "from-surface", model.string(), out, "--cells", "20"};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  testing::internal::CaptureStdout();
  const int code = gf::cli::runMeshCommand(static_cast<int>(argv.size()), argv.data());
  const std::string said = testing::internal::GetCapturedStdout();
  ASSERT_EQ(code, gf::cli::kExitOk) << said;
  EXPECT_NE(said.find("open edge"), std::string::npos) << said;
  EXPECT_NE(said.find("lattice: 20 cells"), std::string::npos) << said;
  EXPECT_NE(said.find("quality: dihedral angles"), std::string::npos) << said;
  gf::Result<gf::TetMesh> m = gf::TetMesh::fromFile(out);
  ASSERT_TRUE(m.ok()) << m.error().message;
  EXPECT_GT(m.value().tetCount(), 1000u);

  // The duck is closed but crosses itself: tetgen fails (or is missing), the lattice meshes it.
  args = {"mesh", "from-surface", "/usr/share/assimp/models/Collada/duck.dae", out};
  argv.clear();
  for (std::string& a : args) argv.push_back(a.data());
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  const int duck = gf::cli::runMeshCommand(static_cast<int>(argv.size()), argv.data());
  const std::string duckSaid = testing::internal::GetCapturedStdout();
  testing::internal::GetCapturedStderr();
  ASSERT_EQ(duck, gf::cli::kExitOk) << duckSaid;
  EXPECT_NE(duckSaid.find("tetgen cannot mesh it ("), std::string::npos) << duckSaid;
  EXPECT_NE(duckSaid.find("lattice: 32 cells"), std::string::npos) << duckSaid;
  m = gf::TetMesh::fromFile(out);
  ASSERT_TRUE(m.ok()) << m.error().message;
  // Against its divergence-theorem volume, 1.1955 (its crossings are small).
  EXPECT_NEAR(m.value().volume(), 1.1955, 0.03);
  fs::remove_all(dir);
}

}  // namespace
