// `graphfrac run` end to end: the CSV it writes must hold the physics of a case with a known
// answer (free fall: backward Euler gives v_n = n g dt exactly), and the surface frames must
// be closed meshes of the body's boundary. With fracture: a bar pulled apart and a cylinder
// cut by a plane must end in two pieces, the event log must agree with the CSV edge for edge,
// and the render surface must be closed with its crack faces marked and enclose the body's
// volume.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "cli/commands.h"
#include "common/cli_run.h"
#include "scene/scene.h"

namespace fs = std::filesystem;

namespace {

int run(std::vector<std::string> args) { return gf::test::runCli(std::move(args)); }

std::vector<std::map<std::string, double>> readCsv(const fs::path& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  std::stringstream hs(line);
  for (std::string h; std::getline(hs, h, ',');) header.push_back(h);
  std::vector<std::map<std::string, double>> rows;
  while (std::getline(in, line)) {
    std::stringstream ls(line);
    std::map<std::string, double> row;
    size_t i = 0;
    for (std::string v; std::getline(ls, v, ',') && i < header.size(); ++i)
      row[header[i]] = std::stod(v);
    rows.push_back(row);
  }
  return rows;
}

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("gf_cli_test_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

TEST(Cli, FreeFallCsvMatchesBackwardEuler) {
  const fs::path dir = scratch("fall");
  std::ofstream(dir / "fall.json") << R"({
    "dt": 0.01, "frames": 5, "gravity": [0, -9.81, 0],
    "bodies": [{"name": "cube", "mesh": {"generator": "box", "size": [1, 1, 1], "cells": 2},
                "translate": [0, 2, 0],
                "material": {"model": "stvk", "E": 1e6, "nu": 0.3, "rho": 1000}}]})";
  ASSERT_EQ(run({"run", (dir / "fall.json").string(), "--out", (dir / "out").string(), "--surface",
                 "obj", "--quiet"}),
            gf::cli::kExitOk);
  const auto rows = readCsv(dir / "out" / "stats.csv");
  ASSERT_EQ(rows.size(), 6u);  // frame 0 (initial state) + 5 frames
  // Gravity crosses the API as a float (glm::vec3).
  const double m = 1000.0, g = double(9.81f), dt = 0.01;
  // Gravity energy -m g . x_cm with the centre at y = 2.5.
  EXPECT_NEAR(rows[0].at("gravity_energy"), m * g * 2.5, 1e-9 * m * g * 2.5);
  EXPECT_EQ(rows[0].at("kinetic_energy"), 0.0);
  for (int n = 1; n <= 5; ++n) {
    const double v = n * g * dt;  // a rigid body in free fall does not deform
    EXPECT_NEAR(rows[n].at("kinetic_energy"), 0.5 * m * v * v, 1e-6 * 0.5 * m * v * v) << n;
    EXPECT_NEAR(rows[n].at("time"), n * dt, 1e-12);
    EXPECT_LT(rows[n].at("elastic_energy"), 1e-9);
    EXPECT_EQ(rows[n].at("flags"), 0.0);
  }
  // The last surface frame: the cube's boundary, closed (every edge in exactly two faces,
  // once in each direction).
  std::ifstream obj(dir / "out" / "surface" / "cube_00005.obj");
  ASSERT_TRUE(obj.good());
  int vertices = 0;
  std::map<std::pair<int, int>, int> directedEdges;
  int faces = 0;
  for (std::string line; std::getline(obj, line);) {
    std::stringstream ls(line);
    std::string tag;
    ls >> tag;
    if (tag == "v") ++vertices;
    if (tag != "f") continue;
    ++faces;
    std::vector<int> f;
    for (std::string tok; ls >> tok;) f.push_back(std::stoi(tok.substr(0, tok.find('/'))));
    ASSERT_EQ(f.size(), 3u);
    for (int k = 0; k < 3; ++k) ++directedEdges[{f[k], f[(k + 1) % 3]}];
  }
  EXPECT_EQ(faces, 2 * 2 * (4 + 4 + 4));  // 2x2 cells per side, 2 triangles each
  EXPECT_EQ(vertices, 26);                // 3^3 nodes minus the interior one
  for (const auto& [e, count] : directedEdges) {
    EXPECT_EQ(count, 1);
    EXPECT_EQ(directedEdges.count({e.second, e.first}), 1u);
  }
}

/// A triangle mesh read back from an OBJ frame, with the group of each face.
struct ObjMesh {
  std::vector<std::array<double, 3>> vertices;
  std::vector<std::array<int, 3>> faces;  // 0-based
  std::vector<std::string> groups;        // per face
};

ObjMesh readObj(const fs::path& path) {
  ObjMesh m;
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  std::string group;
  for (std::string line; std::getline(in, line);) {
    std::stringstream ls(line);
    std::string tag;
    ls >> tag;
    if (tag == "v") {
      std::array<double, 3> p{};
      ls >> p[0] >> p[1] >> p[2];
      m.vertices.push_back(p);
    } else if (tag == "g") {
      ls >> group;
    } else if (tag == "f") {
      std::array<int, 3> f{};
      for (int& i : f) {
        std::string tok;
        ls >> tok;
        i = std::stoi(tok.substr(0, tok.find('/'))) - 1;
      }
      m.faces.push_back(f);
      m.groups.push_back(group);
    }
  }
  return m;
}

