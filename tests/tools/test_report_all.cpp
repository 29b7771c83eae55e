// `graphfrac report all` (tools/cli/report_all.cpp) on a small page with every marker pair:
// the quick form must fill each generated region with a table of finite numbers, leave every
// hand-written byte outside the markers as it was (checked by a splitter written here, not the
// tool's), write the plots it links, and give each thesis ratio as its two columns' quotient. A
// page with a missing, unknown or nested marker is an error that names the region and leaves
// the file as it was.
#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "cli/results_regions.h"
#include "common/cli_run.h"
#include "common/temp_dir.h"

namespace fs = std::filesystem;

namespace {

const std::vector<std::string> kRegions = {
    "header",        "thesis", "lab-brazilian", "lab-charpy", "lab-izod",  "lab-acceptance",
    "error-vs-time", "bench",  "bench-scenes",  "stability",  "peer-time", "peer-range"};

int reportAll(std::vector<std::string> args) {
  args.insert(args.begin(), {"report", "all"});
  return gf::test::runCli(args);
}

std::string read(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void write(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary) << text;
}

// A page with hand-written text around every region, a CRLF line, and old region bodies.
std::string page(const std::string& skipEndOf = "") {
  std::string s = "# Results\n\nHand-written intro, regenerate with `graphfrac report all`.\r\n";
  for (const std::string& r : kRegions) {
    s += "\n## " + r + "\n\nProse before " + r + " | with a pipe.\n";
    s += "<!-- report:" + r + ":begin -->\n| old | table |\n|---|---|\n| 1 | 2 |\n";
    if (r != skipEndOf) s += "<!-- report:" + r + ":end -->\n";
    s += "Prose after " + r + ", 3.5 kN.\n";
  }
  return s + "Last line without a line break";
}

// The page with each region's body cut out, by plain search (independent of the tool's parser).
std::string skeleton(const std::string& text) {
  std::string s = text;
  for (const std::string& r : kRegions) {
    const std::string begin = "<!-- report:" + r + ":begin -->\n",
                      end = "<!-- report:" + r + ":end -->";
    const size_t b = s.find(begin), e = s.find(end);
    if (b == std::string::npos || e == std::string::npos || e < b) continue;
    s.erase(b + begin.size(), e - (b + begin.size()));
  }
  return s;
}

std::string body(const std::string& text, const std::string& region) {
  const std::string begin = "<!-- report:" + region + ":begin -->\n",
                    end = "<!-- report:" + region + ":end -->";
  const size_t b = text.find(begin), e = text.find(end);
  if (b == std::string::npos || e == std::string::npos || e < b) return {};
  return text.substr(b + begin.size(), e - (b + begin.size()));
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  for (std::string l; std::getline(ss, l);) out.push_back(l);
  return out;
}

std::vector<std::string> cells(const std::string& row) {
  std::vector<std::string> out;
  std::stringstream ss(row.substr(1));
  for (std::string c; std::getline(ss, c, '|');) {
    const size_t a = c.find_first_not_of(' '), z = c.find_last_not_of(' ');
    out.push_back(a == std::string::npos ? std::string() : c.substr(a, z - a + 1));
  }
  return out;
}

// Every number written in a cell must be finite, and no cell may say nan or inf.
void expectFiniteNumbers(const std::string& region, const std::string& cell) {
  std::string lower;
  for (char c : cell) lower += char(std::tolower(static_cast<unsigned char>(c)));
  for (const char* bad : {"nan", "inf"}) {
    for (size_t p = lower.find(bad); p != std::string::npos; p = lower.find(bad, p + 1)) {
      const bool startsWord = p == 0 || !std::isalpha(static_cast<unsigned char>(lower[p - 1]));
      const bool endsWord =
          p + 3 >= lower.size() || !std::isalpha(static_cast<unsigned char>(lower[p + 3]));
      EXPECT_FALSE(startsWord && endsWord) << region << ": '" << cell << "'";
    }
  }
  const char* s = cell.c_str();
  for (size_t i = 0; i < cell.size(); ++i) {
    if (!std::isdigit(static_cast<unsigned char>(s[i]))) continue;
    char* end = nullptr;
    const double v = std::strtod(s + i, &end);
    EXPECT_TRUE(std::isfinite(v)) << region << ": '" << cell << "'";
    i = size_t(end - s);
  }
}

bool number(const std::string& cell, double& v) {
  char* end = nullptr;
  v = std::strtod(cell.c_str(), &end);
  return end != cell.c_str() && std::isfinite(v);
}

}  // namespace

