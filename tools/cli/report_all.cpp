// `graphfrac report all [--quick] [--out DIR] [--results FILE]`: every measurement that
// docs/RESULTS.md publishes, in one run, written into that file's generated regions
// (cli/results_regions.h) and nowhere else, so the prose around the tables survives.
//
// The parts run in this process through the commands that own them (`report lab`,
// `report error-vs-time`, `bench multigrid`, `bench peer`); their CSV and SVG files go under
// DIR and the regions are built from those files, so what the page shows is what DIR holds.
// The stability suite is a gtest binary that the tools cannot link. Its cases are fixtures whose
// rules are gtest assertions (a failure, a skip naming a known failure), so moving the case list
// into a library would give the report a second way of judging the same runs; instead the
// report runs the binary as a child process with GF_STABILITY_CSV naming a file, and the suite
// writes one row per run with gtest's own verdict and message (tests/stability). The binary is
// found where the build puts it beside this program (or --stability-bin); when it is not
// there, the region says so and names where it looked. Where any part cannot run, its region
// says why instead of showing an empty table.
//
// The file is read and its markers checked before anything runs, and written (whole, through a
// temporary file and a rename) only at the end: a bad marker costs nothing and changes nothing.
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cli/commands.h"
#include "cli/report_lab.h"
#include "cli/results_regions.h"
#include "cli/svg_plot.h"

extern char** environ;

#ifndef GF_BUILD_TYPE
#define GF_BUILD_TYPE "unknown"
#endif
#ifndef GF_CXX_COMPILER
#define GF_CXX_COMPILER "unknown compiler"
#endif

namespace gf::cli {
namespace {

namespace fs = std::filesystem;

constexpr const char* kAllUsage =
    "usage: graphfrac report all [--quick] [--out DIR] [--results FILE] [--scenes DIR]\n"
    "                            [--stability-bin PATH] [--only PART [--reuse]]\n"
    "\n"
    "Runs every measurement of docs/RESULTS.md and rewrites the file's generated regions, the\n"
    "lines between <!-- report:NAME:begin --> and <!-- report:NAME:end -->; every other line is\n"
    "kept byte for byte. Each region must appear once; a missing, unknown or unpaired marker is\n"
    "an error before anything runs. Regions and the parts that fill them:\n"
    "  header          machine (/proc), compiler and build type, date, load average before and\n"
    "                  after, OPENBLAS_NUM_THREADS, the commands below with exit and wall time\n"
    "  thesis          the thesis's published numbers (tables 4.1, 6.1, 6.2, lab outcomes)\n"
    "                  beside ours, with the ratio and the hardware of each\n"
    "  lab-brazilian, lab-charpy, lab-izod, lab-acceptance            (PART lab)\n"
    "                  graphfrac report lab --out DIR/lab\n"
    "  error-vs-time   graphfrac report error-vs-time scenes/hanging_sphere.json (PART\n"
    "                  error-vs-time)\n"
    "  bench           graphfrac bench multigrid --threads 1,2 (4k to 160k tets, thesis table\n"
    "                  6.2; PART bench)\n"
    "  bench-scenes    graphfrac bench scenes --json DIR/bench_scenes.json (4k to 680k tets,\n"
    "                  fracture off and on, peak MB, solver error; PART bench)\n"
    "  stability       gf_stability_tests (found next to this build, or --stability-bin) run\n"
    "                  with GF_STABILITY_CSV=DIR/stability.csv; GF_FULL_VALIDATION=1 unless\n"
    "                  --quick (PART stability)\n"
    "  peer-time, peer-range\n"
    "                  graphfrac bench peer (Bullet's deformable FEM beside ours; PART peer),\n"
    "                  with the ratios of Bullet's step time and error to ours\n"
    "CSV and SVG files go to DIR (default docs/reports, where the page's links point; with\n"
    "--quick out/report-quick), the parts' logs to DIR/logs. FILE defaults to docs/RESULTS.md,\n"
    "--scenes to scenes. The full form takes tens of minutes (run it with OPENBLAS_NUM_THREADS=1\n"
    "as docs/reports/README.md does); --quick is CI's short form, about a minute: coarse lab\n"
    "meshes with the impacts stopped 0.5 mm past contact, 2 frames of error against time, the\n"
    "4k-tet benchmark case, the stability suite's reduced form, the Bullet comparison on its\n"
    "smallest meshes for 0.25 s per run (not at all without Bullet).\n"
    "--only PART (lab, error-vs-time, bench, stability or peer) runs that part alone and\n"
    "rewrites only its own regions (header and thesis describe a full run and are kept); with\n"
    "--reuse it runs nothing and reads the files that part left under DIR (lab/*.csv,\n"
    "hanging_sphere/error_vs_time.csv, bench_multigrid.csv, bench_scenes.csv, stability.csv,\n"
    "peer.csv).\n"
    "Exit: 0; 1 usage; 2 a scene could not be loaded; 3 a part failed or flagged a step (its\n"
    "region says so; error against time's capped solver settings flag by design and do not\n"
    "count); 4 FILE has a bad marker or cannot be written (it is then unchanged), or --reuse\n"
    "finds a part's file missing.\n";

/// The parts `--only` can name.
const std::vector<std::string> kParts = {"lab", "error-vs-time", "bench", "stability", "peer"};

/// The regions `report all` owns, in the order the page shows them.
const std::vector<std::string> kRegions = {
    "header",        "thesis", "lab-brazilian", "lab-charpy", "lab-izod",  "lab-acceptance",
    "error-vs-time", "bench",  "bench-scenes",  "stability",  "peer-time", "peer-range"};

struct Options {
  bool quick = false;
  bool reuse = false;  // --reuse: read the part's files instead of running it (needs --only)
  std::string out, results = "docs/RESULTS.md", scenes = "scenes", stabilityBin;
  std::string only;  // one of kParts, or empty (every part)
};

std::string fmt(const char* f, double v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

Result<std::string> readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail(path, ": cannot read");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// A command as a user would type it: arguments with blanks quoted.
std::string commandLine(const std::vector<std::string>& args) {
  std::string s = "graphfrac";
  for (const std::string& a : args)
    s += " " + (a.find_first_of(" \t'\"") == std::string::npos ? a : "'" + a + "'");
  return s;
}

// The part commands print their figures on stdout; here stdout goes to a file for the length of
// one call, so the command functions run unchanged and their output lands under DIR. Child
// processes they start (bench peer's Bullet runs) inherit it.
class StdoutToFile {
 public:
  explicit StdoutToFile(const std::string& path) {
    std::fflush(stdout);
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) return;
    m_saved = ::dup(STDOUT_FILENO);
    if (m_saved < 0 || ::dup2(fd, STDOUT_FILENO) < 0) {
      if (m_saved >= 0) ::close(m_saved);
      m_saved = -1;
    }
    ::close(fd);
  }
  ~StdoutToFile() {
    if (m_saved < 0) return;
    std::fflush(stdout);
    ::dup2(m_saved, STDOUT_FILENO);
    ::close(m_saved);
  }
  bool ok() const { return m_saved >= 0; }
  StdoutToFile(const StdoutToFile&) = delete;
  StdoutToFile& operator=(const StdoutToFile&) = delete;

 private:
  int m_saved = -1;
};

// One part of the report: what ran, how it ended, how long it took.
struct Part {
  std::string name, command;
  int exit = -1;  // -1: not run
  double seconds = 0;
  std::string note;  // why it did not run, or what its exit code means
};

int runPart(Part& part, int (*fn)(int, char**), std::vector<std::string> args,
            const fs::path& log) {
  part.command = commandLine(args);
  std::printf("report all: %s ...\n", part.command.c_str());
  std::fflush(stdout);
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  const auto t0 = std::chrono::steady_clock::now();
  {
    StdoutToFile capture(log.string());
    if (!capture.ok()) {
      part.note = "cannot write " + log.string();
      return part.exit = kExitOutput;
    }
    part.exit = fn(int(argv.size()), argv.data());
  }
  part.seconds = secondsSince(t0);
  std::printf("report all:   exit %d after %.1f s (output: %s)\n", part.exit, part.seconds,
              log.string().c_str());
  return part.exit;
}

// A CSV as the parts write it: '#' lines are comments; fields may be double-quoted.
struct Table {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  int col(const std::string& name) const {
    for (size_t i = 0; i < header.size(); ++i)
      if (header[i] == name) return int(i);
    return -1;
  }
  std::string at(size_t row, const std::string& name) const {
    const int c = col(name);
    return c >= 0 && size_t(c) < rows[row].size() ? rows[row][size_t(c)] : std::string();
  }
  std::string material(size_t row) const { return at(row, "material"); }
  double num(size_t row, const std::string& name) const {
    const std::string s = at(row, name);
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    return s.empty() || *end != '\0' ? NAN : v;
  }
};

std::vector<std::string> splitCsvLine(const std::string& line) {
  std::vector<std::string> out(1);
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        out.back() += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        out.back() += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      out.emplace_back();
    } else if (c != '\r') {
      out.back() += c;
    }
  }
  return out;
}

Result<Table> readCsv(const fs::path& path) {
  std::ifstream in(path);
  if (!in) return fail(path.string(), ": cannot read");
  Table t;
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    if (t.header.empty())
      t.header = splitCsvLine(line);
    else
      t.rows.push_back(splitCsvLine(line));
  }
  if (t.header.empty()) return fail(path.string(), ": no header row");
  return t;
}

