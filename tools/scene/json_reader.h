// Reading JSON with paths: the scene loader's building blocks. Every reader knows the JSON path
// it stands on and throws SceneError{path, reason} on a bad value; ObjReader remembers the keys
// an object may hold so that a typo is reported (with the closest valid key) instead of being
// ignored; DuplicateKeyCheck rejects a key given twice. Internal to tools/scene.
#pragma once

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <glm/vec3.hpp>
#include <initializer_list>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace gf::scene::detail {

using nlohmann::json;

/// An error at a JSON path; becomes `source: path: reason`.
struct SceneError {
  std::string path;
  std::string reason;
};

inline std::string joinPath(const std::string& base, std::string_view key) {
  return base.empty() ? std::string(key) : base + "." + std::string(key);
}

inline std::string indexPath(const std::string& base, size_t i) {
  return base + "[" + std::to_string(i) + "]";
}

/// A short rendering of a JSON value for "got ..." in messages.
inline std::string describe(const json& v) {
  if (v.is_object()) return "an object";
  if (v.is_array() && v.size() > 6) return "an array of " + std::to_string(v.size());
  std::string s = v.dump();
  if (s.size() > 48) s = s.substr(0, 45) + "...";
  return s;
}

inline std::string fmt(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", x);
  return buf;
}