TEST(ReportAll, MarkerErrorsNameTheRegionAndLeaveTheFileUnchanged) {
  gf::test::TempDir dir("report_all_markers");
  const fs::path results = dir.path / "RESULTS.md";
  struct Bad {
    std::string text, mustSay;
  };
  std::string unknown = page();
  unknown.insert(unknown.find("## thesis"),
                 "<!-- report:lab-extra:begin -->\n<!-- report:lab-extra:end -->\n");
  std::string missing = page();
  for (const std::string marker : {"<!-- report:bench:begin -->\n", "<!-- report:bench:end -->\n"})
    missing.erase(missing.find(marker), marker.size());
  std::string nested = page();
  nested.insert(nested.find("<!-- report:lab-izod:end -->"), "<!-- report:peer-time:begin -->\n");
  const Bad cases[] = {
      {page("lab-izod"), "region 'lab-izod': missing end marker <!-- report:lab-izod:end -->"},
      {unknown, "unknown region 'lab-extra'"},
      {missing, "region 'bench' is missing"},
      {nested,
       "region 'lab-izod': missing end marker <!-- report:lab-izod:end --> (region "
       "'peer-time' begins inside it"},
      {page() + "\n<!-- report:header:stop -->\n", "malformed report marker"},
  };
  for (const Bad& b : cases) {
    write(results, b.text);
    testing::internal::CaptureStderr();
    const int rc =
        reportAll({"--quick", "--results", results.string(), "--out", (dir.path / "out").string()});
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_EQ(rc, gf::cli::kExitOutput) << b.mustSay;
    EXPECT_NE(err.find(b.mustSay), std::string::npos) << err;
    EXPECT_NE(err.find(results.string()), std::string::npos) << "the error names the file: " << err;
    EXPECT_EQ(read(results), b.text) << "the page must be left as it was";
    // Nothing ran: the markers are checked before any part.
    EXPECT_FALSE(fs::exists(dir.path / "out" / "lab")) << b.mustSay;
  }
  EXPECT_EQ(reportAll({"--results", (dir.path / "none.md").string()}), gf::cli::kExitOutput);
  EXPECT_EQ(reportAll({"--bogus"}), gf::cli::kExitUsage);
  EXPECT_EQ(reportAll({"--out"}), gf::cli::kExitUsage);
  // The lab's stop distance, which the quick form shortens, takes millimetres in (0, 100].
  for (const char* bad : {"0", "-1", "abc", "101"})
    EXPECT_EQ(gf::test::runCli({"report", "lab", "--stop-after", bad}), gf::cli::kExitUsage) << bad;
}

TEST(ReportAll, RegionsSpliceBackByteForByte) {
  const std::string text = page();
  gf::Result<gf::cli::MarkedText> m = gf::cli::parseMarkedText("p.md", text, kRegions);
  ASSERT_TRUE(m.ok()) << m.error().message;
  ASSERT_EQ(m.value().names, kRegions);
  EXPECT_EQ(gf::cli::spliceRegions(m.value(), {}), text);
  const std::string spliced =
      gf::cli::spliceRegions(m.value(), {{"bench", "| new |\n|---|\n| 7 |"}, {"peer-range", ""}});
  EXPECT_EQ(skeleton(spliced), skeleton(text));
  EXPECT_EQ(body(spliced, "bench"), "| new |\n|---|\n| 7 |\n");
  EXPECT_EQ(body(spliced, "peer-range"), "");
  EXPECT_EQ(body(spliced, "thesis"), body(text, "thesis"));
}