// Path of `target` as a link from a markdown file in `fromDir`.
std::string linkPath(const fs::path& target, const fs::path& fromDir) {
  std::error_code ec;
  const fs::path a = fs::weakly_canonical(fs::absolute(target), ec);
  const fs::path b = fs::weakly_canonical(fs::absolute(fromDir), ec);
  const fs::path rel = a.lexically_relative(b);
  return (rel.empty() ? a : rel).generic_string();
}

// ---- machine ------------------------------------------------------------------------------

std::string procField(const char* file, const char* key) {
  std::ifstream in(file);
  for (std::string line; std::getline(in, line);)
    if (line.rfind(key, 0) == 0) {
      const size_t colon = line.find(':');
      if (colon == std::string::npos) continue;
      const size_t first = line.find_first_not_of(" \t", colon + 1);
      return first == std::string::npos ? std::string() : line.substr(first);
    }
  return {};
}

int procCount(const char* file, const char* key) {
  std::ifstream in(file);
  int n = 0;
  for (std::string line; std::getline(in, line);) n += line.rfind(key, 0) == 0;
  return n;
}

std::string osName() {
  std::ifstream in("/etc/os-release");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("PRETTY_NAME=", 0) == 0) {
      std::string v = line.substr(12);
      v.erase(std::remove(v.begin(), v.end(), '"'), v.end());
      return v;
    }
  return "unknown";
}

std::string cpuText() {
  std::string model = procField("/proc/cpuinfo", "model name");
  if (model.empty()) model = "unknown CPU (no /proc/cpuinfo)";
  const int processors = procCount("/proc/cpuinfo", "processor");
  return model + ", " +
         std::to_string(processors > 0 ? processors : int(std::thread::hardware_concurrency())) +
         " logical cores";
}

std::string memoryText() {
  const std::string kb = procField("/proc/meminfo", "MemTotal");
  const double v = std::strtod(kb.c_str(), nullptr);
  return v > 0 ? fmt("%.1f GiB", v / (1024.0 * 1024.0)) : std::string("unknown (no /proc/meminfo)");
}

// ---- regions ------------------------------------------------------------------------------

// The 1-, 5- and 15-minute load averages: other jobs on the machine slow every wall time here.
std::string loadAverage() {
  std::ifstream in("/proc/loadavg");
  double l1 = -1, l5 = -1, l15 = -1;
  in >> l1 >> l5 >> l15;
  if (!in) return "unknown (no /proc/loadavg)";
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.2f, %.2f, %.2f", l1, l5, l15);
  return buf;
}

std::string headerRegion(const Options& opt, const std::vector<Part>& parts,
                         const std::string& self, double seconds, const std::string& loadBefore,
                         const std::string& loadAfter) {
  const std::time_t now = std::time(nullptr);
  char date[64];
  std::strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
  std::string s =
      "Generated by `" + self + "` on " + date + " in " + fmt("%.0f s", seconds) +
      (opt.quick ? " (the quick form: CI's short runs, not the published figures)" : "") +
      ". Machine and build:\n\n";
  s += "| | |\n|---|---|\n";
  s += "| CPU | " + cpuText() + " |\n";
  s += "| memory | " + memoryText() + " |\n";
  s += "| system | " + osName() + " |\n";
  s += std::string("| compiler, build | ") + GF_CXX_COMPILER + ", " + GF_BUILD_TYPE + " build |\n";
  const char* blas = std::getenv("OPENBLAS_NUM_THREADS");
  s += std::string("| OPENBLAS_NUM_THREADS | ") + (blas ? blas : "not set") + " |\n";
  s += "| load average (1, 5, 15 min) | " + loadBefore + " at the start, " + loadAfter +
       " at the end (this machine has " +
       std::to_string(std::max(1, procCount("/proc/cpuinfo", "processor"))) +
       " logical cores; a load above that means the runs shared them) |\n";
  s += "\nThe parts, each a command of its own (same figures, same files):\n\n";
  s += "| part | command | exit | wall [s] |\n|---|---|---|---|\n";
  for (const Part& p : parts)
    s += "| " + p.name + " | " + (p.command.empty() ? "-" : "`" + p.command + "`") + " | " +
         (p.exit < 0 ? "not run: " + p.note
                     : std::to_string(p.exit) + (p.note.empty() ? "" : " (" + p.note + ")")) +
         " | " + (p.exit < 0 ? "-" : fmt("%.1f", p.seconds)) + " |\n";
  s += "\nExit 3 is a part that ran and flagged a step (e.g. a capped PCG setting of error "
       "against time); the figures are still written.\n";
  return s;
}

// "13 056": thousands apart, as the hand-written tables have them.
std::string grouped(const std::string& digits) {
  std::string s;
  for (size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) s += ' ';
    s += digits[i];
  }
  return s;
}

std::string notGenerated(const Part& part, const std::string& why) {
  if (part.exit < 0) return "Not run: " + part.note + ".\n";
  return "Not generated: `" + part.command + "` ended with exit " + std::to_string(part.exit) +
         " (" + why + ").\n";
}

std::string image(const char* alt, const fs::path& svg, const fs::path& resultsDir) {
  return fs::exists(svg) ? std::string("\n![") + alt + "](" + linkPath(svg, resultsDir) + ")\n"
                         : std::string("\n(no ") + svg.filename().string() + " was written)\n";
}

// The Brazilian disc's runs (lab/brazilian.csv), in the columns of RESULTS.md's table.
std::string pct(double now, double before) { return fmt("%+.2f %%", 100 * (now / before - 1)); }

// What the disc's rows say beside the acceptance: the first break against Hondros's centre
// stress for the jaws' arc, the load the jaws add while the crack crosses, the loading rate's
// and the mesh's effect on P. Rows as `report lab` writes them: the coarse disc at the scene's
// rate first, then at the other rate, the fine disc last.
std::string brazilianFindings(const Table& b) {
  if (b.rows.empty()) return "";
  // scenes/lab/brazilian_disc.json bonds the jaws over +-11.25 degrees of the rim; for a load
  // spread over 2 alpha, Hondros (1959) puts the centre's tensile stress at
  // (sin 2 alpha - alpha) / alpha times 2 P / (pi D t).
  const double alpha = 11.25 * M_PI / 180, hondros = (std::sin(2 * alpha) - alpha) / alpha;
  std::vector<size_t> atRate, other;
  for (size_t r = 0; r < b.rows.size(); ++r)
    (b.num(r, "jaw_speed_m_s") == b.num(0, "jaw_speed_m_s") ? atRate : other).push_back(r);
  std::string s =
      "\n- First break against the set-up's elastic solution: for the jaws' arc of "
      "+-11.25 degrees Hondros's centre stress is " +
      fmt("%.3f", hondros) +
      " times 2 P / (pi D t), so the first edge should break at 2 P / (pi D t) = " +
      fmt("%.3f", 1 / hondros) + " sigma_th; it breaks at";
  for (size_t i = 0; i < atRate.size(); ++i)
    s += (i ? ", " : " ") + fmt("%.3f", b.num(atRate[i], "first_break_ratio")) + " (" +
         b.at(atRate[i], "tets") + " tets)";
  s += ". The jaws add";
  for (size_t i = 0; i < atRate.size(); ++i)
    s += (i ? ", " : " ") +
         pct(b.num(atRate[i], "peak_load_N"), b.num(atRate[i], "first_break_load_N"));
  s += " to the first-break load while the crack crosses the disc (P over the first break's "
       "load).\n";
  // Quasi-static: the time to P against a longitudinal wave's transit of the disc, D / c with
  // c = sqrt(E / rho) for table 4.1's granite and the scene's D = 50 mm. Both jaws move, so the
  // approach closes at twice the jaw speed.
  const double transit = 0.05 / std::sqrt(4.5e10 / 2.75e3);
  for (size_t r : atRate) {
    const double toPeak = b.num(r, "approach_at_peak_m") / (2 * b.num(r, "jaw_speed_m_s"));
    s += "- Loading time: P after " + fmt("%.1f um", 1e6 * b.num(r, "approach_at_peak_m")) +
         " of approach, " + fmt("%.2f ms", 1e3 * toPeak) + " at the jaws' speed (" +
         b.at(r, "tets") + " tets): " + fmt("%.0f", toPeak / transit) +
         fmt(" times the %.1f us a longitudinal wave takes to cross the disc.\n", 1e6 * transit);
  }
  for (size_t r : other)
    s += "- Loading rate: at " + fmt("%.3g m/s", b.num(r, "jaw_speed_m_s")) + " instead of " +
         fmt("%.3g m/s", b.num(0, "jaw_speed_m_s")) + " (" + b.at(r, "tets") +
         " tets) the first-break load changes by " +
         pct(b.num(r, "first_break_load_N"), b.num(0, "first_break_load_N")) + " and P by " +
         pct(b.num(r, "peak_load_N"), b.num(0, "peak_load_N")) + ".\n";
  if (atRate.size() > 1)
    s += "- Mesh: P changes by " +
         pct(b.num(atRate.back(), "peak_load_N"), b.num(atRate.front(), "peak_load_N")) + " from " +
         b.at(atRate.front(), "tets") + " to " + b.at(atRate.back(), "tets") +
         " tets, the first-break load by " +
         pct(b.num(atRate.back(), "first_break_load_N"),
             b.num(atRate.front(), "first_break_load_N")) +
         ".\n";
  return s;
}