inline size_t editDistance(std::string_view a, std::string_view b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diag = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      const bool same = std::tolower(static_cast<unsigned char>(a[i - 1])) ==
                        std::tolower(static_cast<unsigned char>(b[j - 1]));
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (same ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

// ---- scalar readers ---------------------------------------------------------------------

inline double readNumber(const json& v, const std::string& path) {
  if (!v.is_number()) throw SceneError{path, "expected a number, got " + describe(v)};
  const double x = v.get<double>();
  if (!std::isfinite(x)) throw SceneError{path, "expected a finite number, got " + describe(v)};
  return x;
}

inline double readPositive(const json& v, const std::string& path) {
  if (!v.is_number() || !(v.get<double>() > 0) || !std::isfinite(v.get<double>())) {
    throw SceneError{path, "expected a positive number, got " + describe(v)};
  }
  return v.get<double>();
}

inline double readNonNegative(const json& v, const std::string& path) {
  if (!v.is_number() || !(v.get<double>() >= 0) || !std::isfinite(v.get<double>())) {
    throw SceneError{path, "expected a number >= 0, got " + describe(v)};
  }
  return v.get<double>();
}

/// A number in [lo, hi]; `range` describes the interval for the message.
inline double readInRange(const json& v, const std::string& path, double lo, double hi, bool openLo,
                          bool openHi) {
  const std::string range =
      std::string(openLo ? "(" : "[") + fmt(lo) + ", " + fmt(hi) + (openHi ? ")" : "]");
  if (!v.is_number())
    throw SceneError{path, "expected a number in " + range + ", got " + describe(v)};
  const double x = v.get<double>();
  const bool okLo = openLo ? x > lo : x >= lo;
  const bool okHi = openHi ? x < hi : x <= hi;
  if (!(okLo && okHi))
    throw SceneError{path, "expected a number in " + range + ", got " + describe(v)};
  return x;
}

inline int readInt(const json& v, const std::string& path, long long lo, long long hi) {
  const std::string want = "expected an integer in [" + std::to_string(lo) + ", " +
                           std::to_string(hi) + "], got " + describe(v);
  if (!v.is_number()) throw SceneError{path, want};
  const double x = v.get<double>();
  if (!std::isfinite(x) || x != std::floor(x) || x < static_cast<double>(lo) ||
      x > static_cast<double>(hi)) {
    throw SceneError{path, want};
  }
  return static_cast<int>(x);
}

/// Any integer an int holds. Ranges are not checked here: the runtime's check() routines own
/// the rules of the values they validate.
inline int readInteger(const json& v, const std::string& path) {
  if (v.is_number()) {
    const double x = v.get<double>();
    if (std::isfinite(x) && x == std::floor(x) && x >= std::numeric_limits<int>::min() &&
        x <= std::numeric_limits<int>::max()) {
      return static_cast<int>(x);
    }
  }
  throw SceneError{path, "expected an integer, got " + describe(v)};
}

/// A cap against typos: beyond it a value would exhaust memory (10000 cells for 10), not break
/// a physical rule, so it is the loader's to enforce.
inline void requireAtMost(double x, double cap, const std::string& path, const json& v) {
  if (x > cap) {
    throw SceneError{path, "at most " + fmt(cap) + " (a cap against typos), got " + describe(v)};
  }
}

inline std::string readString(const json& v, const std::string& path) {
  if (!v.is_string()) throw SceneError{path, "expected a string, got " + describe(v)};
  return v.get<std::string>();
}

inline bool readBool(const json& v, const std::string& path) {
  if (!v.is_boolean()) throw SceneError{path, "expected true or false, got " + describe(v)};
  return v.get<bool>();
}

inline const json& readArray(const json& v, const std::string& path, size_t n, const char* what) {
  if (!v.is_array() || (n != 0 && v.size() != n)) {
    const std::string count = n != 0 ? std::to_string(n) + " " : "";
    throw SceneError{path, "expected an array of " + count + what + ", got " + describe(v)};
  }
  return v;
}

inline glm::dvec3 readVec3(const json& v, const std::string& path) {
  readArray(v, path, 3, "numbers");
  glm::dvec3 r;
  for (int i = 0; i < 3; ++i) r[i] = readNumber(v[i], indexPath(path, i));
  return r;
}

inline glm::dvec3 readPositiveVec3(const json& v, const std::string& path) {
  readArray(v, path, 3, "positive numbers");
  glm::dvec3 r;
  for (int i = 0; i < 3; ++i) r[i] = readPositive(v[i], indexPath(path, i));
  return r;
}

/// A non-zero vector, returned normalised (fibre directions, normals, axes).
inline glm::dvec3 readDirection(const json& v, const std::string& path) {
  const glm::dvec3 d = readVec3(v, path);
  const double len = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
  if (!(len > 0)) throw SceneError{path, "expected a non-zero vector, got " + describe(v)};
  return d / len;
}

/// One of `choices`, case-sensitive; the message lists them.
inline std::string readChoice(const json& v, const std::string& path,
                              std::initializer_list<std::string_view> choices) {
  std::string list;
  for (std::string_view c : choices) list += (list.empty() ? "\"" : ", \"") + std::string(c) + "\"";
  if (v.is_string()) {
    const std::string s = v.get<std::string>();
    for (std::string_view c : choices) {
      if (s == c) return s;
    }
  }
  throw SceneError{path, "expected one of " + list + ", got " + describe(v)};
}

// ---- object reader ------------------------------------------------------------------------

/// Reads the keys of one JSON object and reports the ones nobody asked for.
class ObjReader {
 public:
  ObjReader(const json& v, std::string path) : m_v(v), m_path(std::move(path)) {
    if (!v.is_object()) {
      throw SceneError{m_path.empty() ? "(top level)" : m_path,
                       "expected an object, got " + describe(v)};
    }
  }

  const std::string& path() const { return m_path; }
  std::string at(std::string_view key) const { return joinPath(m_path, key); }
  bool has(std::string_view key) const { return m_v.contains(key); }

  /// The value under `key`, or null when absent; marks the key as known either way.
  /// Declares every key this object may hold and reports an unknown one at once, before any
  /// value is read (so a misspelt required key is reported as the typo it is).
  void keys(std::initializer_list<std::string_view> allowed) {
    for (std::string_view k : allowed) m_known.insert(std::string(k));
    finish();
  }

  const json* find(std::string_view key) {
    m_known.insert(std::string(key));
    auto it = m_v.find(key);
    return it == m_v.end() ? nullptr : &*it;
  }

  const json& require(std::string_view key) {
    const json* v = find(key);
    if (v == nullptr) throw SceneError{at(key), "missing (required)"};
    return *v;
  }

  /// Reports the first key that was never looked up, with the closest known key as a hint.
  void finish() const {
    for (auto it = m_v.begin(); it != m_v.end(); ++it) {
      if (m_known.count(it.key()) != 0) continue;
      std::string reason = "unknown key";
      size_t best = 3;
      std::string hint;
      for (const std::string& k : m_known) {
        const size_t d = editDistance(it.key(), k);
        if (d < best) best = d, hint = k;
      }
      if (!hint.empty()) reason += " (did you mean \"" + hint + "\"?)";
      if (!m_known.empty()) {
        std::string list;
        for (const std::string& k : m_known) list += (list.empty() ? "" : ", ") + k;
        reason += "; valid keys here: " + list;
      }
      throw SceneError{at(it.key()), reason};
    }
  }

 private:
  const json& m_v;
  std::string m_path;
  std::set<std::string> m_known;
};

// ---- parsing with duplicate-key detection -------------------------------------------------

/// Tracks the JSON path during parsing so a duplicate key can be named exactly.
class DuplicateKeyCheck {
 public:
  bool operator()(int /*depth*/, json::parse_event_t ev, json& parsed) {
    using E = json::parse_event_t;
    switch (ev) {
      case E::object_start:
      case E::array_start:
        m_stack.push_back(Frame{ev == E::array_start, 0, {}, {}, childPath()});
        break;
      case E::key: {
        Frame& f = m_stack.back();
        f.key = parsed.get<std::string>();
        if (!f.keys.insert(f.key).second) {
          throw SceneError{joinPath(f.path, f.key), "duplicate key"};
        }
        break;
      }
      case E::value:
        advance();
        break;
      case E::object_end:
      case E::array_end:
        m_stack.pop_back();
        advance();
        break;
    }
    return true;
  }

 private:
  struct Frame {
    bool array;
    size_t index;
    std::string key;
    std::set<std::string> keys;
    std::string path;
  };
  std::string childPath() const {
    if (m_stack.empty()) return {};
    const Frame& f = m_stack.back();
    return f.array ? indexPath(f.path, f.index) : joinPath(f.path, f.key);
  }
  void advance() {
    if (!m_stack.empty() && m_stack.back().array) ++m_stack.back().index;
  }
  std::vector<Frame> m_stack;
};

/// Turns nlohmann's parse error into `line:column: reason`.
inline std::string syntaxError(const json::parse_error& e, const std::string& text) {
  std::string what = e.what();
  // "[json.exception.parse_error.101] parse error at line 3, column 5: <reason>"
  long line = 0, column = 0;
  const size_t at = what.find("at line ");
  if (at == std::string::npos ||
      std::sscanf(what.c_str() + at, "at line %ld, column %ld", &line, &column) != 2) {
    // Fall back to the byte offset.
    line = 1;
    column = 0;
    for (size_t i = 0; i < std::min<size_t>(e.byte, text.size()); ++i) {
      if (text[i] == '\n')
        ++line, column = 0;
      else
        ++column;
    }
  }
  std::string reason = what;
  const size_t colon = what.find(": ", at == std::string::npos ? 0 : at);
  if (colon != std::string::npos) reason = what.substr(colon + 2);
  return std::to_string(line) + ":" + std::to_string(column) + ": invalid JSON: " + reason;
}

}  // namespace gf::scene::detail
