// Mesh file formats: the same small mesh written by hand in Gmsh 2.2, Gmsh 4.1 (entity blocks,
// non-contiguous tags, parametric nodes, mixed element types) and TetGen (0- and 1-based, with
// attributes, markers and comments) must read to the identical mesh; writing .msh and reading
// it back must be exact; every file in the malformed corpus must fail with a specific reason.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <random>
#include <set>
#include <sstream>

#include "graphfrac/mesh.h"
#include "mesh/mesh_internal.h"

namespace {

namespace fs = std::filesystem;

std::string dataPath(const std::string& rel) {
  return std::string(GF_SOURCE_DIR) + "/tests/data/meshes/" + rel;
}

std::string tempPath(const std::string& name) {
  return (fs::path(::testing::TempDir()) / ("gf_mesh_" + std::to_string(::getpid()) + "_" + name))
      .string();
}

// The hand-written cube: corners of [0,2]x[0,1]x[0,0.5], Kuhn split, stored in this order.
const std::vector<double> kCubePositions = {2, 0, 0.5, 0, 0, 0,   2, 1, 0.5, 0, 1, 0,
                                            2, 0, 0,   0, 1, 0.5, 2, 1, 0,   0, 0, 0.5};

TEST(MeshIo, AllFormatsReadToTheSameMesh) {
  const char* files[] = {"good/cube_v22.msh", "good/cube_v41.msh", "good/cube_1based.node",
                         "good/cube_1based.ele", "good/cube_0based.ele"};
  std::vector<gf::TetMesh> meshes;
  for (const char* f : files) {
    gf::MeshLoadInfo info;
    gf::Result<gf::TetMesh> r = gf::TetMesh::fromFile(dataPath(f), &info);
    ASSERT_TRUE(r.ok()) << f << ": " << r.error().message;
    // Each file stores tet 4 with two nodes swapped; the loader must repair exactly that one.
    EXPECT_EQ(info.flippedFixed, 1) << f;
    meshes.push_back(std::move(r).value());
  }
  for (size_t i = 0; i < meshes.size(); ++i) {
    EXPECT_EQ(meshes[i].positions, kCubePositions) << files[i];
    EXPECT_EQ(meshes[i].tets, meshes[0].tets) << files[i];
    EXPECT_EQ(meshes[i].tetCount(), 6u);
    EXPECT_NEAR(meshes[i].volume(), 2.0 * 1.0 * 0.5, 1e-14);
    for (size_t e = 0; e < meshes[i].tetCount(); ++e) {
      // Each Kuhn tet is 1/6 of the box: 6V = 1, and positive after the repair.
      EXPECT_NEAR(gf::detail::tetSixVolume(meshes[i].positions.data(), &meshes[i].tets[4 * e]), 1.0,
                  1e-14);
    }
  }
}

TEST(MeshIo, MshRoundTripIsExact) {
  // A sphere has irrational coordinates: the writer must print enough digits.
  for (const gf::TetMesh& mesh : {gf::gen::sphere(0.37, 6), gf::gen::box(1, 2, 3, 2, 3, 4)}) {
    const std::string path = tempPath("roundtrip.msh");
    ASSERT_TRUE(mesh.writeMsh(path).ok());
    gf::MeshLoadInfo info;
    gf::Result<gf::TetMesh> back = gf::TetMesh::fromFile(path, &info);
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(back.value().positions, mesh.positions);  // bit-exact
    EXPECT_EQ(back.value().tets, mesh.tets);
    EXPECT_EQ(info.flippedFixed, 0);
    fs::remove(path);
  }
}

// Each malformed file and the words its error must contain (besides the file name).
const std::map<std::string, std::string> kBadFiles = {
    {"empty.msh", "empty file"},
    {"blank_lines.msh", "empty file"},
    {"not_gmsh.msh", ":1: not a Gmsh .msh file: expected $MeshFormat"},
    {"truncated_nodes.msh", "unexpected end of file after 3 of 8 nodes"},
    {"truncated_elements.msh", "unexpected end of file after 3 of 6 elements"},
    {"garbage_coordinate.msh", ":8: node 3: expected a coordinate, found 'abc'"},
    {"nan_coordinate.msh", ":8: node 3: non-finite coordinate 'nan'"},
    {"inf_coordinate.msh", ":9: node 4: non-finite coordinate 'inf'"},
    {"node_count_too_small.msh", "expected $EndNodes after 4 nodes"},
    {"element_count_too_large.msh", "section ended after 1 of 10 elements"},
    {"undefined_node.msh", ":13: element 1: node 99 is not defined"},
    {"negative_node.msh", ":13: element 1: node -4 is not defined"},
    {"repeated_node.msh", ":13: element 1: node 2 repeated"},
    {"zero_volume.msh", ":15: element 2: zero volume"},
    {"duplicate_nodes.msh", ":10: node 5: duplicate node: same position as node 2"},
    {"unreferenced_node.msh", ":10: node 5: unreferenced node"},
    {"nonmanifold_edge.msh", "non-manifold boundary: edge (1, 2) is on 4 boundary faces"},
    {"face_three_tets.msh", "non-manifold: face (1, 2, 3) is shared by 3 tets"},
    {"huge_node_count.msh", "unexpected end of file after 2 of 2000000000 nodes"},
    {"count_overflow.msh", ":5: expected a node count, found '99999999999999999999'"},
    {"negative_count.msh", "a node count -3 is out of range"},
    {"binary.msh", "binary .msh files are not supported"},
    {"version3.msh", "unsupported Gmsh format version '3.0'"},
    {"version40.msh", "unsupported Gmsh format version '4'"},
    {"no_tets.msh", "no 4-node tetrahedra (element type 4)"},
    {"tet10_only.msh", "found 1 10-node tetrahedra (type 11), which are not supported"},
    {"no_elements_section.msh", "no $Elements section"},
    {"unterminated_section.msh",
     "section $PhysicalNames opened on line 4 has no $EndPhysicalNames"},
    {"duplicate_node_tag.msh", ":9: node 7: number already used on line 8"},
    {"element_missing_node.msh", "element 1: tetrahedron with 0 tags needs 7 values, found 6"},
    {"garbage_element.msh", "element 1: expected a node tag, found 'three'"},
    {"missing_end_nodes.msh", "expected $EndNodes after 4 nodes"},
    {"v41_block_count_mismatch.msh", "node blocks hold 8 nodes but the header says 9"},
    {"v41_truncated_block.msh", "unexpected end of file after 6 of 8 node tags"},
    {"v41_bad_parametric.msh", "parametric flag must be 0 or 1, found '7'"},
    {"v41_tet_arity.msh", "element 7: tetrahedron needs a tag and 4 node tags, found 6 values"},
    {"tg_dim2", "tg_dim2.node:1: dimension must be 3, found 2"},
    {"tg_truncated_ele", "tg_truncated_ele.ele:2: unexpected end of file after 1 of 3 tetrahedra"},
    {"tg_bad_index", "tg_bad_index.ele:2: element 1: node 42 is not defined in"},
    {"tg_nodes_per_tet", "tg_nodes_per_tet.ele:1: nodes per tetrahedron must be 4 or 10, found 3"},
    {"tg_garbage_coordinate", ".node:3: point 2: expected a coordinate, found 'x1'"},
    {"tg_extra_points", "tg_extra_points.node:5: more records than the header's 3 points"},
    {"tg_missing_ele", "tg_missing_ele.ele: cannot open: no such file"},
    {"tg_empty_ele", "tg_empty_ele.ele: empty file"},
    {"tg_wrong_columns", "tg_wrong_columns.node:2: expected 6 values"},
    {"tg_zero_points", "tg_zero_points.node:1: a point count 0 is out of range"},
};

TEST(MeshIo, EveryMalformedFileFailsWithItsReason) {
  // Every file in the corpus must have an expectation, so nothing is added untested.
  std::set<std::string> seen;
  for (const auto& entry : fs::directory_iterator(dataPath("bad"))) {
    const fs::path p = entry.path();
    const std::string key = p.extension() == ".msh" ? p.filename().string() : p.stem().string();
    if (!seen.insert(key).second) continue;
    auto it = kBadFiles.find(key);
    ASSERT_NE(it, kBadFiles.end()) << "no expected error for " << p;
    const std::string path =
        p.extension() == ".msh" ? p.string() : (p.parent_path() / key).string() + ".ele";
    gf::Result<gf::TetMesh> r = gf::TetMesh::fromFile(path);
    ASSERT_FALSE(r.ok()) << key << " loaded";
    const std::string& msg = r.error().message;
    EXPECT_NE(msg.find(key), std::string::npos) << "file name missing: " << msg;
    EXPECT_NE(msg.find(it->second), std::string::npos)
        << "expected '" << it->second << "' in: " << msg;
  }
  EXPECT_EQ(seen.size(), kBadFiles.size()) << "an expectation names a file that does not exist";
}

TEST(MeshIo, MissingFilesAndUnknownFormats) {
  gf::Result<gf::TetMesh> r = gf::TetMesh::fromFile(dataPath("nowhere.msh"));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("nowhere.msh: cannot open: no such file"), std::string::npos);
  r = gf::TetMesh::fromFile(dataPath("good/cube_v22.stl"));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("unknown mesh format '.stl'"), std::string::npos);
  r = gf::TetMesh::fromFile(dataPath("good"));  // a directory
  ASSERT_FALSE(r.ok());
  r = gf::TetMesh::fromGmsh(dataPath("good"));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("not a regular file"), std::string::npos);
}