std::string labBrazilianRegion(const fs::path& dir, const fs::path& resultsDir, const Part& part) {
  Result<Table> t = readCsv(dir / "brazilian.csv");
  if (!t.ok()) return notGenerated(part, t.error().message);
  const Table& b = t.value();
  std::string s =
      "| mesh, jaw speed | tets | first break [kN] | 2 P_first / (pi D t) / sigma_th | P [kN] | "
      "2P/(pi D t) [MPa] | / sigma_th (" +
      fmt("%.3g MPa", 1e-6 * (b.rows.empty() ? 0 : b.num(0, "sigma_th_Pa"))) +
      ") | first break from the centre | crack: broken edges, share within 0.1 D of the loaded "
      "diameter, principal axis from it |\n|---|---|---|---|---|---|---|---|---|\n";
  for (size_t r = 0; r < b.rows.size(); ++r) {
    std::string run = b.at(r, "run");
    if (const size_t at = run.find(" at "); at != std::string::npos) run.replace(at, 4, ", ");
    s += "| " + run + " | " + grouped(b.at(r, "tets")) + " | " +
         fmt("%.2f", 1e-3 * b.num(r, "first_break_load_N")) + " | " +
         fmt("%.3f", b.num(r, "first_break_ratio")) + " | " +
         fmt("%.2f", 1e-3 * b.num(r, "peak_load_N")) + " | " +
         fmt("%.2f", 1e-6 * b.num(r, "indirect_strength_Pa")) + " | " +
         fmt("%.3f", b.num(r, "ratio")) + " | " +
         fmt("%.3f D", b.num(r, "first_break_from_centre_over_D")) + " | " +
         b.at(r, "broken_edges") + ", " + fmt("%.0f %%", 100 * b.num(r, "on_diameter_fraction")) +
         ", " + fmt("%.1f deg", b.num(r, "crack_angle_deg")) + " |\n";
  }
  s += "\nFrom `" + part.command + "` (" + linkPath(dir, resultsDir) + "/brazilian.csv).\n";
  s += brazilianFindings(b);
  return s + image("Brazilian disc", dir / "brazilian.svg", resultsDir);
}

// "68x8x4 (13 056)" from the mesh label "68x8x4 cells" and the tet count.
std::string meshText(const Table& m, size_t r) {
  std::string mesh = m.at(r, "mesh");
  if (const size_t sp = mesh.find(' '); sp != std::string::npos) mesh.resize(sp);
  return mesh + " (" + grouped(m.at(r, "tets")) + ")";
}

std::string mmText(double metres) { return metres >= 0 ? fmt("%.3f", 1e3 * metres) : "-"; }

std::string impactOutcome(const Table& m, size_t r) {
  const double largest = m.num(r, "largest_share"), second = m.num(r, "second_share");
  const std::string shares =
      fmt("%.0f %% / ", 100 * largest) + fmt("%.0f %% of the nodes", 100 * second);
  if (second >= lab::kSplitShare) return "split in two (" + shares + ")";
  if (m.material(r) == "ductile")
    return m.num(r, "broken_edges") > 0 ? "bent, partly cracked, one piece" : "bent, intact";
  return "one piece (" + shares + ")";
}

// One impact test's runs (lab/impact.csv) in RESULTS.md's columns; `stopMm` is where the runs
// that did not split were stopped.
std::string labImpactRegion(const fs::path& dir, const fs::path& resultsDir, const Part& part,
                            const std::string& test, double stopMm) {
  Result<Table> t = readCsv(dir / "impact.csv");
  if (!t.ok()) return notGenerated(part, t.error().message);
  const Table& m = t.value();
  const bool charpy = test == "charpy";
  std::string s = charpy
                      ? "| material | mesh (tets) | first break [kN] at [mm] | peak load [kN] at "
                        "[mm] | fracture at [mm] (energy [J]) | split at [mm] | absorbed [J] | "
                        "broken edges | ligament cut | outcome |\n"
                        "|---|---|---|---|---|---|---|---|---|---|\n"
                      : "| material | mesh (tets) | first break [kN] at [mm] | peak load [kN] at "
                        "[mm] | absorbed [J] (" +
                            fmt("%g mm", stopMm) +
                            ") | broken edges | ligament cut | outcome |\n"
                            "|---|---|---|---|---|---|---|---|\n";
  for (size_t r = 0; r < m.rows.size(); ++r) {
    if (m.at(r, "test") != test) continue;
    const bool split = m.num(r, "displacement_at_split_m") >= 0;
    const std::string firstBreak = m.num(r, "first_break_displacement_m") >= 0
                                       ? fmt("%.2f at ", 1e-3 * m.num(r, "first_break_load_N")) +
                                             mmText(m.num(r, "first_break_displacement_m"))
                                       : std::string("none");
    s += "| " + m.at(r, "material") + " | " + meshText(m, r) + " | " + firstBreak + " | " +
         fmt("%.2f at ", 1e-3 * m.num(r, "peak_load_N")) +
         mmText(m.num(r, "displacement_at_peak_m")) + " | ";
    const std::string absorbed = fmt("%.2f", m.num(r, "absorbed_energy_J"));
    if (charpy) {
      const double fracture = m.num(r, "displacement_at_fracture_m");
      s += (fracture >= 0 ? mmText(fracture) + fmt(" (%.2f)", m.num(r, "energy_to_fracture_J"))
                          : std::string("-")) +
           " | " + mmText(m.num(r, "displacement_at_split_m")) + " | " + absorbed +
           (split ? "" : fmt(" (at %g mm)", stopMm)) + " | ";
    } else {
      s += absorbed +
           (split ? " (split at " + mmText(m.num(r, "displacement_at_split_m")) + " mm)" : "") +
           " | ";
    }
    s += m.at(r, "broken_edges") + " | " +
         fmt("%.0f %%", 100 * m.num(r, "ligament_broken_fraction")) + " | " + impactOutcome(m, r) +
         " |\n";
  }
  s += "\nFrom `" + part.command + "` (" + linkPath(dir, resultsDir) + "/impact.csv, curves/).\n";
  // The mesh check: each material's first and last mesh (coarse, fine), as `report lab` runs
  // them.
  for (const char* material : {"brittle", "ductile"}) {
    std::vector<size_t> rows;
    for (size_t r = 0; r < m.rows.size(); ++r)
      if (m.at(r, "test") == test && m.at(r, "material") == material) rows.push_back(r);
    if (rows.size() < 2) continue;
    const size_t c = rows.front(), f = rows.back();
    s += std::string(material == std::string("brittle") ? "\n" : "") + "- Mesh, " + material +
         " bar, " + meshText(m, c) + " to " + meshText(m, f) + ": peak load " +
         pct(m.num(f, "peak_load_N"), m.num(c, "peak_load_N")) + " (at " +
         mmText(m.num(c, "displacement_at_peak_m")) + " and " +
         mmText(m.num(f, "displacement_at_peak_m")) + " mm), load at the first break " +
         pct(m.num(f, "first_break_load_N"), m.num(c, "first_break_load_N")) +
         ", absorbed energy " + pct(m.num(f, "absorbed_energy_J"), m.num(c, "absorbed_energy_J")) +
         ".\n";
  }
  return s + image(charpy ? "Charpy" : "Izod", dir / (test + ".svg"), resultsDir);
}

