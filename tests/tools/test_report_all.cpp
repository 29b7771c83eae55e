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
    "error-vs-time", "bench",  "stability",     "peer-time",  "peer-range"};

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
  EXPECT_EQ(reportAll({"--only", "bench", "--results", results.string()}), gf::cli::kExitUsage);
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