/// True when every directed edge appears once and its reverse once: closed, 2-manifold along
/// edges and consistently oriented.
bool closedAndOriented(const ObjMesh& m) {
  std::map<std::pair<int, int>, int> directed;
  for (const auto& f : m.faces) {
    for (int k = 0; k < 3; ++k) ++directed[{f[k], f[(k + 1) % 3]}];
  }
  for (const auto& [e, count] : directed) {
    if (count != 1) return false;
    const auto back = directed.find({e.second, e.first});
    if (back == directed.end() || back->second != 1) return false;
  }
  return true;
}

/// Signed volumes of the connected pieces of a closed mesh (divergence theorem), largest first.
std::vector<double> pieceVolumes(const ObjMesh& m) {
  std::vector<int> parent(m.vertices.size());
  for (size_t i = 0; i < parent.size(); ++i) parent[i] = int(i);
  auto find = [&](int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (const auto& f : m.faces) {
    parent[find(f[1])] = find(f[0]);
    parent[find(f[2])] = find(f[0]);
  }
  std::map<int, double> volume;
  for (const auto& f : m.faces) {
    const auto& a = m.vertices[f[0]];
    const auto& b = m.vertices[f[1]];
    const auto& c = m.vertices[f[2]];
    volume[find(f[0])] += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
                           a[2] * (b[0] * c[1] - b[1] * c[0])) /
                          6;
  }
  std::vector<double> out;
  for (const auto& [root, v] : volume) out.push_back(v);
  std::sort(out.rbegin(), out.rend());
  return out;
}

/// Rows of the event log as strings (it holds names and causes).
std::vector<std::vector<std::string>> readEvents(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::vector<std::string>> rows;
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "frame,body,edge,nodeA,nodeB,x,y,z,stress,cause");
  while (std::getline(in, line)) {
    std::vector<std::string> row;
    std::stringstream ls(line);
    for (std::string v; std::getline(ls, v, ',');) row.push_back(v);
    EXPECT_EQ(row.size(), 10u) << line;
    rows.push_back(row);
  }
  return rows;
}

/// Checks that the event log and the CSV agree: each edge reported once, and the events up to
/// frame n add up to the CSV's broken_edges of frame n.
void expectEventsMatchCsv(const std::vector<std::vector<std::string>>& events,
                          const std::vector<std::map<std::string, double>>& rows,
                          const std::set<std::string>& causes) {
  std::set<int> edges;
  std::map<int, int> perFrame;
  for (const auto& e : events) {
    EXPECT_TRUE(edges.insert(std::stoi(e[2])).second) << "edge " << e[2] << " reported twice";
    EXPECT_TRUE(causes.count(e[9]) != 0) << e[9];
    ++perFrame[std::stoi(e[0])];
  }
  int cumulative = 0;
  for (const auto& row : rows) {
    cumulative += perFrame[int(row.at("frame"))];
    EXPECT_EQ(row.at("broken_edges"), cumulative) << "frame " << row.at("frame");
  }
}

/// A VTK XML UnstructuredGrid read back: its counts and every named DataArray.
struct Vtu {
  size_t points = 0, cells = 0;
  std::map<std::string, std::vector<double>> arrays;
};

Vtu readVtu(const fs::path& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  Vtu v;
  EXPECT_EQ(std::sscanf(text.c_str() + text.find("<Piece"),
                        "<Piece NumberOfPoints=\"%zu\" NumberOfCells=\"%zu\"", &v.points, &v.cells),
            2);
  for (size_t at = text.find("<DataArray"); at != std::string::npos;
       at = text.find("<DataArray", at + 1)) {
    const size_t name = text.find("Name=\"", at) + 6;
    const size_t open = text.find('>', at) + 1;
    const size_t close = text.find("</DataArray>", open);
    std::stringstream values(text.substr(open, close - open));
    std::vector<double>& a = v.arrays[text.substr(name, text.find('"', name) - name)];
    for (double x; values >> x;) a.push_back(x);
  }
  EXPECT_NE(text.find("</VTKFile>"), std::string::npos) << path << " is cut short";
  return v;
}