// Issue 19's acceptance per mesh, from the same files.
std::string labAcceptanceRegion(const fs::path& dir, const Part& part) {
  Result<Table> disc = readCsv(dir / "brazilian.csv");
  Result<Table> imp = readCsv(dir / "impact.csv");
  if (!disc.ok() || !imp.ok())
    return notGenerated(part, (disc.ok() ? imp : Result<Table>(disc.error())).error().message);
  const Table& b = disc.value();
  const Table& m = imp.value();
  const char* meshes[2] = {"68x8x4 cells", "68x12x8 cells"};
  // The disc's runs at the scene's jaw rate: the first is the coarse disc, the last the fine.
  std::vector<size_t> discRows;
  for (size_t r = 0; r < b.rows.size(); ++r)
    if (r == 0 || b.num(r, "jaw_speed_m_s") == b.num(0, "jaw_speed_m_s")) discRows.push_back(r);
  auto cell = [](bool met, const std::string& detail) {
    return (met ? "met, " : "**not met** (") + detail + (met ? "" : ")");
  };
  auto discCell = [&](int res, bool strength) -> std::string {
    if (size_t(res) >= discRows.size()) return "not run";
    const size_t r = discRows[size_t(res)];
    if (strength) {
      const double ratio = b.num(r, "ratio");
      std::string detail = fmt("%+.1f %%", 100 * (ratio - 1));
      // The coarse disc's run at another jaw rate (the report's rate check) follows it.
      if (res == 0 && b.rows.size() > 1 && b.num(1, "jaw_speed_m_s") != b.num(0, "jaw_speed_m_s")) {
        const double other = b.num(1, "ratio");
        detail +=
            fmt(" (%+.1f %% at ", 100 * (other - 1)) + fmt("%.3g m/s)", b.num(1, "jaw_speed_m_s"));
        return cell(std::abs(ratio - 1) <= 0.15 && std::abs(other - 1) <= 0.15, detail);
      }
      return cell(std::abs(ratio - 1) <= 0.15, detail);
    }
    const double d = b.num(r, "first_break_from_centre_over_D");
    return cell(b.num(r, "broken_edges") > 0 && d <= 0.2, fmt("%.3f D", d));
  };
  auto row = [&](const std::string& test, const std::string& material, int res) -> int {
    for (size_t r = 0; r < m.rows.size(); ++r)
      if (m.at(r, "test") == test && m.at(r, "material") == material &&
          m.at(r, "mesh") == meshes[res])
        return int(r);
    return -1;
  };
  std::string s = "| issue 19 acceptance | coarse mesh | fine mesh |\n|---|---|---|\n";
  s += "| Brazilian: 2P/(pi D t) within 15 % of sigma_th | " + discCell(0, true) + " | " +
       (discRows.size() > 1 ? discCell(int(discRows.size()) - 1, true) : "not run") + " |\n";
  s += "| Brazilian: crack starts within 0.2 D of the centre | " + discCell(0, false) + " | " +
       (discRows.size() > 1 ? discCell(int(discRows.size()) - 1, false) : "not run") + " |\n";
  for (const std::string test : {"charpy", "izod"}) {
    const std::string name = test == "charpy" ? "Charpy" : "Izod";
    std::string split = "| " + name + ": brittle splits in two |",
                bend = "| " + name + ": ductile bends and stays partly joined |",
                energy = "| " + name + ": ductile absorbs more |";
    for (int res = 0; res < 2; ++res) {
      const int br = row(test, "brittle", res), du = row(test, "ductile", res);
      if (br < 0 || du < 0) {
        split += " not run |";
        bend += " not run |";
        energy += " not run |";
        continue;
      }
      const size_t bi = size_t(br), di = size_t(du);
      const bool brittleSplit = m.num(bi, "second_share") >= lab::kSplitShare;
      split += " " +
               cell(brittleSplit, brittleSplit
                                      ? "at " + mmText(m.num(bi, "displacement_at_split_m")) + " mm"
                                      : fmt("%.0f %% of the ligament",
                                            100 * m.num(bi, "ligament_broken_fraction"))) +
               " |";
      const bool ductileBends =
          m.num(di, "second_share") < lab::kSplitShare && m.num(di, "broken_edges") > 0;
      bend += " " +
              cell(ductileBends, fmt("%.0f %% of the ligament cut",
                                     100 * m.num(di, "ligament_broken_fraction"))) +
              " |";
      const double ed = m.num(di, "absorbed_energy_J"), eb = m.num(bi, "absorbed_energy_J");
      energy += " " + cell(ed > eb, fmt("%.2f J against ", ed) + fmt("%.2f J", eb)) + " |";
    }
    s += split + "\n" + bend + "\n" + energy + "\n";
  }
  return s;
}

std::string errorVsTimeRegion(const fs::path& dir, const fs::path& resultsDir, const Part& part) {
  Result<Table> t = readCsv(dir / "error_vs_time.csv");
  if (!t.ok())
    return "Not generated: `" + part.command + "` ended with exit " + std::to_string(part.exit) +
           " (" + t.error().message + ").\n";
  const Table& c = t.value();
  std::string s = "From `" + part.command + "` (" + linkPath(dir, resultsDir) +
                  "/error_vs_time.csv). Error: |x - x_ref| / |x_ref - X| after the last frame, "
                  "against the full-Newton reference and against the direct solver.\n\n";
  s +=
      "| setting | ms per frame | CPU ms per frame | error vs reference | error vs direct | volume "
      "gain [%] | linear iterations per frame | flagged frames |\n";
  s += "|---|---|---|---|---|---|---|---|\n";
  for (size_t r = 0; r < c.rows.size(); ++r) {
    if (c.at(r, "ok") != "1") {
      s += "| " + c.at(r, "setting") + " | failed | | | | | | |\n";
      continue;
    }
    s += "| " + c.at(r, "setting") + " | " + fmt("%.1f", c.num(r, "ms_per_frame")) + " | " +
         fmt("%.1f", c.num(r, "cpu_ms_per_frame")) + " | " +
         fmt("%.2e", c.num(r, "rel_displacement_error")) + " | " +
         fmt("%.2e", c.num(r, "rel_error_vs_direct")) + " | " +
         fmt("%.3f", c.num(r, "volume_gain_pct")) + " | " +
         fmt("%.1f", c.num(r, "linear_iterations_per_frame")) + " | " + c.at(r, "flagged_frames") +
         " |\n";
  }
  s += "\n![Error against run time](" + linkPath(dir / "error_vs_time.svg", resultsDir) + ")\n";
  return s;
}

std::string benchRegion(const fs::path& csv, const fs::path& svg, const fs::path& resultsDir,
                        const Part& part) {
  Result<Table> t = readCsv(csv);
  if (!t.ok() || t.value().rows.empty())
    return "Not generated: `" + part.command + "` ended with exit " + std::to_string(part.exit) +
           (t.ok() ? " and printed no rows" : " (" + t.error().message + ")") + ".\n";
  const Table& c = t.value();
  std::string s = "From `" + part.command + "` (" + linkPath(csv, resultsDir) +
                  "): ms per frame on this machine's CPU, each case at every thread count in "
                  "the same run (speed-up: the 1-thread frame time over this one; on a machine "
                  "whose cores other jobs share it understates the code's), against the "
                  "thesis's fps on one RTX 2060 GPU (table 6.2). CPU ms: the process's CPU time "
                  "per frame over all threads, which other jobs do not stretch; residual cut: "
                  "per V-cycle on the first step (multigrid); unconverged: frames whose linear "
                  "solve stopped at its cap.\n\n";
  s += "| case | solver | tets | threads | ms per frame | CPU ms per frame | fps | speed-up over 1 "
       "thread | elements | assembly | solve | fracture | linear iterations | residual cut per "
       "V-cycle | unconverged frames | thesis GPU fps |\n";
  s += "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  // "-" where the column is missing or empty, and for a residual cut of 0, which bench
  // multigrid writes for a solver without V-cycles.
  const auto opt = [&c](size_t r, const char* name) {
    if (c.col(name) < 0 || c.at(r, name).empty()) return std::string("-");
    if (std::string(name) == "vcycle_reduction" && !(c.num(r, name) > 0)) return std::string("-");
    return c.at(r, name);
  };
  PlotPanel panel{"Frame time against size", "tets", "ms per frame", true, true, {}};
  const char* colours[] = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e"};
  std::map<std::string, size_t> seriesOf;
  for (size_t r = 0; r < c.rows.size(); ++r) {
    s += "| " + c.at(r, "case") + " | " + c.at(r, "solver") + " | " + c.at(r, "tets") + " | " +
         c.at(r, "threads") + " | " + c.at(r, "ms_frame") + " | " + opt(r, "cpu_ms_frame") + " | " +
         c.at(r, "fps") + " | " + opt(r, "speedup") + " | " + c.at(r, "ms_elements") + " | " +
         c.at(r, "ms_assembly") + " | " + c.at(r, "ms_solve") + " | " + c.at(r, "ms_fracture") +
         " | " + c.at(r, "linear_iterations") + " | " + opt(r, "vcycle_reduction") + " | " +
         opt(r, "unconverged_frames") + " | " + c.at(r, "thesis_gpu_fps") + " |\n";
    const std::string key = c.at(r, "solver") + ", " + c.at(r, "threads") + " thread(s)";
    if (!seriesOf.count(key)) {
      seriesOf[key] = panel.series.size();
      panel.series.push_back({key, colours[panel.series.size() % 4], {}});
    }
    panel.series[seriesOf[key]].points.push_back({c.num(r, "tets"), c.num(r, "ms_frame"), ""});
  }
  PlotSeries thesis{"thesis, RTX 2060 (table 6.2)", "#000000", {}};
  std::vector<std::string> cases;
  for (size_t r = 0; r < c.rows.size(); ++r)
    if (c.num(r, "thesis_gpu_fps") > 0 &&
        std::find(cases.begin(), cases.end(), c.at(r, "case")) == cases.end()) {
      cases.push_back(c.at(r, "case"));
      thesis.points.push_back(
          {c.num(r, "tets"), 1000 / c.num(r, "thesis_gpu_fps"), c.at(r, "case")});
    }
  if (!thesis.points.empty()) panel.series.push_back(thesis);
  if (writeSvg(svg.string(), {panel}, "graphfrac bench multigrid on " + cpuText()).ok())
    s += "\n![Frame time against size](" + linkPath(svg, resultsDir) + ")\n";
  return s;
}

