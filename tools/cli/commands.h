// Subcommands of the `graphfrac` executable and the exit codes they share.
#pragma once

namespace gf::cli {

/// Exit codes of every subcommand (documented in `graphfrac --help`).
enum ExitCode : int {
  kExitOk = 0,       ///< Success.
  kExitUsage = 1,    ///< Bad command line.
  kExitScene = 2,    ///< The scene (or a mesh it names) could not be loaded or created.
  kExitFlagged = 3,  ///< The simulation ran but some step raised a flag; results are written.
  kExitOutput = 4,   ///< Results could not be written (directory, disk).
};

/// `graphfrac run SCENE [options]`; argv[0] is "run".
int runCommand(int argc, char** argv);

/// `graphfrac bench NAME [options]`; argv[0] is "bench". Prints CSV figures.
int runBenchCommand(int argc, char** argv);

/// `graphfrac report error-vs-time SCENE [options]`; argv[0] is "report". Writes a CSV and an
/// SVG plot of error against run time for every solver setting.
int runReportCommand(int argc, char** argv);

/// `graphfrac report lab [--quick] [--only TEST] [--out DIR] [--scenes DIR] [--crack-refine N]`;
/// argv[0] is "report", argv[1] "lab". Runs the laboratory tests of scenes/lab (Brazilian,
/// Charpy, Izod) and writes their curves and a summary (tools/cli/report_lab_command.cpp).
int runLabReport(int argc, char** argv);

/// `graphfrac report all [--quick] [--out DIR] [--results FILE] [--scenes DIR]
/// [--stability-bin PATH]`; argv[0] is "report", argv[1] "all". Runs every part of
/// docs/RESULTS.md (lab, error vs time, frame-time bench, stability suite, Bullet comparison)
/// and rewrites only the file's generated regions (tools/cli/report_all.cpp).
int runAllReport(int argc, char** argv);

/// `graphfrac mesh SUBCOMMAND ...`; argv[0] is "mesh", argv[1] the subcommand:
///   from-surface IN OUT.msh [--method auto|tetgen|lattice] [--cells N | --target-tets T]
///                [--max-volume V] [--quality Q] [--tetgen PATH] [--keep-temp] ...
///     (tetrahedralises a surface: a closed one with the tetgen program, run as a tool; any
///     triangle soup with the winding-number lattice mesher)
///   info FILE
///   convert IN OUT          (IN: .msh/.node/.ele; OUT: .msh/.obj/.ply)
/// Returns kExitOk, kExitUsage, or kExitScene when an input cannot be read or meshed.
int runMeshCommand(int argc, char** argv);

}  // namespace gf::cli
