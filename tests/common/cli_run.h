// Runs a `graphfrac` subcommand in-process (tools/cli/commands.h), as the CLI's main would.
#pragma once

#include <string>
#include <vector>

#include "cli/commands.h"

namespace gf::test {

/// args[0] is the subcommand ("run", "mesh", ...); returns its exit code.
inline int runCli(std::vector<std::string> args) {
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  return gf::cli::runCommand(int(argv.size()), argv.data());
}

}  // namespace gf::test