// bench scenes' CSV: the fixed 4k-680k scene list with fracture off and on.
std::string benchScenesRegion(const fs::path& csv, const fs::path& resultsDir, const Part& part) {
  Result<Table> t = readCsv(csv);
  if (!t.ok() || t.value().rows.empty())
    return "Not generated: `" + part.command + "` ended with exit " + std::to_string(part.exit) +
           (t.ok() ? " and printed no rows" : " (" + t.error().message + ")") + ".\n";
  const Table& c = t.value();
  std::string s =
      "From `" + part.command + "` (" + linkPath(csv, resultsDir) + ", and " +
      linkPath(fs::path(csv).replace_extension(".json"), resultsDir) +
      " with the same rows): ms per frame and per stage on one CPU thread, the process's peak "
      "resident MB over the case (VmHWM, reset per case when the kernel allows: peak reset 0 "
      "means the peak since the process started), and the solver error |x - x_ref| / |x_ref - "
      "X0| after the last frame against the same frames with every linear system solved by "
      "multigrid-preconditioned CG to a true relative residual of 1e-12; where the reference "
      "stopped short of that, the residual it reached is in brackets. Broken: edges broken "
      "after the last frame (reference run's in brackets).\n\n";
  s += "| case | fracture | tets | frames | ms per frame | fps | elements | assembly | solve | "
       "fracture ms | other | linear iterations | peak MB | peak reset | solver error | broken "
       "edges |\n";
  s += "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (size_t r = 0; r < c.rows.size(); ++r) {
    const bool withRef = c.num(r, "solver_error") >= 0;
    const bool refShort = withRef && c.num(r, "reference_residual") > 1e-12;
    s += "| " + c.at(r, "case") + " | " + (c.at(r, "fracture") == "1" ? "on" : "off") + " | " +
         c.at(r, "tets") + " | " + c.at(r, "frames") + " | " + c.at(r, "ms_frame") + " | " +
         c.at(r, "fps") + " | " + c.at(r, "ms_elements") + " | " + c.at(r, "ms_assembly") + " | " +
         c.at(r, "ms_solve") + " | " + c.at(r, "ms_fracture") + " | " + c.at(r, "ms_other") +
         " | " + c.at(r, "linear_iterations") + " | " + c.at(r, "peak_mb") + " | " +
         c.at(r, "peak_reset") + " | " + (withRef ? c.at(r, "solver_error") : "-") +
         (refShort ? " (reference " + c.at(r, "reference_residual") + ")" : std::string()) + " | " +
         c.at(r, "broken_edges") +
         (withRef ? " (" + c.at(r, "broken_edges_reference") + ")" : std::string()) + " |\n";
  }
  return s;
}

const char* kFlagNames[] = {"NotConverged", "NanContained", "InvalidInput", "LineSearchFailed",
                            "ContactSwept"};

std::string shorten(const std::string& s, size_t n) {
  return s.size() <= n ? s : s.substr(0, n) + " ...";
}

// Per case of the matrix (stability.csv, one row per run), in RESULTS.md's columns.
std::string stabilityRegion(const fs::path& csv, const Part& part) {
  if (part.exit < 0) return "Not run: " + part.note + ".\n";
  Result<Table> t = readCsv(csv);
  if (!t.ok() || t.value().rows.empty())
    return notGenerated(part,
                        t.ok() ? std::string("no rows in ") + csv.string() : t.error().message);
  const Table& c = t.value();
  struct Agg {
    int passed = 0, known = 0, failed = 0, skippedCpu = 0, skippedOther = 0;
    unsigned flags = 0;
  };
  std::vector<std::string> order;
  std::map<std::string, Agg> agg;
  std::map<std::string, int> skipReasons;
  std::string known, failed;
  for (size_t r = 0; r < c.rows.size(); ++r) {
    const std::string kase = c.at(r, "case"), outcome = c.at(r, "outcome");
    if (!agg.count(kase)) order.push_back(kase);
    Agg& a = agg[kase];
    const bool cpu = c.at(r, "backend") == "Cpu";
    const std::string what = kase + " " + c.at(r, "material") + " " + c.at(r, "damage") + " " +
                             c.at(r, "solver") + " " + c.at(r, "backend");
    if (outcome == "skipped") {
      ++(cpu ? a.skippedCpu : a.skippedOther);
      ++skipReasons[c.at(r, "backend") + ": " + shorten(c.at(r, "message"), 200)];
      continue;
    }
    if (outcome == "passed" && cpu) ++a.passed;
    if (outcome == "known_failure") {
      a.known += cpu;
      known += "- " + what + ": " + shorten(c.at(r, "message"), 400) + "\n";
    }
    if (outcome == "failed") {
      a.failed += cpu;
      failed += "- " + what + ": " + shorten(c.at(r, "message"), 400) + "\n";
    }
    const double flags = c.num(r, "flags");
    if (std::isfinite(flags)) a.flags |= unsigned(flags);
  }
  std::string s =
      "| case | CPU runs: pass / known failure / failed | skipped: CPU, other backends | flags "
      "seen (all with a message) |\n|---|---|---|---|\n";
  for (const std::string& k : order) {
    const Agg& a = agg[k];
    std::string flags;
    for (int b = 0; b < 5; ++b)
      if (a.flags & (1u << b)) flags += (flags.empty() ? "" : ", ") + std::string(kFlagNames[b]);
    s += "| " + k + " | " + std::to_string(a.passed) + " / " + std::to_string(a.known) + " / " +
         std::to_string(a.failed) + " | " + std::to_string(a.skippedCpu) + ", " +
         std::to_string(a.skippedOther) + " | " + (flags.empty() ? "none" : flags) + " |\n";
  }
  s += "\nFrom `" + part.command + "` (exit " + std::to_string(part.exit) + ", " +
       fmt("%.0f s", part.seconds) + "; one row per run, with its energy and step figures, in " +
       csv.filename().string() + ").\n";
  if (!skipReasons.empty()) {
    s += "\nSkipped runs, by reason:\n\n";
    for (const auto& [why, n] : skipReasons) s += "- " + std::to_string(n) + " x " + why + "\n";
  }
  if (!known.empty())
    s += "\nKnown failures (reported as skips; GF_STABILITY_STRICT=1 fails them):\n\n" + known;
  if (!failed.empty()) s += "\nFailed runs:\n\n" + failed;
  return s;
}

// "1/240 s" for dt = 0.00417.
std::string dtText(double dt) {
  const double inv = 1 / dt;
  return std::abs(inv - std::round(inv)) < 0.05 * inv ? fmt("1/%.0f s", inv) : fmt("%g s", dt);
}

std::string methodName(const std::string& m) {
  static const std::map<std::string, std::string> names = {
      {"graphfrac-multigrid", "graphfrac multigrid"},
      {"graphfrac-direct", "graphfrac direct"},
      {"graphfrac-pcg", "graphfrac PCG"},
      {"bullet-implicit", "Bullet implicit"},
      {"bullet-explicit", "Bullet explicit"},
      {"bullet-implicit-linear", "Bullet implicit, linear"}};
  const auto it = names.find(m);
  return it == names.end() ? m : it->second;
}

using NumberGrid = std::map<std::string, std::map<std::string, double>>;

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Each Bullet run over each graphfrac solver on the same case and dt: step time and error
// (issue 19 asks for the ratios), and the same for the medians of the stable sweep runs.
std::string peerRatios(const std::vector<std::string>& keys,
                       const std::vector<std::string>& methods, NumberGrid& ms, NumberGrid& err,
                       std::map<std::string, std::map<std::string, std::vector<double>>>& sweep) {
  std::vector<std::string> ours, theirs;
  for (const std::string& m : methods) (m.rfind("graphfrac", 0) == 0 ? ours : theirs).push_back(m);
  if (ours.empty() || theirs.empty()) return "";
  std::string s =
      "\nRatios, Bullet over graphfrac (ms per step; error), where both ran stable:\n\n";
  s += "| case, dt | Bullet run |";
  std::string rule = "|---|---|";
  for (const std::string& o : ours) {
    s += " over " + o + " |";
    rule += "---|";
  }
  s += "\n" + rule + "\n";
  int rows = 0;
  for (const std::string& key : keys)
    for (const std::string& t : theirs) {
      if (!ms[key].count(t)) continue;
      s += "| " + key + " | " + t + " |";
      for (const std::string& o : ours) {
        std::string c = "-";
        if (ms[key].count(o)) {
          c = fmt("%.2fx; ", ms[key][t] / ms[key][o]);
          c += err[key][o] > 0 ? fmt("%.3gx", err[key][t] / err[key][o]) : std::string("-");
        }
        s += ' ';
        s += c;
        s += " |";
      }
      s += "\n";
      ++rows;
    }
  if (rows == 0) s += "\nNo Bullet run was stable on a case of this table.\n";
  // The sweep's medians over its stable runs: a time ratio less tied to one E and dt.
  std::string med;
  for (const auto& [kase, byMethod] : sweep) {
    std::string line;
    for (const std::string& m : methods) {
      const auto it = byMethod.find(m);
      if (it == byMethod.end()) continue;
      line += (line.empty() ? "" : ", ") + m + fmt(" %.2f ms", median(it->second)) + " (" +
              std::to_string(it->second.size()) + " of its runs)";
    }
    const auto base = byMethod.find(ours.front());
    if (base != byMethod.end())
      for (const std::string& t : theirs) {
        const auto it = byMethod.find(t);
        if (it != byMethod.end())
          line += "; " + t + " / " + ours.front() +
                  fmt(" %.2fx", median(it->second) / median(base->second));
      }
    med += "- " + kase + ": " + line + "\n";
  }
  if (!med.empty())
    s += "\nMedian ms per step over each method's stable runs of the sweep of E and dt (where "
         "two methods' counts differ, their ratio compares different sets of E and dt):\n\n" +
         med;
  return s;
}

