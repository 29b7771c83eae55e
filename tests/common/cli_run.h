// Runs `graphfrac` subcommands in-process (tools/cli/commands.h), as the CLI's main would.
#pragma once

#include <string>
#include <vector>

#include "cli/commands.h"

namespace gf::test {

/// args[0] is the subcommand ("run", "report", "bench" or "mesh"), the rest its arguments;
/// returns its exit code.
inline int runCli(std::vector<std::string> args) {
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  const int argc = int(argv.size());
  if (args.at(0) == "report") return gf::cli::runReportCommand(argc, argv.data());
  if (args[0] == "bench") return gf::cli::runBenchCommand(argc, argv.data());
  if (args[0] == "mesh") return gf::cli::runMeshCommand(argc, argv.data());
  return gf::cli::runCommand(argc, argv.data());
}

}  // namespace gf::test
