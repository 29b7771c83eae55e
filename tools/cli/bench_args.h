// The command line of a `graphfrac bench` mode, checked against a table of its options before
// anything runs: every mode reports an unknown option or a bad value the same way.
#pragma once

#include <initializer_list>
#include <string>
#include <variant>
#include <vector>

namespace gf::cli {

/// One option of a bench mode and where its value goes: an integer or a comma-separated list of
/// integers in [lo, hi], a number > 0, a non-empty text (a vector collects a repeated option),
/// or a flag without value (the bool is set).
struct BenchOption {
  const char* name;
  std::variant<int*, std::vector<int>*, double*, std::string*, std::vector<std::string>*, bool*>
      out;
  long long lo = 0, hi = 0;
};

/// Reads argv[2..] (argv[1] is the mode) into the options' targets; kExitOk, or kExitUsage after
/// "bench MODE: --OPTION needs ..." or "bench MODE: unknown option '...'" on stderr.
int parseBenchArgs(const char* mode, int argc, char** argv,
                   std::initializer_list<BenchOption> options);

/// Upper bounds of the bench modes' integer options: far beyond what a run can afford, below
/// what the modes' tet counts (6 cells^3) can hold in an int.
inline constexpr long long kBenchMaxCount = 100'000'000;
inline constexpr long long kBenchMaxCells = 512;
inline constexpr long long kBenchMaxThreads = 1024;

}  // namespace gf::cli