// Every prefix of the good files, and copies with random bytes overwritten, must load or fail
// cleanly (run under the asan preset this also proves there is no out-of-bounds read); a
// copy that still loads must be a valid mesh.
TEST(MeshIo, TruncatedAndCorruptedCopiesNeverCrash) {
  std::mt19937 rng(7);
  int failed = 0, loaded = 0;
  for (const char* name : {"good/cube_v22.msh", "good/cube_v41.msh"}) {
    std::ifstream in(dataPath(name), std::ios::binary);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string path = tempPath("corrupt.msh");
    auto attempt = [&](const std::string& content) {
      std::ofstream(path, std::ios::binary) << content;
      gf::Result<gf::TetMesh> r = gf::TetMesh::fromFile(path);
      if (r.ok()) {
        ++loaded;
        EXPECT_TRUE(gf::validate(r.value(), "reloaded").ok());
      } else {
        ++failed;
        EXPECT_NE(r.error().message.find(path), std::string::npos) << r.error().message;
      }
    };
    for (size_t n = 0; n < text.size(); ++n) attempt(text.substr(0, n));
    const std::string garbage("x9-.e$\n \0", 9);  // includes a NUL byte
    for (int trial = 0; trial < 300; ++trial) {
      std::string t = text;
      for (int k = 0; k < 3; ++k) {
        t[std::uniform_int_distribution<size_t>(0, t.size() - 1)(rng)] =
            garbage[std::uniform_int_distribution<size_t>(0, garbage.size() - 1)(rng)];
      }
      attempt(t);
    }
    fs::remove(path);
  }
  EXPECT_GT(failed, 1000);  // nearly every prefix is incomplete
  EXPECT_GT(loaded, 0);     // some byte changes are harmless (e.g. in a skipped section)
}