// `--only lab --reuse` writes the lab regions from the files a `graphfrac report lab` left and
// nothing else: every other region keeps its old body, the hand-written text its bytes. The
// tables come from the files: the committed run's (docs/reports/lab), whose first Charpy row's
// absorbed energy must appear in the Charpy table as the CSV has it, to two decimals.
TEST(ReportAll, OnlyLabReuseRewritesTheLabRegionsFromTheFilesAlone) {
  gf::test::TempDir dir("report_all_only_lab");
  const fs::path results = dir.path / "docs" / "RESULTS.md", out = dir.path / "out";
  fs::create_directories(results.parent_path());
  const std::string before = page();
  write(results, before);
  // Missing files: an error naming the file and the command that makes it; the page unchanged.
  testing::internal::CaptureStderr();
  EXPECT_EQ(
      reportAll({"--only", "lab", "--reuse", "--results", results.string(), "--out", out.string()}),
      gf::cli::kExitOutput);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("brazilian.csv is missing"), std::string::npos) << err;
  EXPECT_NE(err.find("graphfrac report lab --out"), std::string::npos) << err;
  EXPECT_EQ(read(results), before);
  EXPECT_EQ(reportAll({"--reuse", "--results", results.string()}), gf::cli::kExitUsage);
  EXPECT_EQ(reportAll({"--only", "header", "--results", results.string()}), gf::cli::kExitUsage);
  EXPECT_EQ(reportAll({"--only"}), gf::cli::kExitUsage);

  const fs::path committed = fs::path(GF_SOURCE_DIR) / "docs" / "reports" / "lab";
  fs::create_directories(out / "lab");
  for (const char* f : {"brazilian.csv", "impact.csv", "charpy.svg", "izod.svg", "brazilian.svg"})
    fs::copy_file(committed / f, out / "lab" / f);
  EXPECT_EQ(
      reportAll({"--only", "lab", "--reuse", "--results", results.string(), "--out", out.string()}),
      gf::cli::kExitOk);
  const std::string after = read(results);
  EXPECT_EQ(skeleton(after), skeleton(before)) << "a hand-written byte changed";
  for (const std::string& r : kRegions) {
    const bool lab = r.rfind("lab-", 0) == 0;
    EXPECT_EQ(body(after, r) == body(before, r), !lab) << r;
  }
  EXPECT_FALSE(fs::exists(out / "logs")) << "--reuse runs nothing, so it logs nothing";

  // The Charpy table's first brittle row carries impact.csv's absorbed energy.
  const std::string csv = read(out / "lab" / "impact.csv");
  std::vector<std::string> rows = lines(csv);
  ASSERT_GE(rows.size(), 2u);
  std::vector<std::string> head, first;
  for (auto* v : {&head, &first}) {
    std::stringstream ss(rows[v == &head ? 0 : 1]);
    for (std::string c; std::getline(ss, c, ',');) v->push_back(c);
  }
  double absorbed = -1;
  for (size_t i = 0; i < head.size() && i < first.size(); ++i)
    if (head[i] == "absorbed_energy_J") absorbed = std::strtod(first[i].c_str(), nullptr);
  ASSERT_GE(absorbed, 0);
  char want[32];
  std::snprintf(want, sizeof want, "| %.2f", absorbed);
  const std::string charpy = body(after, "lab-charpy");
  EXPECT_NE(charpy.find(want), std::string::npos) << want << " not in\n" << charpy;
}