TEST(Cli, BarPulledApartEndsInTwoClosedPieces) {
  // A V-notched bar (brittle mode, one crack region) pulled at both ends: the stress peaks at
  // the notch tip and one crack plane runs from there through the section.
  const fs::path dir = scratch("bar");
  std::ofstream(dir / "bar.json") << R"({
    "dt": 0.01, "frames": 80, "gravity": [0, 0, 0],
    "bodies": [{"name": "bar",
      "mesh": {"generator": "box", "size": [0.4, 0.1, 0.1], "cells": [16, 4, 2],
               "notch": {"depth": 0.05, "angle_deg": 60}},
      "material": {"model": "stable_neo_hookean", "E": 1e5, "nu": 0.3, "rho": 1000},
      "fracture": {"strength": 2e4, "brittle": true},
      "grips": [
        {"region": {"min": [0, 0, 0], "max": [0, 0.1, 0.1]}, "velocity": [-0.2, 0, 0]},
        {"region": {"min": [0.4, 0, 0], "max": [0.4, 0.1, 0.1]}, "velocity": [0.2, 0, 0]}]}]})";
  ASSERT_EQ(run({"run", (dir / "bar.json").string(), "--out", (dir / "out").string(), "--surface",
                 "obj", "--surface-every", "80", "--vtk", "--vtk-every", "80", "--events",
                 (dir / "events.csv").string(), "--quiet"}),
            gf::cli::kExitOk);
  const auto rows = readCsv(dir / "out" / "stats.csv");
  ASSERT_EQ(rows.size(), 81u);
  EXPECT_EQ(rows.front().at("broken_edges"), 0);
  EXPECT_EQ(rows.front().at("fragments"), 1);
  EXPECT_GT(rows.back().at("broken_edges"), 0);
  EXPECT_EQ(rows.back().at("fragments"), 2);
  for (size_t i = 1; i < rows.size(); ++i) {
    EXPECT_GE(rows[i].at("broken_edges"), rows[i - 1].at("broken_edges")) << "edges healed";
    EXPECT_GE(rows[i].at("ms_fracture"), 0);
  }
  const auto events = readEvents(dir / "events.csv");
  expectEventsMatchCsv(events, rows, {"stress", "brittle"});

  // The field file of the last frame: a node is damaged exactly when one of its edges broke
  // (the event log names both nodes of every broken edge), and the fragment ids split the
  // nodes in two.
  const Vtu vtu = readVtu(dir / "out" / "vtk" / "bar_00080.vtu");
  std::set<int> brokenNodes;
  for (const auto& e : events) brokenNodes.insert({std::stoi(e[3]), std::stoi(e[4])});
  const std::vector<double>& damage = vtu.arrays.at("damage");
  ASSERT_EQ(damage.size(), vtu.points);
  for (size_t n = 0; n < damage.size(); ++n) {
    EXPECT_EQ(damage[n] > 0, brokenNodes.count(int(n)) != 0) << "node " << n;
    EXPECT_LE(damage[n], 1.0);
  }
  const std::vector<double>& fragment = vtu.arrays.at("fragment");
  EXPECT_EQ(std::set<double>(fragment.begin(), fragment.end()), (std::set<double>{0, 1}));

  // Frame 0: no crack group yet. Last frame: crack faces in their own group, every edge used
  // twice (once per direction), and two solid pieces whose volumes add up to the bar's
  // (0.4 x 0.1 x 0.1 less the notch, d^2 tan 30deg x 0.1); a crack inside a piece may add a
  // closed zero-volume slit, which is no piece.
  const ObjMesh first = readObj(dir / "out" / "surface" / "bar_00000.obj");
  EXPECT_EQ(std::count(first.groups.begin(), first.groups.end(), "crack"), 0);
  const ObjMesh last = readObj(dir / "out" / "surface" / "bar_00080.obj");
  EXPECT_GT(std::count(last.groups.begin(), last.groups.end(), "crack"), 0);
  EXPECT_GT(std::count(last.groups.begin(), last.groups.end(), "surface"), 0);
  EXPECT_TRUE(closedAndOriented(last));
  const double volume = 0.4 * 0.1 * 0.1 - 0.05 * 0.05 * std::tan(std::numbers::pi / 6) * 0.1;
  std::vector<double> pieces = pieceVolumes(last);
  std::erase_if(pieces, [&](double v) { return std::abs(v) < 1e-6 * volume; });
  ASSERT_EQ(pieces.size(), 2u);
  EXPECT_GT(pieces[1], 0.2 * volume);  // two real halves, not a chip
  EXPECT_NEAR(pieces[0] + pieces[1], volume, 0.01 * volume);
}

/// Reads a binary little/big-endian PLY frame of the render surface (the host's order).
struct PlyMesh {
  std::vector<int32_t> vertexFragment;
  std::vector<std::array<int32_t, 3>> faces;
  std::vector<std::array<uint8_t, 3>> colours;
};

PlyMesh readPly(const fs::path& path) {
  PlyMesh m;
  std::ifstream in(path, std::ios::binary);
  size_t nv = 0, nf = 0;
  std::string header;
  for (std::string line; std::getline(in, line) && line != "end_header";) {
    header += line + "\n";
    std::sscanf(line.c_str(), "element vertex %zu", &nv);
    std::sscanf(line.c_str(), "element face %zu", &nf);
  }
  EXPECT_NE(header.find("property int fragment"), std::string::npos) << header;
  EXPECT_NE(header.find("property uchar red"), std::string::npos) << header;
  for (size_t i = 0; i < nv; ++i) {
    char buf[7 * 4];
    in.read(buf, sizeof buf);
    int32_t fragment = 0;
    std::memcpy(&fragment, buf + 6 * 4, 4);
    m.vertexFragment.push_back(fragment);
  }
  for (size_t i = 0; i < nf; ++i) {
    char buf[1 + 12 + 3];
    in.read(buf, sizeof buf);
    EXPECT_EQ(buf[0], 3);
    std::array<int32_t, 3> f{};
    std::memcpy(f.data(), buf + 1, 12);
    std::array<uint8_t, 3> c{};
    std::memcpy(c.data(), buf + 13, 3);
    m.faces.push_back(f);
    m.colours.push_back(c);
  }
  EXPECT_TRUE(in.good()) << path << " is shorter than its header says";
  return m;
}

