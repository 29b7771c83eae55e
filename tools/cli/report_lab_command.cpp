// `graphfrac report lab [--quick] [--out DIR] [--scenes DIR]`: the laboratory tests of thesis
// sec 2.5 / 4.5.5 run as experiments (report_lab.h), each at two mesh resolutions (--quick: the
// coarse one), the Brazilian disc also at half its loading rate. Writes the load-displacement
// curves (SVG, and CSV per run) and a summary (CSV and markdown, with the acceptance checks of
// issue 19) to DIR.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "cli/args.h"
#include "cli/commands.h"
#include "cli/csv_writer.h"
#include "cli/report_lab.h"
#include "cli/svg_plot.h"

namespace gf::cli {
namespace {

namespace fs = std::filesystem;

constexpr const char* kLabUsage =
    "usage: graphfrac report lab [--quick] [--only brazilian|charpy|izod] [--out DIR]\n"
    "                            [--scenes DIR] [--crack-refine N] [--stop-after MM]\n"
    "\n"
    "Runs the laboratory tests of scenes/lab (or --scenes DIR) and writes to DIR (default\n"
    "out/lab): brazilian.svg, charpy.svg, izod.svg (load-displacement; Charpy also load-CMOD),\n"
    "brazilian.csv, impact.csv, summary.md and curves/<run>.csv.\n"
    "  Brazilian disc  granite, jaws at the scene's rate and at half of it; failure load P,\n"
    "                  2 P / (pi D t) against sigma_th, where the first edge broke, whether\n"
    "                  the crack follows the loaded diameter\n"
    "  Charpy, Izod    brittle A516 Gr.70 (-40 C) and ductile NVE36 struck by a 20 kg striker;\n"
    "                  peak load, displacement at fracture, absorbed energy, the outcome\n"
    "Each test runs at two mesh resolutions; --quick runs the coarse one only (CI's short form);\n"
    "--only runs one test. --crack-refine N (default 10): the disc's steps are N times shorter\n"
    "once its first edge breaks, so its crack can run before the jaws load it further (1: off).\n"
    "--stop-after MM (default 4): the impact runs stop MM of striker travel past contact\n"
    "(`report all --quick` uses 0.5 to fit CI's budget; the ductile energies are then smaller).\n";

struct Resolution {
  const char* label;
  const char* patch;  // merged into bodies[0].mesh
};

constexpr Resolution kDisc[2] = {
    {"64 rim nodes", R"({"segments": 64, "rings": 8, "layers": 8})"},
    {"96 rim nodes", R"({"segments": 96, "rings": 12, "layers": 12})"}};
constexpr Resolution kBar[2] = {{"68x8x4 cells", R"({"cells": [68, 8, 4]})"},
                                {"68x12x8 cells", R"({"cells": [68, 12, 8]})"}};

const std::vector<std::string> kImpactColumns{"test",
                                              "material",
                                              "mesh",
                                              "tets",
                                              "striker_speed_m_s",
                                              "first_break_load_N",
                                              "first_break_displacement_m",
                                              "peak_load_N",
                                              "displacement_at_peak_m",
                                              "displacement_at_fracture_m",
                                              "displacement_at_split_m",
                                              "energy_to_fracture_J",
                                              "absorbed_energy_J",
                                              "broken_edges",
                                              "fragments",
                                              "largest_share",
                                              "second_share",
                                              "ligament_broken_fraction",
                                              "max_cmod_m",
                                              "steps",
                                              "flagged_steps",
                                              "seconds"};

const char* kColours[] = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b"};

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

Result<void> writeCurve(const fs::path& path, const lab::Curve& c) {
  CsvWriter csv;
  const bool cmod = !c.cmod.empty();
  std::vector<std::string> cols{"displacement_m", "load_N"};
  if (cmod) cols.push_back("cmod_m");
  Result<void> r = csv.open(path.string(), cols);
  for (size_t i = 0; r.ok() && i < c.load.size(); ++i) {
    std::vector<CsvWriter::Value> row{c.displacement[i], c.load[i]};
    if (cmod) row.push_back(c.cmod[i]);
    r = csv.row(row);
  }
  return r.ok() ? csv.close() : r;
}

// Samples up to striker travel `upTo` (the fracture: afterwards the striker knocks the halves
// about, spikes an order of magnitude above the bar's load that would flatten the curves;
// curves/*.csv keeps them).
PlotSeries curveSeries(const std::string& name, int colour, const lab::Curve& c, bool againstCmod,
                       double xScale, double upTo = 1e300) {
  PlotSeries s;
  s.name = name;
  s.colour = kColours[colour % 6];
  s.line = true;
  for (size_t i = 0; i < c.load.size() && c.displacement[i] <= upTo; ++i)
    s.points.push_back(
        {xScale * (againstCmod ? c.cmod[i] : c.displacement[i]), 1e-3 * c.load[i], ""});
  return s;
}

int labReport(int argc, char** argv) {
  bool quick = false;
  std::string out = "out/lab", scenes = "scenes/lab", only;
  int crackRefine = 10;
  lab::ImpactSetup impactSetup;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") {
      quick = true;
    } else if (a == "--only") {
      only = i + 1 < argc ? argv[++i] : "";
      if (only != "brazilian" && only != "charpy" && only != "izod") {
        std::fprintf(stderr, "graphfrac report lab: --only: expected brazilian, charpy or izod\n");
        return kExitUsage;
      }
    } else if (a == "--crack-refine") {
      char* end = nullptr;
      const long n = i + 1 < argc ? std::strtol(argv[++i], &end, 10) : 0;
      if (n < 1 || n > 1000 || !end || *end != '\0') {
        std::fprintf(stderr,
                     "graphfrac report lab: --crack-refine: expected an integer in [1, 1000]\n");
        return kExitUsage;
      }
      crackRefine = int(n);
    } else if (a == "--stop-after") {
      double mm = 0;
      if (i + 1 >= argc || !parseDouble(argv[++i], mm) || !(mm > 0) || mm > 100) {
        std::fprintf(stderr,
                     "graphfrac report lab: --stop-after: expected millimetres in (0, 100]\n");
        return kExitUsage;
      }
      impactSetup.maxDisplacement = 1e-3 * mm;
    } else if (a == "--out" || a == "--scenes") {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "graphfrac report lab: %s: expected a directory\n", a.c_str());
        return kExitUsage;
      }
      (a == "--out" ? out : scenes) = argv[++i];
    } else if (a == "--help" || a == "-h") {
      std::fputs(kLabUsage, stdout);
      return kExitOk;
    } else {
      std::fprintf(stderr, "graphfrac report lab: unknown argument %s\n\n%s", a.c_str(), kLabUsage);
      return kExitUsage;
    }
  }
  std::error_code ec;
  fs::create_directories(fs::path(out) / "curves", ec);
  if (ec) {
    std::fprintf(stderr, "graphfrac report lab: %s: %s\n", out.c_str(), ec.message().c_str());
    return kExitOutput;
  }
  const int resolutions = quick ? 1 : 2;
  int flagged = 0;
  std::string md;

  // Brazilian disc: each resolution at the scene's rate, the coarse one also at half of it.
  struct DiscRun {
    std::string label;
    lab::BrazilianResult r;
  };
  std::vector<DiscRun> discs;
  const std::string discScene = (fs::path(scenes) / "brazilian_disc.json").string();
  for (int res = 0; res < (only.empty() || only == "brazilian" ? resolutions : 0); ++res) {
    Result<scene::Scene> sc = lab::loadLabScene(discScene, kDisc[res].patch);
    if (!sc.ok()) {
      std::fprintf(stderr, "graphfrac report lab: %s\n", sc.error().message.c_str());
      return kExitScene;
    }
    for (double rate : res == 0 ? std::vector<double>{1.0, 0.5} : std::vector<double>{1.0}) {
      std::printf("brazilian disc, %s, jaw rate x%.1f ...\n", kDisc[res].label, rate);
      std::fflush(stdout);
      Result<lab::BrazilianResult> r = lab::runBrazilian(sc.value(), rate, crackRefine);
      if (!r.ok()) {
        std::fprintf(stderr, "graphfrac report lab: %s\n", r.error().message.c_str());
        return kExitScene;
      }
      const lab::BrazilianResult& b = r.value();
      flagged += b.flaggedSteps;
      std::printf(
          "  %zu tets, %d steps, %.1f s: first break at %.4g N, peak P = %.4g N, 2P/(pi D t) = "
          "%.4g Pa = %.3f sigma_th; first break %.3f D from the centre; %d broken edges, %.0f %% "
          "within 0.1 D of the loaded diameter, crack axis %.1f deg from it\n",
          b.tets, b.steps, b.seconds, b.firstBreakLoad, b.peakLoad, b.indirectStrength,
          b.indirectStrength / b.strength, b.firstBreakFromCentre, b.broken, 100 * b.onDiameter,
          b.crackAngleDeg);
      // No commas: the label is a field of brazilian.csv, which is not quoted.
      discs.push_back(
          {std::string(kDisc[res].label) + " at " + fmt("%.3g", b.jawSpeed) + " m/s", b});
    }
  }

  // Impact tests: brittle and ductile bars, Charpy and Izod, each resolution.
  struct ImpactRun {
    std::string test, material, resolution;
    lab::ImpactResult r;
  };
  std::vector<ImpactRun> impacts;
  for (const char* test : {"charpy", "izod"}) {
    if (!only.empty() && only != test) continue;
    for (const char* material : {"brittle", "ductile"}) {
      const std::string path =
          (fs::path(scenes) / (std::string(test) + "_" + material + ".json")).string();
      for (int res = 0; res < resolutions; ++res) {
        Result<scene::Scene> sc = lab::loadLabScene(path, kBar[res].patch);
        if (!sc.ok()) {
          std::fprintf(stderr, "graphfrac report lab: %s\n", sc.error().message.c_str());
          return kExitScene;
        }
        std::printf("%s %s, %s ...\n", test, material, kBar[res].label);
        std::fflush(stdout);
        // Both tests stop 4 mm past contact (--stop-after; or 0.5 mm past the fracture): the
        // ductile bars are still bending there, so their absorbed energy is a lower bound.
        Result<lab::ImpactResult> r = lab::runImpact(sc.value(), impactSetup);
        if (!r.ok()) {
          std::fprintf(stderr, "graphfrac report lab: %s\n", r.error().message.c_str());
          return kExitScene;
        }
        const lab::ImpactResult& m = r.value();
        flagged += m.flaggedSteps;
        std::printf(
            "  %zu tets, %d steps, %.1f s: first break at %.4g N, %.3f mm; peak %.4g N at %.3f "
            "mm; fracture at %.3f mm (%.3g J); absorbed %.3g J; %d broken edges, %d fragments "
            "(largest %.0f %%, second %.0f %%), ligament %.0f %% cut, max CMOD %.3f mm\n",
            m.tets, m.steps, m.seconds, m.firstBreakLoad, 1e3 * m.firstBreakDisplacement,
            m.peakLoad, 1e3 * m.displacementAtPeak, 1e3 * m.displacementAtFracture,
            m.energyToFracture, m.absorbedEnergy, m.broken, m.fragments, 100 * m.largestShare,
            100 * m.secondShare, 100 * m.ligamentBroken, 1e3 * m.maxCmod);
        impacts.push_back({test, material, kBar[res].label, m});
      }
    }
  }

  // Curves and summaries.
  Result<void> w;
  for (size_t i = 0; w.ok() && i < discs.size(); ++i)
    w = writeCurve(fs::path(out) / "curves" / ("brazilian_" + std::to_string(i) + ".csv"),
                   discs[i].r.curve);
  for (size_t i = 0; w.ok() && i < impacts.size(); ++i)
    w = writeCurve(fs::path(out) / "curves" /
                       (impacts[i].test + "_" + impacts[i].material + "_" +
                        std::to_string(i % resolutions) + ".csv"),
                   impacts[i].r.curve);
  CsvWriter csv;
  if (w.ok())
    w = csv.open((fs::path(out) / "brazilian.csv").string(),
                 {"run", "tets", "jaw_speed_m_s", "first_break_load_N", "first_break_ratio",
                  "peak_load_N", "approach_at_peak_m", "indirect_strength_Pa", "sigma_th_Pa",
                  "ratio", "first_break_from_centre_over_D", "broken_edges", "on_diameter_fraction",
                  "crack_angle_deg", "fragments", "steps", "flagged_steps", "seconds"});
  for (size_t i = 0; w.ok() && i < discs.size(); ++i) {
    const lab::BrazilianResult& b = discs[i].r;
    w = csv.row({discs[i].label, int64_t(b.tets), b.jawSpeed, b.firstBreakLoad,
                 2 * b.firstBreakLoad / (M_PI * b.diameter * b.thickness) / b.strength, b.peakLoad,
                 b.displacementAtPeak, b.indirectStrength, b.strength,
                 b.indirectStrength / b.strength, b.firstBreakFromCentre, int64_t(b.broken),
                 b.onDiameter, b.crackAngleDeg, int64_t(b.fragments), int64_t(b.steps),
                 int64_t(b.flaggedSteps), b.seconds});
  }
  if (w.ok()) w = csv.close();
  CsvWriter icsv;
  if (w.ok()) w = icsv.open((fs::path(out) / "impact.csv").string(), kImpactColumns);
  for (size_t i = 0; w.ok() && i < impacts.size(); ++i) {
    const lab::ImpactResult& m = impacts[i].r;
    w = icsv.row({impacts[i].test,
                  impacts[i].material,
                  impacts[i].resolution,
                  int64_t(m.tets),
                  m.strikerSpeed,
                  m.firstBreakLoad,
                  m.firstBreakDisplacement,
                  m.peakLoad,
                  m.displacementAtPeak,
                  m.displacementAtFracture,
                  m.displacementAtSplit,
                  m.energyToFracture,
                  m.absorbedEnergy,
                  int64_t(m.broken),
                  int64_t(m.fragments),
                  m.largestShare,
                  m.secondShare,
                  m.ligamentBroken,
                  m.maxCmod,
                  int64_t(m.steps),
                  int64_t(m.flaggedSteps),
                  m.seconds});
  }
  if (w.ok()) w = icsv.close();

  PlotPanel discPanel{
      "Brazilian disc (granite)", "jaw approach [um]", "load [kN]", false, false, {}};
  for (size_t i = 0; i < discs.size(); ++i)
    discPanel.series.push_back(curveSeries(discs[i].label, int(i), discs[i].r.curve, false, 1e6));
  // Where the crack ran, one panel per run (the broken edges when the load gave way).
  std::vector<PlotPanel> discPanels{discPanel};
  for (size_t i = 0; i < discs.size() && i < 3; ++i) {
    PlotPanel crack{"crack: " + discs[i].label,
                    "across the load [mm]",
                    "along the load [mm]",
                    false,
                    false,
                    {}};
    PlotSeries pts{"broken edges", kColours[i % 6], {}};
    for (const glm::dvec2& c : discs[i].r.crack) pts.points.push_back({1e3 * c.x, 1e3 * c.y, ""});
    // The rim, so the panel shows the whole disc at its true aspect.
    PlotSeries rim{"rim", "#999999", {}};
    rim.line = true;
    for (int k = 0; k <= 96; ++k) {
      const double t = 2 * M_PI * k / 96, rad = 0.5e3 * discs[i].r.diameter;
      rim.points.push_back({rad * std::cos(t), rad * std::sin(t), ""});
    }
    crack.series = {rim, pts};
    discPanels.push_back(crack);
  }
  if (w.ok() && !discs.empty())
    w = writeSvg((fs::path(out) / "brazilian.svg").string(), discPanels,
                 "jaws' reaction (World::gripForces) against their approach; failure load P at the "
                 "peak, sigma_th pi D t / 2 = " +
                     fmt("%.4g", discs[0].r.strength * M_PI * discs[0].r.diameter *
                                     discs[0].r.thickness / 2 * 1e-3) +
                     " kN");
  for (const char* test : {"charpy", "izod"}) {
    PlotPanel ld{std::string(test) + ": load against striker displacement",
                 "striker displacement since contact [mm]",
                 "load [kN]",
                 false,
                 false,
                 {}};
    PlotPanel lc{std::string(test) + ": load against CMOD",
                 "crack mouth opening [mm]",
                 "load [kN]",
                 false,
                 false,
                 {}};
    int k = 0;
    for (const ImpactRun& run : impacts) {
      if (run.test != test) continue;
      const std::string name = run.material + ", " + run.resolution;
      const double upTo =
          run.r.displacementAtFracture >= 0 ? run.r.displacementAtFracture + 5e-5 : 1e300;
      ld.series.push_back(curveSeries(name, k, run.r.curve, false, 1e3, upTo));
      lc.series.push_back(curveSeries(name, k, run.r.curve, true, 1e3, upTo));
      ++k;
    }
    if (w.ok() && k > 0)
      w = writeSvg(
          (fs::path(out) / (std::string(test) + ".svg")).string(), {ld, lc},
          "striker load = World::colliderImpulses / dt; 20 kg striker at 5 m/s; curves end "
          "0.05 mm after the ligament is cut (curves/*.csv has the rest)");
  }

  // Markdown summary with the acceptance checks of issue 19.
  md +=
      "| run | tets | first break [kN] | / (sigma_th pi D t / 2) | P [kN] | 2P/(pi D t) [MPa] | / "
      "sigma_th | first break from centre | broken | within 0.1 D of the diameter | crack axis "
      "from the diameter |\n";
  md += "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const DiscRun& d : discs) {
    const lab::BrazilianResult& b = d.r;
    md += "| " + d.label + " | " + std::to_string(b.tets) + " | " +
          fmt("%.2f", 1e-3 * b.firstBreakLoad) + " | " +
          fmt("%.3f", 2 * b.firstBreakLoad / (M_PI * b.diameter * b.thickness) / b.strength) +
          " | " + fmt("%.2f", 1e-3 * b.peakLoad) + " | " + fmt("%.2f", 1e-6 * b.indirectStrength) +
          " | " + fmt("%.3f", b.indirectStrength / b.strength) + " | " +
          fmt("%.3f D", b.firstBreakFromCentre) + " | " + std::to_string(b.broken) + " | " +
          fmt("%.0f %%", 100 * b.onDiameter) + " | " + fmt("%.1f deg", b.crackAngleDeg) + " |\n";
  }
  if (!discs.empty())
    md += "\nJaw steps of " + fmt("%g s", discs[0].r.dt) + ", " +
          std::to_string(discs[0].r.crackRefine) +
          " times shorter from the first broken edge on; the crack is measured when the load "
          "first falls below 90 % of its peak.\n";
  md +=
      "\n| test | material | mesh | tets | first break [kN] | at [mm] | peak load [kN] | at [mm] "
      "| fracture at [mm] | split at [mm] | energy to fracture [J] | absorbed [J] | broken "
      "edges | fragments (two largest) | ligament cut | outcome |\n";
  md += "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  // "-" where a length was never reached.
  auto mm = [](double metres) { return metres >= 0 ? fmt("%.3f", 1e3 * metres) : "-"; };
  for (const ImpactRun& run : impacts) {
    const lab::ImpactResult& m = run.r;
    const char* outcome = m.splitInTwo() ? "split in two"
                          : m.broken > 0 ? "bent, partly cracked"
                                         : "bent, intact";
    md += "| " + run.test + " | " + run.material + " | " + run.resolution + " | " +
          std::to_string(m.tets) + " | " + fmt("%.2f", 1e-3 * m.firstBreakLoad) + " | " +
          mm(m.firstBreakDisplacement) + " | " + fmt("%.2f", 1e-3 * m.peakLoad) + " | " +
          mm(m.displacementAtPeak) + " | " + mm(m.displacementAtFracture) + " | " +
          mm(m.displacementAtSplit) + " | " +
          (m.energyToFracture >= 0 ? fmt("%.2f", m.energyToFracture) : "-") + " | " +
          fmt("%.2f", m.absorbedEnergy) + " | " + std::to_string(m.broken) + " | " +
          std::to_string(m.fragments) + " (" + fmt("%.0f", 100 * m.largestShare) + " / " +
          fmt("%.0f %%", 100 * m.secondShare) + ") | " + fmt("%.0f %%", 100 * m.ligamentBroken) +
          " | " + outcome + " |\n";
  }
  if (!impacts.empty())
    md += "\nThe impact runs stop " + fmt("%g mm", 1e3 * impactSetup.maxDisplacement) +
          " of striker travel past contact, or 0.5 mm past the split.\n";
  md += "\nAcceptance (issue 19):\n\n";
  auto check = [&](bool pass, const std::string& what) {
    md += std::string("- ") + (pass ? "PASS" : "FAIL") + ": " + what + "\n";
  };
  for (const DiscRun& d : discs) {
    const lab::BrazilianResult& b = d.r;
    check(std::abs(b.indirectStrength / b.strength - 1) <= 0.15,
          "Brazilian " + d.label + ": 2P/(pi D t) within 15 % of sigma_th (" +
              fmt("%+.1f %%", 100 * (b.indirectStrength / b.strength - 1)) + ")");
    check(b.broken > 0 && b.firstBreakFromCentre <= 0.2,
          "Brazilian " + d.label + ": crack starts within 0.2 D of the centre (" +
              fmt("%.3f D", b.firstBreakFromCentre) + ")");
  }
  if (discs.size() >= 2)
    md += "- rate check: P at half the jaw rate / P at the scene's rate = " +
          fmt("%.4f", discs[1].r.peakLoad / discs[0].r.peakLoad) + "\n";
  if (discs.size() >= 3)
    md += "- mesh check: P on the fine disc / P on the coarse one = " +
          fmt("%.4f", discs[2].r.peakLoad / discs[0].r.peakLoad) + "\n";
  for (const char* test : {"charpy", "izod"})
    for (int res = 0; res < resolutions; ++res) {
      const ImpactRun *brittle = nullptr, *ductile = nullptr;
      for (const ImpactRun& run : impacts)
        if (run.test == test && run.resolution == kBar[res].label)
          (run.material == "brittle" ? brittle : ductile) = &run;
      if (!brittle || !ductile) continue;
      const std::string where = std::string(test) + " " + kBar[res].label;
      check(brittle->r.splitInTwo(), where + ": the brittle bar splits in two");
      check(!ductile->r.splitInTwo() && ductile->r.broken > 0,
            where + ": the ductile bar bends and stays partly joined");
      check(ductile->r.absorbedEnergy > brittle->r.absorbedEnergy,
            where + ": the ductile bar absorbs more (" + fmt("%.2f J", ductile->r.absorbedEnergy) +
                " against " + fmt("%.2f J", brittle->r.absorbedEnergy) + ")");
    }
  if (!quick)
    for (const char* test : {"charpy", "izod"})
      for (const char* material : {"brittle", "ductile"}) {
        const ImpactRun *c = nullptr, *f = nullptr;
        for (const ImpactRun& run : impacts)
          if (run.test == test && run.material == material)
            (run.resolution == kBar[0].label ? c : f) = &run;
        if (c && f && c->r.peakLoad > 0)
          md += std::string("- mesh check, ") + test + " " + material +
                ": peak load fine / coarse = " + fmt("%.4f", f->r.peakLoad / c->r.peakLoad) + "\n";
      }
  if (w.ok()) {
    std::FILE* f = std::fopen((fs::path(out) / "summary.md").string().c_str(), "wb");
    if (!f || std::fputs(md.c_str(), f) < 0 || std::fclose(f) != 0)
      w = fail((fs::path(out) / "summary.md").string(), ": cannot write");
  }
  if (!w.ok()) {
    std::fprintf(stderr, "graphfrac report lab: %s\n", w.error().message.c_str());
    return kExitOutput;
  }
  std::fputs(md.c_str(), stdout);
  std::printf("wrote %s/{brazilian,charpy,izod}.svg, brazilian.csv, impact.csv, summary.md\n",
              out.c_str());
  return flagged > 0 ? kExitFlagged : kExitOk;
}

}  // namespace

int runLabReport(int argc, char** argv) { return labReport(argc, argv); }

}  // namespace gf::cli
