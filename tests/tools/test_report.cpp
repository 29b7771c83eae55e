// `graphfrac report error-vs-time` end to end on a small hanging beam: the reference must be
// the converged implicit step (the direct solver with one Newton step differs from it by the
// linearisation error, which shrinks with dt), solvers run to a tight tolerance must agree
// with the direct solver, a starved PCG must not (and must be flagged), the volume gain of a
// hanging beam must stay a fraction of a percent, and every setting rerun on 2 threads must
// give the same bits.
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

using Row = std::map<std::string, std::string>;

std::vector<Row> readRows(const fs::path& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  std::stringstream hs(line);
  for (std::string h; std::getline(hs, h, ',');) header.push_back(h);
  std::vector<Row> rows;
  while (std::getline(in, line)) {
    std::stringstream ls(line);
    Row row;
    size_t i = 0;
    for (std::string v; std::getline(ls, v, ',') && i < header.size(); ++i) row[header[i]] = v;
    rows.push_back(row);
  }
  return rows;
}

int report(std::vector<std::string> args) {
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  return gf::cli::runReportCommand(int(argv.size()), argv.data());
}

const Row& find(const std::vector<Row>& rows, const std::string& setting) {
  for (const Row& r : rows)
    if (r.at("setting") == setting) return r;
  ADD_FAILURE() << "no row " << setting;
  return rows.front();
}

double num(const Row& r, const char* key) { return std::stod(r.at(key)); }

}  // namespace

TEST(Report, ErrorVsTimeRanksSolversAgainstTheConvergedStep) {
  const fs::path dir = fs::temp_directory_path() / "gf_report_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path scene = dir / "beam.json";
  std::ofstream(scene) << R"({"name": "beam", "dt": 0.02, "frames": 6,
    "gravity": [0, -9.81, 0],
    "bodies": [{"name": "beam",
      "mesh": {"generator": "box", "size": [0.6, 0.1, 0.1], "cells": [12, 2, 2]},
      "material": {"model": "stable_neo_hookean", "E": 2e5, "nu": 0.3, "rho": 1000},
      "pins": [{"region": {"min": [0, 0, 0], "max": [0, 0.1, 0.1]}}]}]})";
  const fs::path out = dir / "out";
  ASSERT_EQ(report({"report", "error-vs-time", scene.string(), "--out", out.string(), "--levels",
                    "8/all", "--cycles", "1", "--pcg-caps", "2,500", "--tolerances", "1e-4,1e-2",
                    "--threads", "1", "--compare-threads", "2"}),
            gf::cli::kExitFlagged)
      << "pcg 2 cannot converge, so the run must say a frame was flagged";
  const std::vector<Row> rows = readRows(out / "error_vs_time.csv");
  // reference, direct, pcg 2, pcg 500, 8/all x1, 8/all cg (the default 1e-4), 8/all cg 0.01,
  // 8/all cg smoothed (1e-4)
  ASSERT_EQ(rows.size(), 8u);
  const Row& ref = find(rows, "reference");
  const Row& direct = find(rows, "direct");
  EXPECT_EQ(num(ref, "rel_displacement_error"), 0);
  // One Newton step is not the converged step: a visible, bounded linearisation error.
  const double linearisation = num(direct, "rel_displacement_error");
  EXPECT_GT(linearisation, 1e-6);
  EXPECT_LT(linearisation, 0.2);
  // Converged linear solvers reproduce the direct solver; a starved PCG does not.
  EXPECT_LT(num(find(rows, "pcg 500"), "rel_error_vs_direct"), 1e-4);
  EXPECT_LT(num(find(rows, "8/all cg"), "rel_error_vs_direct"), 1e-4);
  EXPECT_LT(num(find(rows, "8/all cg smoothed"), "rel_error_vs_direct"), 1e-4);
  // A looser tolerance buys fewer iterations with a larger error.
  const Row& loose = find(rows, "8/all cg 0.01");
  EXPECT_GT(num(loose, "rel_error_vs_direct"), num(find(rows, "8/all cg"), "rel_error_vs_direct"));
  EXPECT_LT(num(loose, "linear_iterations_per_frame"),
            num(find(rows, "8/all cg"), "linear_iterations_per_frame"));
  EXPECT_GT(num(find(rows, "pcg 2"), "rel_error_vs_direct"), 1e-3);
  EXPECT_EQ(num(find(rows, "pcg 2"), "ok"), 1);
  EXPECT_GT(num(find(rows, "pcg 2"), "flagged_frames"), 0);
  // One V-cycle per step lies between them.
  const double oneCycle = num(find(rows, "8/all x1"), "rel_error_vs_direct");
  EXPECT_GT(oneCycle, 0);
  EXPECT_LT(oneCycle, num(find(rows, "pcg 2"), "rel_error_vs_direct"));
  for (const Row& r : rows) {
    EXPECT_GT(num(r, "ms_per_frame"), 0) << r.at("setting");
    EXPECT_GT(num(r, "cpu_ms_per_frame"), 0) << r.at("setting");
    // A hanging beam changes its volume by a fraction of a percent, not more.
    EXPECT_LT(std::abs(num(r, "volume_gain_pct")), 1.0) << r.at("setting");
    // Every setting ran again on 2 threads and must have given the same bits.
    if (r.at("setting") != "reference") {
      EXPECT_EQ(num(r, "compare_threads"), 2) << r.at("setting");
      EXPECT_GT(num(r, "ms_per_frame_compare"), 0) << r.at("setting");
      EXPECT_EQ(num(r, "same_bits"), 1) << r.at("setting");
    }
  }
  std::ifstream svg(out / "error_vs_time.svg");
  std::stringstream text;
  text << svg.rdbuf();
  EXPECT_NE(text.str().find("<svg"), std::string::npos);
  EXPECT_NE(text.str().find("8/all cg"), std::string::npos);
}

TEST(Report, BadArgumentsAreUsageErrors) {
  EXPECT_EQ(report({"report"}), gf::cli::kExitUsage);
  EXPECT_EQ(report({"report", "speed"}), gf::cli::kExitUsage);
  EXPECT_EQ(report({"report", "error-vs-time"}), gf::cli::kExitUsage);
  EXPECT_EQ(report({"report", "error-vs-time", "x.json", "--levels", "1000/50/all"}),
            gf::cli::kExitUsage);
  EXPECT_EQ(report({"report", "error-vs-time", "x.json", "--cycles", "0"}), gf::cli::kExitUsage);
  EXPECT_EQ(report({"report", "error-vs-time", "x.json", "--tolerances", "1e-6,0"}),
            gf::cli::kExitUsage);
  EXPECT_EQ(report({"report", "error-vs-time", "x.json", "--smoothed", "2"}), gf::cli::kExitUsage);
  EXPECT_EQ(report({"report", "error-vs-time", "/nonexistent/x.json"}), gf::cli::kExitScene);
}