TEST(Cli, PlanarCutSplitsACylinderInTwo) {
  // The strength is far above anything the (weightless, still) cylinder feels: only the cut,
  // applied before frame 2 at y = 0.13 (between node layers), breaks edges.
  const fs::path dir = scratch("cut");
  std::ofstream(dir / "cut.json") << R"({
    "dt": 0.01, "frames": 3, "gravity": [0, 0, 0],
    "bodies": [{"name": "cyl",
      "mesh": {"generator": "cylinder", "radius": 0.1, "height": 0.3, "segments": 12,
               "rings": 2, "layers": 6},
      "material": {"E": 1e6, "nu": 0.3, "rho": 1000},
      "fracture": {"strength": 1e12}}],
    "cuts": [{"frame": 2, "body": "cyl",
              "blade": {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "size": 0.5},
              "from": {"translate": [0, 0.13, 0]}}]})";
  for (const char* format : {"obj", "ply"}) {
    ASSERT_EQ(run({"run", (dir / "cut.json").string(), "--out", (dir / format).string(),
                   "--surface", format, "--events", (dir / "events.csv").string(), "--quiet"}),
              gf::cli::kExitOk)
        << format;
  }
  const auto rows = readCsv(dir / "obj" / "stats.csv");
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[1].at("fragments"), 1);
  EXPECT_EQ(rows[1].at("broken_edges"), 0);
  EXPECT_EQ(rows[2].at("fragments"), 2);
  EXPECT_GT(rows[2].at("broken_edges"), 0);
  EXPECT_EQ(rows[3].at("broken_edges"), rows[2].at("broken_edges"));
  const auto events = readEvents(dir / "events.csv");
  expectEventsMatchCsv(events, rows, {"cut"});
  for (const auto& e : events) {
    EXPECT_EQ(e[0], "2");
    EXPECT_EQ(e[1], "cyl");
    EXPECT_EQ(std::stod(e[8]), 0.0);  // a cut carries no stress
    // The break lies on an edge that straddles the blade: between the node layers y = 0.10
    // and y = 0.15.
    EXPECT_GT(std::stod(e[6]), 0.1 - 1e-6);
    EXPECT_LT(std::stod(e[6]), 0.15 + 1e-6);
  }

  // The two pieces are closed and together enclose the whole cylinder (a 12-gon prism).
  const ObjMesh obj = readObj(dir / "obj" / "surface" / "cyl_00003.obj");
  EXPECT_TRUE(closedAndOriented(obj));
  const double volume = 0.5 * 12 * 0.01 * std::sin(2 * std::numbers::pi / 12) * 0.3;
  std::vector<double> pieces = pieceVolumes(obj);
  std::erase_if(pieces, [&](double v) { return std::abs(v) < 1e-6 * volume; });
  ASSERT_EQ(pieces.size(), 2u);
  EXPECT_NEAR(pieces[0] + pieces[1], volume, 1e-3 * volume);

  // The PLY of the same frame: as many red faces as the OBJ has crack faces, and the crack
  // faces' vertices belong to two fragments.
  const PlyMesh ply = readPly(dir / "ply" / "surface" / "cyl_00003.ply");
  ASSERT_EQ(ply.faces.size(), obj.faces.size());
  size_t red = 0;
  std::set<int32_t> crackFragments;
  for (size_t i = 0; i < ply.faces.size(); ++i) {
    const std::array<uint8_t, 3> kRed{214, 64, 44}, kGrey{200, 200, 200};
    const bool crack = ply.colours[i] == kRed;
    EXPECT_TRUE(crack || ply.colours[i] == kGrey);
    if (!crack) continue;
    ++red;
    for (int32_t v : ply.faces[i]) crackFragments.insert(ply.vertexFragment.at(v));
  }
  EXPECT_EQ(red, size_t(std::count(obj.groups.begin(), obj.groups.end(), "crack")));
  EXPECT_GT(red, 0u);
  EXPECT_EQ(crackFragments.size(), 2u);
}