// `--only PART --reuse` for the other parts, on tiny files written here: each rewrites its own
// regions and nothing else, from the files alone (no run), with figures that can be checked by
// hand: the bench at 1 and 2 threads with its speed-up, the stability table's counts and its
// listed failures, and the Bullet comparison's ratios (Bullet's ms and error over ours) and
// sweep medians.
TEST(ReportAll, OnlyPartReuseWritesEachPartsRegionsFromItsFiles) {
  gf::test::TempDir dir("report_all_only_part");
  const fs::path results = dir.path / "RESULTS.md", out = dir.path / "out";
  fs::create_directories(out);
  const std::string before = page();
  write(results, before);
  auto only = [&](const char* part) {
    return reportAll(
        {"--only", part, "--reuse", "--results", results.string(), "--out", out.string()});
  };
  // Each part's file missing: an error, the page unchanged.
  for (const char* part : {"error-vs-time", "bench", "stability", "peer"}) {
    testing::internal::CaptureStderr();
    EXPECT_EQ(only(part), gf::cli::kExitOutput) << part;
    EXPECT_NE(testing::internal::GetCapturedStderr().find("is missing"), std::string::npos);
    EXPECT_EQ(read(results), before) << part;
  }

  write(out / "bench_multigrid.csv",
        "# 2 frame(s)\n"
        "case,solver,tets,threads,ms_frame,fps,speedup,ms_elements,ms_assembly,ms_solve,"
        "ms_fracture,linear_iterations,thesis_gpu_fps,cpu_ms_frame,vcycle_reduction,"
        "unconverged_frames\n"
        "hinged beam,multigrid (default),4320,1,30.00,33.33,1.00,10,1,15,0,9.0,320.9,29.5,1.80,0\n"
        "hinged beam,multigrid (default),4320,2,20.00,50.00,1.50,6,1,10,0,9.0,320.9,39.0,1.80,1\n"
        "hinged beam,pcg (default),4320,1,40.00,25.00,1.00,10,1,25,0,160.0,320.9,39.5,0,2\n");
  // bench scenes: one case without reference (-1) and one with; the table shows "-" for the
  // missing error and the reference run's broken edges in brackets.
  write(out / "bench_scenes.csv",
        "# 5 frame(s)\n"
        "case,fracture,tets,frames,ms_frame,fps,cpu_ms_frame,ms_elements,ms_assembly,ms_solve,"
        "ms_fracture,ms_contact,ms_other,linear_iterations,peak_mb,peak_reset,solver_error,"
        "broken_edges,broken_edges_reference,reference_residual\n"
        "box 680k,0,679728,1,9000.00,0.111,8800.00,3000.00,900.00,5000.00,0.00,0.00,100.00,"
        "20.0,2500.5,1,-1.000e+00,0,-1,-1.000e+00\n"
        "box 680k,1,679728,1,9500.00,0.105,9300.00,3100.00,900.00,5000.00,400.00,0.00,100.00,"
        "20.0,2700.5,0,3.000e-09,12,11,4.000e-11\n"
        "hinged beam,1,4320,5,12.00,83.333,12.00,7.00,0.60,4.40,0.10,0.00,0.10,"
        "9.0,30.0,1,1.000e-08,51,51,8.000e-13\n");
  write(out / "stability.csv",
        "test,case,material,damage,solver,backend,outcome,e0_J,max_excess_J,max_excess_over_e0,"
        "flags,flagged_steps,not_converged,rolled_back,broken_edges,edges,fragments,ms,message\n"
        "t1,SteelDt5ms,StVK,projection,direct,Cpu,passed,1,0,0,0,0,0,0,0,10,1,5,\"\"\n"
        "t2,SteelDt5ms,StVK,projection,pcg,Cpu,passed,1,0,0,1,3,3,0,0,10,1,5,\"\"\n"
        "t3,SteelDt5ms,StVK,projection,direct,Cuda,skipped,,,,,,,,,,,,\"no device\"\n"
        "t4,Nu0p49,StVK,projection,direct,Cpu,known_failure,1,2,2,0,0,0,0,0,10,1,5,"
        "\"KNOWN FAILURE (why, with a comma)\"\n"
        "t5,Nu0p49,StVK,projection,pcg,Cpu,failed,1,9,9,0,0,0,0,0,10,1,5,\"energy 9 J\"\n");
  write(out / "peer.csv",
        "# bench peer\n"
        "case,method,E_Pa,dt_s,tets,outcome,ms_per_step,measure_m,reference_m,error,"
        "kinetic_over_gravity_work,inverted_tets\n"
        "cantilever,graphfrac-multigrid,1e+07,0.01667,480,stable,2.000,0.1,0.1,1.000e-03,0.1,0\n"
        "cantilever,graphfrac-pcg,1e+07,0.01667,480,stable,4.000,0.1,0.1,2.000e-03,0.1,0\n"
        "cantilever,bullet-implicit,1e+07,0.01667,480,stable,5.000,0.1,0.1,4.000e-03,0.1,0\n"
        "drop,graphfrac-multigrid,1e+06,0.01667,384,stable,1.000,0.1,0.1,1.000e-03,0.1,0\n"
        "drop,bullet-implicit,1e+06,0.01667,384,unstable,-,-,0.1,-,-,17\n"
        "cantilever-sweep,graphfrac-multigrid,1e+05,0.01667,480,stable,1.000,0.1,0.1,1e-3,0,0\n"
        "cantilever-sweep,graphfrac-multigrid,1e+06,0.01667,480,stable,3.000,0.1,0.1,1e-3,0,0\n"
        "cantilever-sweep,graphfrac-multigrid,1e+07,0.01667,480,stable,2.000,0.1,0.1,1e-3,0,0\n"
        "cantilever-sweep,bullet-implicit,1e+05,0.01667,480,stable,8.000,0.1,0.1,1e-3,0,0\n"
        "cantilever-sweep,bullet-implicit,1e+06,0.01667,480,unstable,-,-,0.1,-,-,3\n");

  EXPECT_EQ(only("bench"), gf::cli::kExitOk);
  EXPECT_EQ(only("stability"), gf::cli::kExitOk);
  EXPECT_EQ(only("peer"), gf::cli::kExitOk);
  const std::string after = read(results);
  EXPECT_EQ(skeleton(after), skeleton(before)) << "a hand-written byte changed";
  for (const std::string& r : kRegions) {
    const bool mine = r == "bench" || r == "bench-scenes" || r == "stability" || r == "peer-time" ||
                      r == "peer-range";
    EXPECT_EQ(body(after, r) == body(before, r), !mine) << r;
  }
  EXPECT_FALSE(fs::exists(out / "logs")) << "--reuse runs nothing, so it logs nothing";

  // The bench: both thread counts, each with the speed-up the CSV gives, and the plot.
  // Columns: case, solver, tets, threads, ms, CPU ms, fps, speed-up, ..., residual cut,
  // unconverged, thesis fps.
  std::map<std::string, std::vector<std::string>> rowOf;
  std::vector<std::string> pcgRow;
  for (const std::string& l : lines(body(after, "bench"))) {
    if (l.empty() || l[0] != '|') continue;
    const std::vector<std::string> c = cells(l);
    if (c.size() == 16 && c[0] == "hinged beam" && c[1] == "pcg (default)") pcgRow = c;
    if (c.size() == 16 && c[0] == "hinged beam" && c[1] == "multigrid (default)") rowOf[c[3]] = c;
  }
  ASSERT_EQ(rowOf.size(), 2u);
  EXPECT_EQ(rowOf["1"][5], "29.5");
  EXPECT_EQ(rowOf["1"][7], "1.00");
  EXPECT_EQ(rowOf["2"][7], "1.50");
  EXPECT_EQ(rowOf["2"][13], "1.80");
  EXPECT_EQ(rowOf["2"][14], "1");
  ASSERT_EQ(pcgRow.size(), 16u);
  EXPECT_EQ(pcgRow[13], "-") << "PCG has no V-cycle: 0 in the CSV";
  EXPECT_NE(body(after, "bench").find("--threads 1,2"), std::string::npos)
      << "the command as run names both thread counts";
  EXPECT_NE(read(out / "bench_multigrid.svg").find("<svg"), std::string::npos);

  // The scene list: fracture on/off, the stages, peak MB and its reset, the solver error.
  const std::string scenes = body(after, "bench-scenes");
  EXPECT_NE(scenes.find("| box 680k | off | 679728 | 1 | 9000.00 | 0.111 | 3000.00 | 900.00 | "
                        "5000.00 | 0.00 | 100.00 | 20.0 | 2500.5 | 1 | - | 0 |"),
            std::string::npos)
      << scenes;
  EXPECT_NE(scenes.find(
                "| box 680k | on | 679728 | 1 | 9500.00 | 0.105 | 3100.00 | 900.00 | "
                "5000.00 | 400.00 | 100.00 | 20.0 | 2700.5 | 0 | 3.000e-09 (reference 4.000e-11) | "
                "12 (11) |"),
            std::string::npos)
      << "a reference that stopped short of 1e-12 shows the residual it reached\n"
      << scenes;
  EXPECT_NE(scenes.find("| 0.10 | 9.0 | 30.0 | 1 | 1.000e-08 | 51 (51) |"), std::string::npos)
      << "a converged reference shows the error alone\n"
      << scenes;
  EXPECT_NE(scenes.find("bench_scenes.json"), std::string::npos) << scenes;

  // Stability: per case, CPU passes / known failures / failures, and each listed with why.
  const std::string stab = body(after, "stability");
  EXPECT_NE(stab.find("| SteelDt5ms | 2 / 0 / 0 | 0, 1 | NotConverged |"), std::string::npos)
      << stab;
  EXPECT_NE(stab.find("| Nu0p49 | 0 / 1 / 1 | 0, 0 | none |"), std::string::npos) << stab;
  EXPECT_NE(stab.find("KNOWN FAILURE (why, with a comma)"), std::string::npos) << stab;
  EXPECT_NE(stab.find("Failed runs:"), std::string::npos) << stab;
  EXPECT_NE(stab.find("energy 9 J"), std::string::npos) << stab;

  // The Bullet comparison: 5 / 2 ms = 2.50x and 4e-3 / 1e-3 = 4x over multigrid, 1.25x and 2x
  // over PCG; the unstable drop has no ratio. Sweep medians: ours 2 ms of 3 runs, Bullet's 8 ms
  // of its 1 stable run: 4.00x.
  const std::string peerTime = body(after, "peer-time");
  EXPECT_NE(peerTime.find("| cantilever, 1/60 s | Bullet implicit | 2.50x; 4x | 1.25x; 2x |"),
            std::string::npos)
      << peerTime;
  EXPECT_EQ(peerTime.find("| drop, 1/60 s | Bullet implicit |"), std::string::npos) << peerTime;
  EXPECT_NE(peerTime.find("graphfrac multigrid 2.00 ms (3 of its runs)"), std::string::npos)
      << peerTime;
  EXPECT_NE(peerTime.find("Bullet implicit / graphfrac multigrid 4.00x"), std::string::npos)
      << peerTime;
  const std::string range = body(after, "peer-range");
  EXPECT_NE(range.find("| Bullet implicit | 1 / 2 | - |"), std::string::npos) << range;
  EXPECT_NE(range.find("| graphfrac multigrid | 3 / 3 | - |"), std::string::npos) << range;
}