// bench peer's CSV: the step time and error table (`range` false) or the stable runs over its
// sweep of E and dt (`range` true), in RESULTS.md's columns.
std::string peerRegion(const fs::path& csv, const Part& part, bool range) {
  if (part.exit < 0) return "Not run: " + part.note + ".\n";
  Result<Table> t = readCsv(csv);
  if (!t.ok() || t.value().rows.empty())
    return notGenerated(part, t.ok() ? std::string("no rows") : t.error().message);
  const Table& c = t.value();
  std::vector<std::string> methods, keys, setups;
  std::map<std::string, std::map<std::string, std::string>> cell;
  std::map<std::string, std::map<std::string, std::pair<int, int>>> stable;   // method, case
  NumberGrid ms, err;                                                         // key, method
  std::map<std::string, std::map<std::string, std::vector<double>>> sweepMs;  // case, method
  for (size_t r = 0; r < c.rows.size(); ++r) {
    const std::string kase = c.at(r, "case"), method = methodName(c.at(r, "method")),
                      outcome = c.at(r, "outcome");
    if (std::find(methods.begin(), methods.end(), method) == methods.end())
      methods.push_back(method);
    if (kase.size() > 6 && kase.compare(kase.size() - 6, 6, "-sweep") == 0) {
      auto& st = stable[method][kase.substr(0, kase.size() - 6)];
      ++st.second;
      st.first += outcome == "stable";
      if (outcome == "stable" && std::isfinite(c.num(r, "ms_per_step")))
        sweepMs[kase.substr(0, kase.size() - 6)][method].push_back(c.num(r, "ms_per_step"));
      continue;
    }
    const std::string key = kase + ", " + dtText(c.num(r, "dt_s"));
    const std::string setup = kase + ": E " + c.at(r, "E_Pa") + " Pa, " + c.at(r, "tets") + " tets";
    if (std::find(keys.begin(), keys.end(), key) == keys.end()) keys.push_back(key);
    if (std::find(setups.begin(), setups.end(), setup) == setups.end()) setups.push_back(setup);
    if (outcome == "stable") {
      ms[key][method] = c.num(r, "ms_per_step");
      err[key][method] = c.num(r, "error");
    }
    cell[key][method] =
        outcome == "stable"
            ? fmt("%.2f ms, ", c.num(r, "ms_per_step")) + fmt("%.2e", c.num(r, "error"))
        : outcome == "unstable" ? "unstable (" + c.at(r, "inverted_tets") + " tets inverted)"
                                : outcome;
  }
  std::string s;
  if (!range) {
    s = "| case, dt |";
    std::string rule = "|---|";
    for (const std::string& m : methods) {
      s += " " + m + " |";
      rule += "---|";
    }
    s += "\n" + rule + "\n";
    for (const std::string& key : keys) {
      s += "| " + key + " |";
      for (const std::string& m : methods) {
        const auto it = cell[key].find(m);
        s += ' ';
        s += it == cell[key].end() ? std::string("-") : it->second;
        s += " |";
      }
      s += "\n";
    }
    s += "\nFrom `" + part.command + "` (" + csv.filename().string() + "): ms per step, error;";
    for (const std::string& setup : setups) s += " " + setup + ";";
    s += " both engines on this machine's CPU, one thread.\n";
    s += peerRatios(keys, methods, ms, err, sweepMs);
    return s;
  }
  if (stable.empty())
    return "Not generated: `" + part.command + "` ran without its sweep of E and dt.\n";
  s = "| method | cantilever: stable runs | drop: stable runs |\n|---|---|---|\n";
  for (const std::string& m : methods) {
    auto frac = [&](const char* k) {
      const auto it = stable[m].find(k);
      return it == stable[m].end()
                 ? std::string("-")
                 : std::to_string(it->second.first) + " / " + std::to_string(it->second.second);
    };
    s += "| " + m + " | " + frac("cantilever") + " | " + frac("drop") + " |\n";
  }
  s += "\nFrom `" + part.command + "` (" + csv.filename().string() + ", the *-sweep rows).\n";
  return s;
}

// Table 4.1 (thesis sec 4.5) for the three laboratory materials; its times ran on the CPU of
// sec 4.4.3, tables 6.1 / 6.2 (sec 6.3) on the GPU named there.
struct ThesisMaterial {
  const char* label;
  const char* scene;                   // under scenes/lab
  double rho, E, nu, strength, yield;  // yield 0: none
  double tets, secondsPerFrame;
};
const ThesisMaterial kTable41[] = {
    {"granite (Brazilian disc)", "brazilian_disc.json", 2.75e3, 4.5e10, 0.33, 9.56e6, 0, 45.8e3,
     0.39},
    {"A516 Gr.70, brittle at -40 C", "charpy_brittle.json", 7.7e3, 2.2e11, 0.28, 6.55e8, 0, 27.8e3,
     0.24},
    {"NVE36, ductile at 23 C", "charpy_ductile.json", 7.7e3, 1.9e11, 0.28, 5.4e8, 8.3e7, 27.8e3,
     0.24},
};
constexpr const char* kThesisCpu = "thesis: Intel i7-9750H CPU, 12 threads (sec 4.4.3)";
constexpr const char* kThesisGpu = "thesis: one RTX 2060 GPU (sec 6.3)";

std::string ratio(double ours, double theirs) {
  return std::isfinite(ours) && theirs != 0 ? fmt("%.3g", ours / theirs) : std::string("-");
}

std::string thesisRegion(const Options& opt, const fs::path& out, const fs::path& evtDir) {
  const std::string ours = "ours: " + cpuText() + ", ";
  std::string s =
      "The thesis's published numbers beside ours, read from this run's files (the lab scenes "
      "and lab/*.csv, error_vs_time.csv, bench_multigrid.csv under " +
      out.string() +
      "). The thesis gives its laboratory comparisons as plots only (figs 4.21, 4.23, 4.25, "
      "6.10), so its outcomes are words.\n\n";
  s += "| quantity | thesis | ours | ours / thesis | hardware |\n|---|---|---|---|---|\n";
  const fs::path labScenes = fs::path(opt.scenes) / "lab";
  for (const ThesisMaterial& m : kTable41) {
    Result<scene::Scene> sc = lab::loadLabScene((labScenes / m.scene).string(), "{}");
    if (!sc.ok() || sc.value().bodies.empty()) {
      s += std::string("| table 4.1, ") + m.label +
           " | | not read: " + (sc.ok() ? std::string("no body") : sc.error().message) +
           " | - | - |\n";
      continue;
    }
    const BodyDef& d = sc.value().bodies[0].def;
    auto row = [&](const char* what, double thesis, double our, const char* f) {
      s += std::string("| table 4.1, ") + m.label + ": " + what + " | " + fmt(f, thesis) + " | " +
           fmt(f, our) + " | " + ratio(our, thesis) + " | input |\n";
    };
    row("density [kg/m^3]", m.rho, d.material.density, "%.4g");
    row("Young's modulus [Pa]", m.E, d.material.youngsModulus, "%.4g");
    row("Poisson's ratio", m.nu, d.material.poissonRatio, "%.3g");
    row("sigma_th [Pa]", m.strength, d.fracture.strength, "%.4g");
    if (m.yield > 0 && d.plasticity.enabled)
      row("sigma_p [Pa]", m.yield, d.plasticity.yieldStress, "%.4g");
    else if (m.yield > 0)
      s += std::string("| table 4.1, ") + m.label + ": sigma_p [Pa] | " + fmt("%.4g", m.yield) +
           " | no plasticity in the scene | - | input |\n";
  }
  // Time per step of the lab runs against table 4.1's sec/frame (its dt is 5e-3 s).
  Result<Table> disc = readCsv(out / "lab" / "brazilian.csv");
  if (disc.ok() && !disc.value().rows.empty()) {
    const Table& b = disc.value();
    const double sps = b.num(0, "seconds") / b.num(0, "steps");
    s += "| table 4.1, granite cylinder: s per frame (thesis dt 5e-3 s; ours the disc's step) | "
         "0.39 (45.8k tets) | " +
         fmt("%.3g", sps) + " (" + b.at(0, "tets") + " tets) | " + ratio(sps, 0.39) + " | " +
         kThesisCpu + "; " + ours + "1 thread |\n";
    s += "| Brazilian disc: 2P / (pi D t) / sigma_th (fig 4.25: a curve, no number) | - | " +
         fmt("%.3f", b.num(0, "ratio")) + " (" + b.at(0, "run") + ") | - | - |\n";
    s += "| Brazilian disc: where the crack starts | near the centre (fig 4.24) | " +
         fmt("%.3f D from the centre", b.num(0, "first_break_from_centre_over_D")) + " | - | - |\n";
  }
  Result<Table> imp = readCsv(out / "lab" / "impact.csv");
  if (imp.ok()) {
    const Table& m = imp.value();
    bool timed = false;
    for (size_t r = 0; r < m.rows.size(); ++r) {
      const std::string test = m.at(r, "test"), material = m.at(r, "material");
      if (!timed) {
        const double sps = m.num(r, "seconds") / m.num(r, "steps");
        s += "| table 4.1, steel bar: s per frame (ours: " + test + " " + material +
             " step) | 0.24 (27.8k tets) | " + fmt("%.3g", sps) + " (" + m.at(r, "tets") +
             " tets) | " + ratio(sps, 0.24) + " | " + kThesisCpu + "; " + ours + "1 thread |\n";
        timed = true;
      }
      const bool brittle = material == "brittle";
      const std::string thesisOutcome =
          brittle ? "splits in two (figs 4.20, 4.22)" : "bends, partly damaged (figs 4.20, 4.22)";
      const double second = m.num(r, "second_share");
      const std::string outcome =
          second >= lab::kSplitShare
              ? fmt("split in two (%.0f %% / ", 100 * m.num(r, "largest_share")) +
                    fmt("%.0f %% of the nodes)", 100 * second)
              : fmt("one piece, %.0f %% of the ligament cut",
                    100 * m.num(r, "ligament_broken_fraction"));
      s += "| " + test + " " + material + " (" + m.at(r, "mesh") + "): outcome | " + thesisOutcome +
           " | " + outcome + fmt(", %.2f J absorbed", m.num(r, "absorbed_energy_J")) +
           " | - | - |\n";
    }
  }
  Result<Table> evt = readCsv(evtDir / "error_vs_time.csv");
  if (evt.ok()) {
    const Table& e = evt.value();
    for (size_t r = 0; r < e.rows.size(); ++r) {
      const std::string setting = e.at(r, "setting");
      if (setting != "reference" && setting.rfind("50/all x", 0) != 0) continue;
      const bool ref = setting == "reference";
      const double thesis = ref ? 4.3 : 19.0;
      s += "| table 6.1, hanging sphere: volume gain [%], " +
           std::string(ref ? "stable Neo-Hookean, converged step"
                           : "Galerkin multigrid " + setting) +
           " | " + fmt("%.1f", thesis) + " | " + fmt("%.3g", e.num(r, "volume_gain_pct")) + " | " +
           ratio(e.num(r, "volume_gain_pct"), thesis) + " | - |\n";
    }
  }
  Result<Table> bench = readCsv(out / "bench_multigrid.csv");
  if (bench.ok()) {
    const Table& b = bench.value();
    for (size_t r = 0; r < b.rows.size(); ++r) {
      if (b.at(r, "solver") != "multigrid (default)") continue;
      const double thesis = b.num(r, "thesis_gpu_fps"), fps = b.num(r, "fps");
      s += "| table 6.2, " + b.at(r, "case") + ": fps (ours " + b.at(r, "tets") + " tets, " +
           b.at(r, "threads") + " thread(s)) | " + fmt("%.1f", thesis) + " | " + fmt("%.2f", fps) +
           " | " + ratio(fps, thesis) + " | " + kThesisGpu + "; " + ours + b.at(r, "threads") +
           " thread(s), no GPU |\n";
    }
  }
  s += "\nOur times are one CPU thread's unless a thread count is given; the thesis's are a "
       "12-thread CPU (chapter 4) and a GPU (chapter 6), so these ratios compare machines as "
       "much as methods.\n";
  return s;
}