TEST(Cli, VtkFieldsHoldTheFreeFallDisplacement) {
  // Backward Euler free fall from rest: v_n = -n g dt, so x_n - X = -g dt^2 n (n + 1) / 2 for
  // every node, and the body does not deform.
  const fs::path dir = scratch("vtk");
  std::ofstream(dir / "fall.json") << R"({
    "dt": 0.01, "frames": 4, "gravity": [0, -9.81, 0],
    "bodies": [{"name": "cube", "mesh": {"generator": "box", "size": [1, 1, 1], "cells": 2},
                "material": {"model": "stvk", "E": 1e6, "nu": 0.3, "rho": 1000}}]})";
  ASSERT_EQ(run({"run", (dir / "fall.json").string(), "--out", (dir / "out").string(), "--vtk",
                 "--vtk-every", "3", "--quiet"}),
            gf::cli::kExitOk);
  EXPECT_FALSE(fs::exists(dir / "out" / "vtk" / "cube_00001.vtu"));  // every 3rd frame only
  const Vtu vtu = readVtu(dir / "out" / "vtk" / "cube_00003.vtu");
  EXPECT_EQ(vtu.points, 27u);
  EXPECT_EQ(vtu.cells, 8u * 6);
  const double g = double(9.81f), dt = 0.01, dy = -g * dt * dt * 3 * 4 / 2;
  const std::vector<double>& u = vtu.arrays.at("displacement");
  ASSERT_EQ(u.size(), 3 * vtu.points);
  for (size_t n = 0; n < vtu.points; ++n) {
    EXPECT_NEAR(u[3 * n], 0, 1e-9) << n;
    EXPECT_NEAR(u[3 * n + 1], dy, 1e-6 * std::abs(dy)) << n;
    EXPECT_NEAR(u[3 * n + 2], 0, 1e-9) << n;
  }
  // Points are the current positions: the rest grid moved by the displacement.
  const std::vector<double>& x = vtu.arrays.at("points");
  ASSERT_EQ(x.size(), 3 * vtu.points);
  for (size_t n = 0; n < vtu.points; ++n) {
    const double restY = x[3 * n + 1] - u[3 * n + 1];
    EXPECT_NEAR(restY * 2, std::round(restY * 2), 1e-9) << n;  // y in {0, 0.5, 1}
  }
  EXPECT_EQ(vtu.arrays.at("connectivity").size(), 4 * vtu.cells);
  EXPECT_EQ(vtu.arrays.at("types"), std::vector<double>(vtu.cells, 10.0));  // VTK_TETRA
  EXPECT_EQ(vtu.arrays.at("strain").size(), vtu.points);
  for (double e : vtu.arrays.at("strain")) EXPECT_NEAR(e, 0, 1e-9);
  for (double d : vtu.arrays.at("damage")) EXPECT_EQ(d, 0);  // no fracture

  // The collection lists frames 0 and 3 at their times, with files that exist.
  std::ifstream pvd(dir / "out" / "fields.pvd");
  std::vector<std::pair<double, std::string>> sets;
  for (std::string line; std::getline(pvd, line);) {
    double t = 0;
    char file[256] = {};
    if (std::sscanf(line.c_str(),
                    " <DataSet timestep=\"%lf\" group=\"\" part=\"0\" file=\"%255[^\"]", &t,
                    file) == 2)
      sets.emplace_back(t, file);
  }
  ASSERT_EQ(sets.size(), 2u);
  EXPECT_EQ(sets[0].first, 0.0);
  EXPECT_NEAR(sets[1].first, 0.03, 1e-12);
  EXPECT_EQ(sets[1].second, "vtk/cube_00003.vtu");
  for (const auto& [t, file] : sets) EXPECT_TRUE(fs::exists(dir / "out" / file)) << file;
}

/// Rows of a CSV with text columns, by column name.
std::vector<std::map<std::string, std::string>> readCsvText(const fs::path& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  std::stringstream hs(line);
  for (std::string h; std::getline(hs, h, ',');) header.push_back(h);
  std::vector<std::map<std::string, std::string>> rows;
  while (std::getline(in, line)) {
    std::stringstream ls(line);
    std::map<std::string, std::string> row;
    size_t i = 0;
    for (std::string v; std::getline(ls, v, ',') && i < header.size(); ++i) row[header[i]] = v;
    rows.push_back(row);
  }
  return rows;
}

TEST(Cli, PinnedGripCarriesTheWeightOfAHangingBar) {
  // A bar hanging from a pin at its top face, damped so that it settles: at rest the pin
  // holds the whole weight, m g upwards (the pinned nodes' own weight included).
  const fs::path dir = scratch("hang");
  std::ofstream(dir / "hang.json") << R"({
    "dt": 0.01, "frames": 150, "gravity": [0, -9.81, 0],
    "bodies": [{"name": "bar", "mesh": {"generator": "box", "size": [0.1, 0.5, 0.1],
                                        "cells": [2, 10, 2]},
                "material": {"E": 1e6, "nu": 0.3, "rho": 1000, "damping": {"mass": 20}},
                "pins": [{"region": {"min": [0, 0.5, 0], "max": [0.1, 0.5, 0.1]}}]}]})";
  ASSERT_EQ(run({"run", (dir / "hang.json").string(), "--out", (dir / "out").string(), "--quiet"}),
            gf::cli::kExitOk);
  EXPECT_FALSE(fs::exists(dir / "out" / "colliders.csv"));  // the scene has none
  const auto rows = readCsvText(dir / "out" / "grips.csv");
  ASSERT_EQ(rows.size(), 150u);  // one grip, frames 1..150
  const auto& last = rows.back();
  EXPECT_EQ(last.at("frame"), "150");
  EXPECT_EQ(last.at("body"), "bar");
  EXPECT_EQ(last.at("grip"), "pins[0]");
  const double weight = 1000 * 0.1 * 0.5 * 0.1 * double(9.81f);
  EXPECT_NEAR(std::stod(last.at("fy")), weight, 0.02 * weight);
  EXPECT_NEAR(std::stod(last.at("fx")), 0, 1e-3 * weight);
  EXPECT_NEAR(std::stod(last.at("fz")), 0, 1e-3 * weight);
}

