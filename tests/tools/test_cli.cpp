// `graphfrac run` end to end: the CSV it writes must hold the physics of a case with a known
// answer (free fall: backward Euler gives v_n = n g dt exactly), and the surface frames must
// be closed meshes of the body's boundary.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "cli/commands.h"

namespace fs = std::filesystem;

namespace {

int run(std::vector<std::string> args) {
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  return gf::cli::runCommand(int(argv.size()), argv.data());
}

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

TEST(Cli, SceneErrorsExitWithCodeTwoAndWriteNothing) {
  const fs::path dir = scratch("bad");
  std::ofstream(dir / "bad.json") << R"({"dt": -1, "frames": 5, "bodies": []})";
  EXPECT_EQ(run({"run", (dir / "bad.json").string(), "--out", (dir / "out").string(), "--quiet"}),
            gf::cli::kExitScene);
  EXPECT_FALSE(fs::exists(dir / "out" / "stats.csv"));
  EXPECT_EQ(run({"run"}), gf::cli::kExitUsage);
  EXPECT_EQ(run({"run", (dir / "missing.json").string(), "--quiet"}), gf::cli::kExitScene);
}

}  // namespace