// ---- the stability suite ------------------------------------------------------------------

// The gf_stability_tests binary: --stability-bin, else where the build puts it beside this
// program (build/<preset>/tools/graphfrac and build/<preset>/tests/gf_stability_tests).
std::string findStabilityBinary(const Options& opt, std::string& looked) {
  std::vector<fs::path> candidates;
  if (!opt.stabilityBin.empty()) {
    candidates.push_back(opt.stabilityBin);
  } else {
    std::error_code ec;
    const fs::path self = fs::read_symlink("/proc/self/exe", ec);
    if (!ec) {
      candidates.push_back(self.parent_path().parent_path() / "tests" / "gf_stability_tests");
      candidates.push_back(self.parent_path() / "gf_stability_tests");
    }
  }
  for (const fs::path& p : candidates) {
    looked += (looked.empty() ? "" : ", ") + p.string();
    if (::access(p.c_str(), X_OK) == 0) return p.string();
  }
  return {};
}

// Runs the binary with GF_STABILITY_CSV (and GF_FULL_VALIDATION=1 for the full form), its
// output to `log`; returns its exit status (128 + signal when killed).
int runStability(const std::string& bin, const fs::path& csv, const fs::path& log, bool full,
                 std::string& error) {
  std::vector<std::string> env;
  for (char** e = environ; *e; ++e)
    if (std::strncmp(*e, "GF_STABILITY_CSV=", 17) != 0 &&
        std::strncmp(*e, "GF_FULL_VALIDATION=", 19) != 0)
      env.push_back(*e);
  env.push_back("GF_STABILITY_CSV=" + csv.string());
  if (full) env.push_back("GF_FULL_VALIDATION=1");
  std::vector<char*> envp;
  for (std::string& e : env) envp.push_back(e.data());
  envp.push_back(nullptr);
  std::string arg0 = bin;
  char* argv[] = {arg0.data(), nullptr};
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, bin.c_str(), &actions, nullptr, argv, envp.data());
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    error = bin + ": cannot start: " + std::strerror(rc);
    return -1;
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0)
    if (errno != EINTR) {
      error = std::string("waitpid: ") + std::strerror(errno);
      return -1;
    }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

#ifdef GF_CLI_HAS_BULLET_SOFTBODY
constexpr bool kHasBullet = true;
#else
constexpr bool kHasBullet = false;
#endif

