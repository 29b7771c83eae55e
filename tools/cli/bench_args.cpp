#include "cli/bench_args.h"

#include <cstdio>

#include "cli/args.h"
#include "cli/commands.h"

namespace gf::cli {

namespace {

// Takes the current option's value into `out`; on a bad value, what the option needs.
struct Reader {
  ArgParser& args;
  long long lo, hi;
  std::string range() const {
    return hi >= kBenchMaxCount ? ">= " + std::to_string(lo)
                                : "from " + std::to_string(lo) + " to " + std::to_string(hi);
  }
  std::string operator()(int* out) const {
    return args.intValue(lo, hi, *out) ? "" : "an integer " + range();
  }
  std::string operator()(std::vector<int>* out) const {
    return args.intListValue(lo, hi, *out) ? "" : "a comma-separated list of integers " + range();
  }
  std::string operator()(double* out) const {
    return args.positiveValue(*out) ? "" : "a number > 0";
  }
  std::string operator()(std::string* out) const {
    return args.nonEmptyValue(*out) ? "" : "a value";
  }
  std::string operator()(std::vector<std::string>* out) const {
    std::string v;
    if (!args.nonEmptyValue(v)) return "a value";
    out->push_back(std::move(v));
    return "";
  }
  std::string operator()(bool* out) const {
    *out = true;
    return "";
  }
};

}  // namespace

int parseBenchArgs(const char* mode, int argc, char** argv,
                   std::initializer_list<BenchOption> options) {
  ArgParser args(argc, argv, 2);
  while (args.next()) {
    const BenchOption* option = nullptr;
    for (const BenchOption& o : options)
      if (args.name() == o.name) option = &o;
    if (!option) {
      std::fprintf(stderr, "bench %s: unknown option '%s'\n", mode, args.name().c_str());
      return kExitUsage;
    }
    if (const std::string needs = std::visit(Reader{args, option->lo, option->hi}, option->out);
        !needs.empty()) {
      std::fprintf(stderr, "bench %s: %s needs %s\n", mode, option->name, needs.c_str());
      return kExitUsage;
    }
  }
  return kExitOk;
}

}  // namespace gf::cli