// Signed volume enclosed by a closed triangle surface (divergence theorem), independent of
// the tets: checks that the exported faces are closed and outward.
double enclosedVolume(const std::vector<double>& v, const std::vector<int>& f) {
  double s = 0;
  for (size_t i = 0; i < f.size(); i += 3) {
    const double* a = &v[3 * static_cast<size_t>(f[i])];
    const double* b = &v[3 * static_cast<size_t>(f[i + 1])];
    const double* c = &v[3 * static_cast<size_t>(f[i + 2])];
    s += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
         a[2] * (b[0] * c[1] - b[1] * c[0]);
  }
  return s / 6.0;
}

TEST(MeshIo, SurfaceExportObjAndPlyAreClosedAndOutward) {
  const gf::TetMesh mesh = gf::gen::cylinder(0.5, 2.0, 16, 4, 3);
  for (const char* ext : {".obj", ".ply"}) {
    const std::string path = tempPath(std::string("surface") + ext);
    ASSERT_TRUE(mesh.writeSurface(path).ok());
    std::ifstream in(path);
    std::vector<double> v;
    std::vector<int> f;
    std::string line;
    if (std::string(ext) == ".obj") {
      while (std::getline(in, line)) {
        std::istringstream s(line);
        std::string tag;
        s >> tag;
        if (tag == "v") {
          double x, y, z;
          s >> x >> y >> z;
          v.insert(v.end(), {x, y, z});
        } else if (tag == "f") {
          int a, b, c;
          s >> a >> b >> c;
          f.insert(f.end(), {a - 1, b - 1, c - 1});
        }
      }
    } else {
      size_t nv = 0, nf = 0;
      while (std::getline(in, line) && line != "end_header") {
        std::sscanf(line.c_str(), "element vertex %zu", &nv);
        std::sscanf(line.c_str(), "element face %zu", &nf);
      }
      for (size_t i = 0; i < nv; ++i) {
        double x, y, z;
        in >> x >> y >> z;
        v.insert(v.end(), {x, y, z});
      }
      for (size_t i = 0; i < nf; ++i) {
        int n, a, b, c;
        in >> n >> a >> b >> c;
        ASSERT_EQ(n, 3);
        f.insert(f.end(), {a, b, c});
      }
    }
    EXPECT_EQ(f.size(), mesh.boundaryFaces().size()) << ext;
    EXPECT_NEAR(enclosedVolume(v, f), mesh.volume(), 1e-12) << ext;
    fs::remove(path);
  }
  gf::Result<void> bad = mesh.writeSurface(tempPath("surface.stl"));
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("unknown surface format '.stl'"), std::string::npos);
  bad = mesh.writeMsh("/nonexistent-dir/x.msh");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("cannot open for writing"), std::string::npos);
}

}  // namespace