int reportAll(int argc, char** argv) {
  Options opt;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::fputs(kAllUsage, stdout);
      return kExitOk;
    }
    if (a == "--quick") {
      opt.quick = true;
    } else if (a == "--reuse") {
      opt.reuse = true;
    } else if (a == "--only") {
      if (i + 1 >= argc ||
          std::find(kParts.begin(), kParts.end(), std::string(argv[i + 1])) == kParts.end()) {
        std::fprintf(stderr,
                     "graphfrac report all: --only: expected lab, error-vs-time, bench, "
                     "stability or peer\n\n%s",
                     kAllUsage);
        return kExitUsage;
      }
      opt.only = argv[++i];
    } else if (a == "--out" || a == "--results" || a == "--scenes" || a == "--stability-bin") {
      if (i + 1 >= argc || !*argv[i + 1]) {
        std::fprintf(stderr, "graphfrac report all: %s: expected a path\n\n%s", a.c_str(),
                     kAllUsage);
        return kExitUsage;
      }
      (a == "--out"       ? opt.out
       : a == "--results" ? opt.results
       : a == "--scenes"  ? opt.scenes
                          : opt.stabilityBin) = argv[++i];
    } else {
      std::fprintf(stderr, "graphfrac report all: unknown argument %s\n\n%s", a.c_str(), kAllUsage);
      return kExitUsage;
    }
  }
  if (opt.reuse && opt.only.empty()) {
    std::fprintf(stderr, "graphfrac report all: --reuse: needs --only PART\n\n%s", kAllUsage);
    return kExitUsage;
  }
  // The markers first: a page that cannot take the results stops the run before it starts.
  Result<std::string> page = readFile(opt.results);
  if (!page.ok()) {
    std::fprintf(stderr, "graphfrac report all: %s\n", page.error().message.c_str());
    return kExitOutput;
  }
  if (Result<MarkedText> m = parseMarkedText(opt.results, page.value(), kRegions); !m.ok()) {
    std::fprintf(stderr, "graphfrac report all: %s (the file is unchanged)\n",
                 m.error().message.c_str());
    return kExitOutput;
  }
  // The full form writes where docs/RESULTS.md's hand-written links point; the quick form
  // elsewhere, so CI never overwrites the published files.
  if (opt.out.empty()) opt.out = opt.quick ? "out/report-quick" : "docs/reports";
  const fs::path out(opt.out), resultsDir = fs::path(opt.results).parent_path(),
                               logs = out / "logs";
  std::error_code ec;
  if (!opt.reuse) fs::create_directories(logs, ec);  // --reuse runs nothing, so logs nothing
  if (ec) {
    std::fprintf(stderr, "graphfrac report all: cannot create %s: %s\n", logs.string().c_str(),
                 ec.message().c_str());
    return kExitOutput;
  }
  std::vector<std::string> selfArgs{"report", "all"};
  for (int i = 2; i < argc; ++i) selfArgs.push_back(argv[i]);
  const auto t0 = std::chrono::steady_clock::now();
  const fs::path scenes(opt.scenes);
  const std::string loadBefore = loadAverage();
  Part lab{"lab", "", -1, 0, ""}, evt{"error vs time", "", -1, 0, ""},
      bench{"frame-time bench", "", -1, 0, ""}, benchScenes{"scene-list bench", "", -1, 0, ""},
      stab{"stability suite", "", -1, 0, ""}, peer{"Bullet comparison", "", -1, 0, ""};
  auto wanted = [&](const char* part) { return opt.only.empty() || opt.only == part; };
  // --reuse: the part's files must be there (a region built from nothing would say "not
  // generated"); the part counts as run, with the command that makes the files.
  auto reuse = [&](Part& part, const std::string& command,
                   const std::vector<fs::path>& files) -> bool {
    part.command = command;
    for (const fs::path& f : files)
      if (!fs::exists(f)) {
        std::fprintf(stderr, "graphfrac report all: --reuse: %s is missing (run `%s` first)\n",
                     f.string().c_str(), command.c_str());
        return false;
      }
    part.exit = 0;
    part.note = "its files reused";
    return true;
  };

  // The quick form stops the impacts 0.5 mm past contact: the brittle bars crack within that,
  // the ductile ones have only begun to bend (their energies are then far below the full run's).
  const double stopMm = opt.quick ? 0.5 : 4;
  if (wanted("lab")) {
    std::vector<std::string> labArgs{
        "report", "lab", "--out", (out / "lab").string(), "--scenes", (scenes / "lab").string()};
    if (opt.quick) labArgs.insert(labArgs.end(), {"--quick", "--stop-after", "0.5"});
    if (opt.reuse) {
      if (!reuse(lab, commandLine(labArgs),
                 {out / "lab" / "brazilian.csv", out / "lab" / "impact.csv"}))
        return kExitOutput;
    } else {
      runPart(lab, runLabReport, labArgs, logs / "lab.log");
    }
  }

  // The hanging sphere: table 6.1's volume gain and table 6.2's 35k-tet case in one scene.
  const fs::path evtDir = out / "hanging_sphere";
  if (wanted("error-vs-time")) {
    std::vector<std::string> evtArgs{
        "report", "error-vs-time", (scenes / "hanging_sphere.json").string(),
        "--out",  evtDir.string(), "--threads",
        "1"};
    if (opt.quick)
      evtArgs.insert(evtArgs.end(),
                     {"--frames", "2", "--levels", "50/all", "--cycles", "2", "--pcg-caps", "30"});
    else
      evtArgs.insert(evtArgs.end(), {"--levels", "50/all,256/all,auto"});
    if (opt.reuse) {
      if (!reuse(evt, commandLine(evtArgs), {evtDir / "error_vs_time.csv"})) return kExitOutput;
    } else {
      runPart(evt, runReportCommand, evtArgs, logs / "error_vs_time.log");
    }
  }

  // bench multigrid: the thesis's chapter-6 bodies (4k to 160k tets), a fixed list, each at 1
  // and 2 threads in the same run (issue 14), so the speed-up is measured under one load.
  if (wanted("bench")) {
    std::vector<std::string> benchArgs{"bench",     "multigrid", "--frames", opt.quick ? "2" : "10",
                                       "--threads", "1,2"};
    if (opt.quick) benchArgs.insert(benchArgs.end(), {"--only", "hinged beam"});
    if (opt.reuse) {
      if (!reuse(bench, commandLine(benchArgs), {out / "bench_multigrid.csv"})) return kExitOutput;
    } else {
      runPart(bench, runBenchCommand, benchArgs, out / "bench_multigrid.csv");
    }
    // bench scenes: the fixed 4k-680k list, fracture off and on, with peak memory and the
    // solver error against a converged reference (the 680k box runs one frame).
    std::vector<std::string> scenesArgs{"bench", "scenes", "--json",
                                        (out / "bench_scenes.json").string()};
    if (opt.quick) scenesArgs.insert(scenesArgs.end(), {"--frames", "2", "--only", "hinged beam"});
    if (opt.reuse) {
      if (!reuse(benchScenes, commandLine(scenesArgs), {out / "bench_scenes.csv"}))
        return kExitOutput;
    } else {
      runPart(benchScenes, runBenchCommand, scenesArgs, out / "bench_scenes.csv");
    }
  }

  if (wanted("stability")) {
    const std::string env = std::string(opt.quick ? "" : "GF_FULL_VALIDATION=1 ") +
                            "GF_STABILITY_CSV=" + (out / "stability.csv").string() + " ";
    std::string looked;
    const std::string stabBin = opt.reuse ? "" : findStabilityBinary(opt, looked);
    if (opt.reuse) {
      if (!reuse(stab, env + "gf_stability_tests", {out / "stability.csv"})) return kExitOutput;
    } else if (stabBin.empty()) {
      stab.note =
          "gf_stability_tests was not found (looked for " + looked +
          "); build it with `cmake --build --preset release --target gf_stability_tests` or "
          "name it with --stability-bin";
    } else {
      std::error_code rec;
      const fs::path rel = fs::relative(stabBin, fs::current_path(rec), rec);
      stab.command = env + (rec || rel.empty() ? stabBin : "./" + rel.generic_string());
      std::printf("report all: %s ...\n", stab.command.c_str());
      std::fflush(stdout);
      const auto ts = std::chrono::steady_clock::now();
      std::string error;
      stab.exit =
          runStability(stabBin, out / "stability.csv", logs / "stability.log", !opt.quick, error);
      stab.seconds = secondsSince(ts);
      if (stab.exit < 0)
        stab.note = error;
      else if (stab.exit != 0)
        stab.note = "a run failed: " + (logs / "stability.log").string();
      std::printf("report all:   exit %d after %.1f s\n", stab.exit, stab.seconds);
    }
  }

  if (wanted("peer")) {
    // The quick form: the smallest meshes and a quarter second per run, sweep included.
    std::vector<std::string> peerArgs{"bench", "peer"};
    if (opt.quick) peerArgs.insert(peerArgs.end(), {"--cells", "1", "--seconds", "0.25"});
    if (opt.reuse) {
      if (!reuse(peer, commandLine(peerArgs), {out / "peer.csv"})) return kExitOutput;
    } else if (opt.quick && !kHasBullet) {
      peer.note =
          "this graphfrac was built without Bullet's soft bodies, and --quick skips the "
          "comparison then";
    } else {
      runPart(peer, runBenchCommand, peerArgs, out / "peer.csv");
    }
  }
  const double seconds = secondsSince(t0);
  const bool all = opt.only.empty();

  std::map<std::string, std::string> regions;
  std::vector<Part> parts{lab, evt, bench, benchScenes, stab, peer};
  // --only: the header and the thesis's table describe a full run (the latter reads every
  // part's files), and the other parts' regions stay as they are.
  if (all)
    regions["header"] =
        headerRegion(opt, parts, commandLine(selfArgs), seconds, loadBefore, loadAverage());
  if (all) regions["thesis"] = thesisRegion(opt, out, evtDir);
  if (wanted("lab")) {
    regions["lab-brazilian"] = labBrazilianRegion(out / "lab", resultsDir, lab);
    regions["lab-charpy"] = labImpactRegion(out / "lab", resultsDir, lab, "charpy", stopMm);
    regions["lab-izod"] = labImpactRegion(out / "lab", resultsDir, lab, "izod", stopMm);
    regions["lab-acceptance"] = labAcceptanceRegion(out / "lab", lab);
  }
  if (wanted("error-vs-time"))
    regions["error-vs-time"] = errorVsTimeRegion(evtDir, resultsDir, evt);
  if (wanted("bench"))
    regions["bench"] =
        benchRegion(out / "bench_multigrid.csv", out / "bench_multigrid.svg", resultsDir, bench);
  if (wanted("bench"))
    regions["bench-scenes"] = benchScenesRegion(out / "bench_scenes.csv", resultsDir, benchScenes);
  if (wanted("stability")) regions["stability"] = stabilityRegion(out / "stability.csv", stab);
  if (wanted("peer")) {
    regions["peer-time"] = peerRegion(out / "peer.csv", peer, false);
    regions["peer-range"] = peerRegion(out / "peer.csv", peer, true);
  }

  // The page again: it may have been edited during a long run; its markers are checked again.
  Result<std::string> now = readFile(opt.results);
  Result<MarkedText> marked = now.ok() ? parseMarkedText(opt.results, now.value(), kRegions)
                                       : Result<MarkedText>(now.error());
  if (!marked.ok()) {
    std::fprintf(stderr, "graphfrac report all: %s (the file is unchanged)\n",
                 marked.error().message.c_str());
    return kExitOutput;
  }
  const std::string text = spliceRegions(marked.value(), regions);
  const std::string tmp = opt.results + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    f << text;
    f.close();
    if (!f) {
      std::fprintf(stderr, "graphfrac report all: cannot write %s\n", tmp.c_str());
      fs::remove(tmp, ec);
      return kExitOutput;
    }
  }
  fs::rename(tmp, opt.results, ec);
  if (ec) {
    std::fprintf(stderr, "graphfrac report all: cannot replace %s: %s\n", opt.results.c_str(),
                 ec.message().c_str());
    fs::remove(tmp, ec);
    return kExitOutput;
  }
  std::printf("report all: wrote %zu regions of %s and the files under %s in %.0f s\n",
              regions.size(), opt.results.c_str(), opt.out.c_str(), seconds);
  for (const Part& p : parts)
    if (p.exit == kExitScene) return kExitScene;
  // Error against time flags the capped solver settings it is there to measure: exit 3 is its
  // normal outcome. The Bullet comparison is left out of --quick on purpose without Bullet.
  // The --only name of each entry of `parts` (the bench part runs two commands).
  const char* partOf[] = {"lab", "error-vs-time", "bench", "bench", "stability", "peer"};
  for (size_t i = 0; i < parts.size(); ++i) {
    const Part& p = parts[i];
    if (!wanted(partOf[i])) continue;  // --only: the others were not asked for
    if (p.exit == kExitOk || (i == 1 && p.exit == kExitFlagged) ||
        (i == 5 && p.exit < 0 && opt.quick))
      continue;
    return kExitFlagged;
  }
  return kExitOk;
}

}  // namespace

int runAllReport(int argc, char** argv) { return reportAll(argc, argv); }

}  // namespace gf::cli