TEST(Cli, RestingBlockReportsContactEnergyAndColliderImpulse) {
  // A block dropped a little onto a plane and damped to rest: the plane's impulse per frame
  // settles at m g dt upwards, its penalty energy shows in contact_energy, and total_energy
  // is the sum of the four energies.
  const fs::path dir = scratch("rest");
  std::ofstream(dir / "rest.json") << R"({
    "dt": 0.01, "frames": 200, "gravity": [0, -9.81, 0],
    "colliders": [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0]}],
    "bodies": [{"name": "block", "mesh": {"generator": "box", "size": [0.2, 0.2, 0.2],
                                          "cells": 2},
                "translate": [-0.1, 0.01, -0.1],
                "material": {"E": 1e6, "nu": 0.3, "rho": 1000, "damping": {"mass": 10}}}]})";
  ASSERT_EQ(run({"run", (dir / "rest.json").string(), "--out", (dir / "out").string(), "--quiet"}),
            gf::cli::kExitOk);
  EXPECT_FALSE(fs::exists(dir / "out" / "grips.csv"));  // no grips
  const auto stats = readCsv(dir / "out" / "stats.csv");
  ASSERT_EQ(stats.size(), 201u);
  EXPECT_EQ(stats.front().at("contact_energy"), 0.0);  // not touching yet
  EXPECT_GT(stats.back().at("contact_energy"), 0.0);
  for (const auto& row : stats) {
    const double sum = row.at("kinetic_energy") + row.at("elastic_energy") +
                       row.at("gravity_energy") + row.at("contact_energy");
    EXPECT_NEAR(row.at("total_energy"), sum, 1e-8 * (std::abs(sum) + 1)) << row.at("frame");
  }
  const auto rows = readCsvText(dir / "out" / "colliders.csv");
  ASSERT_EQ(rows.size(), 200u);  // one collider, frames 1..200
  const auto& last = rows.back();
  EXPECT_EQ(last.at("collider"), "0");
  const double weight = 1000 * 0.2 * 0.2 * 0.2 * double(9.81f);
  EXPECT_NEAR(std::stod(last.at("jy")), weight * 0.01, 0.02 * weight * 0.01);
  EXPECT_NEAR(std::stod(last.at("jx")), 0, 1e-3 * weight * 0.01);
  // Centred on the plane's point: the moment of a symmetric load about it is zero.
  EXPECT_NEAR(std::stod(last.at("ax")), 0, 1e-3 * weight * 0.01);
  EXPECT_NEAR(std::stod(last.at("az")), 0, 1e-3 * weight * 0.01);
}

TEST(Cli, RunStartsBodiesInTheSceneInitialState) {
  // angular_velocity and initial_deformation reach the world through scene::addBody: frame 0
  // of stats.csv has the spin's kinetic energy and the stretch's elastic energy.
  const fs::path dir = scratch("spin");
  const std::string text = R"({
    "dt": 0.01, "frames": 1, "gravity": [0, 0, 0],
    "bodies": [{"name": "cube", "mesh": {"generator": "box", "size": [1, 1, 1], "cells": 2},
                "angular_velocity": [0, 0, 3],
                "initial_deformation": [[1.01, 0, 0], [0, 1, 0], [0, 0, 1]],
                "material": {"model": "stvk", "E": 1e6, "nu": 0.3, "rho": 1000}}]})";
  std::ofstream(dir / "spin.json") << text;
  ASSERT_EQ(run({"run", (dir / "spin.json").string(), "--out", (dir / "out").string(), "--quiet"}),
            gf::cli::kExitOk);
  const auto rows = readCsv(dir / "out" / "stats.csv");
  ASSERT_EQ(rows.size(), 2u);
  const gf::Result<gf::scene::Scene> sc = gf::scene::parseScene(text, "spin", "");
  ASSERT_TRUE(sc.ok()) << sc.error().message;
  gf::World world(sc.value().world);
  const gf::Result<gf::BodyId> id = gf::scene::addBody(world, sc.value().bodies[0]);
  ASSERT_TRUE(id.ok()) << id.error().message;
  const gf::BodyStats s = world.stats(id.value());
  EXPECT_GT(s.kineticEnergy, 0.1);
  EXPECT_GT(s.elasticEnergy, 1.0);
  EXPECT_NEAR(rows[0].at("kinetic_energy"), s.kineticEnergy, 1e-9 * s.kineticEnergy);
  EXPECT_NEAR(rows[0].at("elastic_energy"), s.elasticEnergy, 1e-9 * s.elasticEnergy);
}

