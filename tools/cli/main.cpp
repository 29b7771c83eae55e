// `graphfrac`: command-line entry point. Dispatches to the subcommands.
#include <cstdio>
#include <cstring>
#include <string_view>

#include "cli/commands.h"

namespace {

constexpr const char* kUsage =
    "usage: graphfrac <command> [options]\n"
    "\n"
    "commands:\n"
    "  run SCENE [options]   simulate a JSON scene, write per-frame statistics and surfaces\n"
    "  mesh ...              tet-mesh tools (info, convert, tetrahedralise any surface)\n"
    "  bench fracture|multigrid|overhead|stages\n"
    "                        benchmarks that print CSV figures (see bench --help)\n"
    "  report error-vs-time SCENE\n"
    "                        error against run time of every solver setting (CSV + SVG)\n"
    "  report lab [--quick]  Brazilian, Charpy and Izod tests: curves (SVG) and a summary\n"
    "  report all [--quick]  every measurement of docs/RESULTS.md, written into its generated\n"
    "                        regions (tens of minutes; --quick: CI's short form)\n"
    "\n"
    "  graphfrac <command> --help   options of a command\n"
    "  graphfrac --version          print the version\n"
    "\n"
    "exit codes: 0 ok, 1 usage, 2 scene error, 3 a step was flagged (results still written),\n"
    "            4 results could not be written\n"
    "scene format: docs/scene_format.md\n";

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fputs(kUsage, stderr);
    return gf::cli::kExitUsage;
  }
  const std::string_view cmd = argv[1];
  if (cmd == "-h" || cmd == "--help" || cmd == "help") {
    std::fputs(kUsage, stdout);
    return gf::cli::kExitOk;
  }
  if (cmd == "--version") {
    std::puts("graphfrac 0.1.0");
    return gf::cli::kExitOk;
  }
  // Subcommands see their own name as argv[0].
  if (cmd == "run") return gf::cli::runCommand(argc - 1, argv + 1);
  if (cmd == "mesh") return gf::cli::runMeshCommand(argc - 1, argv + 1);
  if (cmd == "bench") return gf::cli::runBenchCommand(argc - 1, argv + 1);
  if (cmd == "report") return gf::cli::runReportCommand(argc - 1, argv + 1);
  std::fprintf(stderr, "graphfrac: unknown command '%s'\n\n%s", argv[1], kUsage);
  return gf::cli::kExitUsage;
}
