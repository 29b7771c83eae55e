// Command-line walking shared by `graphfrac run` and graphfrac-demo: options written
// "--name value" or "--name=value", flags, and positional arguments, with the numeric checks
// their values need. Header-only so that the demo, which links the CLI library privately, and
// the CLI share one copy without another library.
#pragma once

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

#include "graphfrac/defs.h"

namespace gf::cli {

/// Parses all of `s` as a base-10 integer in [lo, hi]; false (out untouched) otherwise.
inline bool parseInt(std::string_view s, long long lo, long long hi, int& out) {
  if (s.empty()) return false;
  const std::string str(s);
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(str.c_str(), &end, 10);
  if (errno != 0 || end != str.c_str() + str.size() || v < lo || v > hi) return false;
  out = static_cast<int>(v);
  return true;
}

/// Parses all of `s` as a finite number; false (out untouched) otherwise.
inline bool parseDouble(std::string_view s, double& out) {
  if (s.empty()) return false;
  const std::string str(s);
  char* end = nullptr;
  const double v = std::strtod(str.c_str(), &end);
  if (end != str.c_str() + str.size() || !std::isfinite(v)) return false;
  out = v;
  return true;
}

/// Parses all of `s` as comma-separated base-10 integers in [lo, hi] ("1,2,4"); false (out
/// untouched) when it is empty or any item is not one.
inline bool parseIntList(std::string_view s, long long lo, long long hi, std::vector<int>& out) {
  std::vector<int> list;
  for (size_t begin = 0;;) {
    const size_t comma = std::min(s.find(',', begin), s.size());
    int v = 0;
    if (!parseInt(s.substr(begin, comma - begin), lo, hi, v)) return false;
    list.push_back(v);
    if (comma == s.size()) break;
    begin = comma + 1;
  }
  out = std::move(list);
  return true;
}

/// A --backend value: auto, cpu or cuda.
inline bool parseBackend(std::string_view s, Backend& out) {
  if (s == "auto")
    out = Backend::Auto;
  else if (s == "cpu")
    out = Backend::Cpu;
  else if (s == "cuda")
    out = Backend::Cuda;
  else
    return false;
  return true;
}

/// Walks argv from `first` on. For each argument next() yields its name: an option's name with
/// any "=value" split off, or the positional argument itself; value() then takes the option's
/// value from after the '=' or from the following argument.
class ArgParser {
 public:
  /// argv[first] is the first argument looked at (argv[0] is the program or subcommand).
  ArgParser(int argc, char** argv, int first = 1) : m_argc(argc), m_argv(argv), m_next(first) {}

  /// Advances to the next argument; false when none is left.
  bool next() {
    if (m_next >= m_argc) return false;
    m_name = m_argv[m_next++];
    m_inline.clear();
    m_hasInline = false;
    // Only long options carry "=value": a positional path may contain '='.
    if (m_name.rfind("--", 0) == 0) {
      const size_t eq = m_name.find('=');
      if (eq != std::string::npos) {
        m_inline = m_name.substr(eq + 1);
        m_name.resize(eq);
        m_hasInline = true;
      }
    }
    return true;
  }

  /// The current argument (an option without its "=value").
  const std::string& name() const { return m_name; }
  /// True when the current argument starts with '-' (an option, known or not).
  bool isOption() const { return !m_name.empty() && m_name[0] == '-'; }

  /// The current option's value; false when the command line ends before it.
  bool value(std::string& out) {
    if (m_hasInline) {
      out = m_inline;
      m_hasInline = false;
      return true;
    }
    if (m_next >= m_argc) return false;
    out = m_argv[m_next++];
    return true;
  }

  /// The value as an integer in [lo, hi]; false when missing or out of range.
  bool intValue(long long lo, long long hi, int& out) {
    std::string v;
    return value(v) && parseInt(v, lo, hi, out);
  }

  /// The value as comma-separated integers in [lo, hi]; false when missing or any is not one.
  bool intListValue(long long lo, long long hi, std::vector<int>& out) {
    std::string v;
    return value(v) && parseIntList(v, lo, hi, out);
  }

  /// The value as a finite number > 0; false when missing or not one.
  bool positiveValue(double& out) {
    std::string v;
    double x = 0;
    if (!value(v) || !parseDouble(v, x) || !(x > 0)) return false;
    out = x;
    return true;
  }

  /// The value when it is not empty; false otherwise.
  bool nonEmptyValue(std::string& out) {
    std::string v;
    if (!value(v) || v.empty()) return false;
    out = std::move(v);
    return true;
  }

 private:
  int m_argc;
  char** m_argv;
  int m_next;
  std::string m_name;
  std::string m_inline;
  bool m_hasInline = false;
};

}  // namespace gf::cli