TEST(Cli, SceneErrorsExitWithCodeTwoAndWriteNothing) {
  const fs::path dir = scratch("bad");
  std::ofstream(dir / "bad.json") << R"({"dt": -1, "frames": 5, "bodies": []})";
  EXPECT_EQ(run({"run", (dir / "bad.json").string(), "--out", (dir / "out").string(), "--quiet"}),
            gf::cli::kExitScene);
  EXPECT_FALSE(fs::exists(dir / "out" / "stats.csv"));
  EXPECT_EQ(run({"run"}), gf::cli::kExitUsage);
  EXPECT_EQ(run({"run", (dir / "missing.json").string(), "--quiet"}), gf::cli::kExitScene);
  // A scene with Bullet rigid bodies is refused rather than run without them.
  const std::string bullet = std::string(GF_SOURCE_DIR) + "/scenes/bunny_bullet.json";
  EXPECT_EQ(run({"run", bullet, "--out", (dir / "out2").string(), "--quiet"}), gf::cli::kExitScene);
  EXPECT_FALSE(fs::exists(dir / "out2" / "stats.csv"));
}

// --backend overrides the scene's "backend": a backend that cannot run is a scene error that
// writes nothing (no device step in this version), an unknown one a usage error.
TEST(Cli, BackendOptionOverridesTheScene) {
  const fs::path dir = scratch("backend");
  std::ofstream(dir / "box.json") << R"({"dt": 0.01, "frames": 2, "backend": "cpu",
    "bodies": [{"mesh": {"generator": "box", "size": [0.1, 0.1, 0.1], "cells": 1},
                "material": {"E": 1e6, "nu": 0.3, "rho": 1000}}]})";
  const std::string scene = (dir / "box.json").string();
  EXPECT_EQ(run({"run", scene, "--backend", "gpu"}), gf::cli::kExitUsage);
  testing::internal::CaptureStderr();
  EXPECT_EQ(run({"run", scene, "--out", (dir / "cuda").string(), "--backend", "cuda", "--quiet"}),
            gf::cli::kExitScene);
  const std::string error = testing::internal::GetCapturedStderr();
  EXPECT_NE(error.find("WorldDef.backend: Cuda cannot run: "), std::string::npos) << error;
  EXPECT_FALSE(fs::exists(dir / "cuda" / "stats.csv"));
  EXPECT_EQ(run({"run", scene, "--out", (dir / "auto").string(), "--backend=auto", "--quiet"}),
            gf::cli::kExitOk);
  EXPECT_TRUE(fs::exists(dir / "auto" / "stats.csv"));
}

// The benchmark modes share one case list; an --only that names no case of the mode is a usage
// error listing the mode's cases, before any world is built (the 680k box is `bench scenes`'s
// alone).
TEST(Cli, BenchOnlyNamingNoCaseIsAUsageError) {
  testing::internal::CaptureStderr();
  EXPECT_EQ(run({"bench", "multigrid", "--only", "box 680k"}), gf::cli::kExitUsage);
  EXPECT_EQ(run({"bench", "scenes", "--only", "charpy"}), gf::cli::kExitUsage);
  const std::string error = testing::internal::GetCapturedStderr();
  EXPECT_NE(error.find("bench multigrid: --only 'box 680k' is none of the cases: 'hinged beam', "
                       "'charpy bar', 'hanging sphere', 'sphere 160k'\n"),
            std::string::npos)
      << error;
  EXPECT_NE(error.find("bench scenes: --only 'charpy' is none of the cases: 'hinged beam', 'charpy "
                       "bar', 'hanging sphere', 'sphere 160k', 'box 680k'\n"),
            std::string::npos)
      << error;
}