// The quick form end to end: about a minute on two cores.
TEST(ReportAll, QuickFormFillsEveryRegionAndKeepsTheHandWrittenText) {
  gf::test::TempDir dir("report_all_quick");
  const fs::path results = dir.path / "docs" / "RESULTS.md", out = dir.path / "out";
  fs::create_directories(results.parent_path());
  const std::string before = page();
  write(results, before);
  const int rc =
      reportAll({"--quick", "--results", results.string(), "--out", out.string(), "--scenes",
                 std::string(GF_SOURCE_DIR) + "/scenes", "--stability-bin", GF_STABILITY_BIN});
  EXPECT_EQ(rc, gf::cli::kExitOk);
  const std::string after = read(results);
  ASSERT_NE(after, before);
  EXPECT_EQ(skeleton(after), skeleton(before)) << "a hand-written byte changed";

  const bool noBullet =
      body(after, "peer-time").find("Not run: this graphfrac was built without Bullet") !=
      std::string::npos;
  for (const std::string& r : kRegions) {
    const std::string b = body(after, r);
    EXPECT_EQ(b.find("| old | table |"), std::string::npos) << r << " was not regenerated";
    if (noBullet && (r == "peer-time" || r == "peer-range")) continue;
    int rows = 0;
    bool rule = false;
    for (const std::string& l : lines(b)) {
      if (l.rfind("|---", 0) == 0) {
        rule = true;
        continue;
      }
      if (l.empty() || l[0] != '|') continue;
      ++rows;
      for (const std::string& c : cells(l)) expectFiniteNumbers(r, c);
    }
    EXPECT_TRUE(rule) << r << " holds no table:\n" << b;
    EXPECT_GE(rows, 2) << r << " holds no table rows:\n" << b;
  }

  // Each ratio is its row's ours over thesis.
  int ratios = 0;
  for (const std::string& l : lines(body(after, "thesis"))) {
    if (l.rfind("| table", 0) != 0) continue;
    const std::vector<std::string> c = cells(l);
    double thesis = 0, ours = 0, ratio = 0;
    if (c.size() < 4 || !number(c[1], thesis) || !number(c[2], ours) || !number(c[3], ratio))
      continue;
    EXPECT_NEAR(ratio, ours / thesis, 1e-2 * std::abs(ours / thesis)) << l;
    ++ratios;
  }
  EXPECT_GE(ratios, 13) << "table 4.1's inputs, its times and tables 6.1 / 6.2";

  // The stability table accounts for every run of the matrix: 10 cases x 48 combinations.
  int cases = 0;
  for (const std::string& l : lines(body(after, "stability"))) {
    if (l.empty() || l[0] != '|' || l.rfind("|---", 0) == 0) continue;
    const std::vector<std::string> c = cells(l);
    if (c.size() < 3 || c[0] == "case") continue;
    int pass = 0, known = 0, failed = 0, skipCpu = 0, skipOther = 0;
    ASSERT_EQ(std::sscanf(c[1].c_str(), "%d / %d / %d", &pass, &known, &failed), 3) << l;
    ASSERT_EQ(std::sscanf(c[2].c_str(), "%d, %d", &skipCpu, &skipOther), 2) << l;
    EXPECT_EQ(pass + known + failed + skipCpu, 24) << l;
    EXPECT_EQ(skipOther, 24) << l << ": the CUDA runs are skipped without a device";
    EXPECT_EQ(failed, 0) << l;
    ++cases;
  }
  EXPECT_EQ(cases, 10);

  // The plots exist, and every image the page links resolves from the page's folder.
  for (const fs::path& svg :
       {out / "lab" / "brazilian.svg", out / "lab" / "charpy.svg", out / "lab" / "izod.svg",
        out / "hanging_sphere" / "error_vs_time.svg", out / "bench_multigrid.svg"})
    EXPECT_NE(read(svg).find("<svg"), std::string::npos) << svg;
  int images = 0;
  for (size_t p = after.find("]("); p != std::string::npos; p = after.find("](", p + 1)) {
    const size_t e = after.find(')', p);
    const fs::path target = results.parent_path() / after.substr(p + 2, e - p - 2);
    EXPECT_TRUE(fs::exists(target)) << target;
    ++images;
  }
  EXPECT_EQ(images, 5);
}