// Every bench mode checks its command line before it builds a world: an unknown option, a
// missing value, a value that is not a number or is out of range is a usage error naming the
// option, and nothing runs (stdout holds at most the backend line). Each case starts with the
// mode's cheapest valid options, so a parser that ignores the bad one runs a short benchmark
// and fails here on the exit code rather than running for minutes.
TEST(Cli, BenchOptionsAreChecked) {
  const std::string scene = std::string(GF_SOURCE_DIR) + "/tests/data/scenes/good/minimal.json";
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"fracture", "--cells", "4", "--steps", "1", "--cell", "8"},
       "bench fracture: unknown option '--cell'"},
      {{"fracture", "--cells", "4", "--steps", "abc"}, "bench fracture: --steps needs"},
      {{"fracture", "--steps", "1", "--cells", "3"}, "bench fracture: --cells needs"},
      {{"multigrid", "--only", "hinged beam", "--frames", "1", "--threads", "1", "--pcg", "0",
        "--frame", "2"},
       "bench multigrid: unknown option '--frame'"},
      {{"multigrid", "--only", "hinged beam", "--frames", "1", "--pcg", "0", "--threads", "1,x"},
       "bench multigrid: --threads needs"},
      {{"multigrid", "--only", "hinged beam", "--frames", "1", "--threads", "1", "--pcg", "yes"},
       "bench multigrid: --pcg needs"},
      {{"overhead", "--cells", "4", "--steps", "1", "--rounds", "1", "--round", "2"},
       "bench overhead: unknown option '--round'"},
      {{"overhead", "--cells", "4", "--steps", "1", "--rounds", "0"},
       "bench overhead: --rounds needs"},
      {{"options", "--cells", "2", "--rounds", "1", "--steps"}, "bench options: --steps needs"},
      {{"options", "--steps", "1", "--rounds", "1", "--cells", "2x"},
       "bench options: --cells needs"},
      {{"stages", "--scene", scene, "--frames", "1", "--scenes", "x"},
       "bench stages: unknown option '--scenes'"},
      {{"stages", "--scene", scene, "--frames", "1", "--threads", "1,x"},
       "bench stages: --threads needs"},
      {{"stages", "--scene", scene, "--frames", "1", "--threads", "-1"},
       "bench stages: --threads needs"},
      {{"stages", "--scene", scene, "--frames", "0"}, "bench stages: --frames needs"},
      {{"debris", "--frames", "1", "--rounds", "1", "--frams", "2"},
       "bench debris: unknown option '--frams'"},
      {{"debris", "--rounds", "1", "--frames", "1.5"}, "bench debris: --frames needs"},
      {{"contact", "--cells", "1", "--frames", "1", "--rounds", "1", "--cell", "2"},
       "bench contact: unknown option '--cell'"},
      {{"contact", "--cells", "1", "--frames", "1", "--rounds", "1", "--threads", "0"},
       "bench contact: --threads needs"},
      {{"xfem", "--cells", "4", "--steps", "1", "--step", "2"},
       "bench xfem: unknown option '--step'"},
      {{"xfem", "--steps", "1", "--cells", "abc"}, "bench xfem: --cells needs"},
      {{"haptic", "--cells", "2", "--steps", "1", "--frames", "2"},
       "bench haptic: unknown option '--frames'"},
      {{"haptic", "--steps", "1", "--cells", "1"}, "bench haptic: --cells needs"},
      {{"peer", "--cells", "1", "--seconds", "0.01", "--no-sweep", "--sweep"},
       "bench peer: unknown option '--sweep'"},
      {{"peer", "--seconds", "0.01", "--no-sweep", "--cells", "17"}, "bench peer: --cells needs"},
      {{"fragments", "--cells", "2", "--rounds", "1", "--cell", "4"},
       "bench fragments: unknown option '--cell'"},
      {{"fragments", "--cells", "2", "--rounds", "1", "--threads", "0"},
       "bench fragments: --threads needs"},
      {{"scenes", "--only", "hinged beam", "--frames", "1", "--reference", "0", "--frame", "2"},
       "bench scenes: unknown option '--frame'"},
      {{"scenes", "--only", "hinged beam", "--frames", "1", "--reference", "2"},
       "bench scenes: --reference needs"},
  };
  for (const auto& [args, message] : cases) {
    std::vector<std::string> argv = {"bench"};
    argv.insert(argv.end(), args.begin(), args.end());
    testing::internal::CaptureStdout();
    testing::internal::CaptureStderr();
    const int code = run(argv);
    const std::string out = testing::internal::GetCapturedStdout();
    const std::string error = testing::internal::GetCapturedStderr();
    EXPECT_EQ(code, gf::cli::kExitUsage) << message;
    EXPECT_NE(error.find(message), std::string::npos) << error;
    EXPECT_LE(std::count(out.begin(), out.end(), '\n'), 1) << message << ":\n" << out;
  }
}

// `bench stages --threads 1,2` runs every scene at each thread count in one process: one row per
// scene and count. --backend=cpu: the joined spelling, which `bench` takes out before the mode.
TEST(Cli, BenchStagesTakesAThreadList) {
  const std::string scene = std::string(GF_SOURCE_DIR) + "/tests/data/scenes/good/minimal.json";
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  const int code = run(
      {"bench", "stages", "--scene", scene, "--frames", "2", "--threads", "1,2", "--backend=cpu"});
  const std::string out = testing::internal::GetCapturedStdout();
  const std::string error = testing::internal::GetCapturedStderr();
  if (code == gf::cli::kExitScene && error.find("without Bullet") != std::string::npos)
    GTEST_SKIP() << "built without Bullet";
  ASSERT_EQ(code, gf::cli::kExitOk) << error;
  std::vector<std::string> threads;
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);) {
    if (line.empty() || line[0] == '#' || line.rfind("scene,", 0) == 0) continue;
    std::vector<std::string> fields;
    std::stringstream fs(line);
    for (std::string f; std::getline(fs, f, ',');) fields.push_back(f);
    ASSERT_GE(fields.size(), 4u) << line;
    EXPECT_EQ(fields[3], "2") << line;  // frames
    threads.push_back(fields[2]);
  }
  EXPECT_EQ(threads, (std::vector<std::string>{"1", "2"})) << out;
}

}  // namespace
