// TetGen .node/.ele reader. '#' starts a comment anywhere; blank lines are skipped. Point
// numbers are looked up rather than assumed, so 0- and 1-based files (and gaps) all work.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <exception>

#include "mesh/mesh_internal.h"

namespace gf {
namespace {

using detail::quote;

constexpr int64_t kMaxCount = INT32_MAX - 1;
constexpr int64_t kMaxReserve = 1 << 16;  // headers are untrusted: reserve at most this much

class TetGenFile {
 public:
  explicit TetGenFile(detail::TextFile& f) : m_f(f) {}

  Error err(const std::string& why) const { return Error{m_f.where() + why}; }

  // Next line with something other than a comment; false at end of file.
  bool next() {
    std::string_view line;
    while (m_f.next(line)) {
      detail::splitTokens(line, m_tok, '#');
      if (!m_tok.empty()) return true;
    }
    return false;
  }

  Result<int64_t> integer(size_t i, const char* what, int64_t lo, int64_t hi) const {
    int64_t v = 0;
    if (!detail::parseInt(m_tok[i], v))
      return err(std::string("expected ") + what + ", found " + quote(m_tok[i]));
    if (v < lo || v > hi) {
      return err(std::string(what) + " " + std::string(m_tok[i]) + " is out of range [" +
                 std::to_string(lo) + ", " + std::to_string(hi) + "]");
    }
    return v;
  }

  // Extra records after the header's count are an error: the count was wrong.
  Result<void> expectEnd(int64_t n, const char* what) {
    if (next()) {
      return err("more records than the header's " + std::to_string(n) + " " + what);
    }
    return {};
  }

  const std::vector<std::string_view>& tok() const { return m_tok; }
  int line() const { return m_f.line(); }

 private:
  detail::TextFile& m_f;
  std::vector<std::string_view> m_tok;
};

Result<void> readNodes(detail::TextFile& file, detail::RawMesh& raw) {
  if (file.blank()) return fail(file.path(), ": empty file");
  TetGenFile f(file);
  if (!f.next()) return fail(file.path(), ": no header line");
  if (f.tok().size() < 2 || f.tok().size() > 4) {
    return f.err("expected header '<points> <dimension> [<attributes> [<markers>]]'");
  }
  Result<int64_t> n = f.integer(0, "a point count", 1, kMaxCount);
  if (!n) return n.error();
  Result<int64_t> dim = f.integer(1, "a dimension", 0, INT32_MAX);
  if (!dim) return dim.error();
  if (dim.value() != 3) return f.err("dimension must be 3, found " + std::to_string(dim.value()));
  int64_t attributes = 0, markers = 0;
  if (f.tok().size() > 2) {
    Result<int64_t> a = f.integer(2, "an attribute count", 0, 1 << 20);
    if (!a) return a.error();
    attributes = a.value();
  }
  if (f.tok().size() > 3) {
    Result<int64_t> m = f.integer(3, "a boundary-marker flag", 0, 1);
    if (!m) return m.error();
    markers = m.value();
  }
  const size_t want = 4 + static_cast<size_t>(attributes + markers);
  const size_t r = static_cast<size_t>(std::min(n.value(), kMaxReserve));
  raw.positions.reserve(3 * r);
  raw.nodeTags.reserve(r);
  raw.nodeLines.reserve(r);
  for (int64_t i = 0; i < n.value(); ++i) {
    if (!f.next()) {
      return f.err("unexpected end of file after " + std::to_string(i) + " of " +
                   std::to_string(n.value()) + " points");
    }
    if (f.tok().size() != want) {
      return f.err("expected " + std::to_string(want) + " values (number, x, y, z, " +
                   std::to_string(attributes) + " attributes, " + std::to_string(markers) +
                   " markers), found " + std::to_string(f.tok().size()));
    }
    Result<int64_t> tag = f.integer(0, "a point number", INT64_MIN, INT64_MAX);
    if (!tag) return tag.error();
    for (size_t k = 1; k <= 3; ++k) {
      double x = 0;
      if (!detail::parseDouble(f.tok()[k], x)) {
        return f.err("point " + std::to_string(tag.value()) + ": expected a coordinate, found " +
                     quote(f.tok()[k]));
      }
      if (!std::isfinite(x)) {
        return f.err("point " + std::to_string(tag.value()) + ": non-finite coordinate " +
                     quote(f.tok()[k]));
      }
      raw.positions.push_back(x);
    }
    raw.nodeTags.push_back(tag.value());
    raw.nodeLines.push_back(f.line());
  }
  return f.expectEnd(n.value(), "points");
}

Result<void> readEle(detail::TextFile& file, detail::RawMesh& raw) {
  if (file.blank()) return fail(file.path(), ": empty file");
  TetGenFile f(file);
  if (!f.next()) return fail(file.path(), ": no header line");
  if (f.tok().size() < 2 || f.tok().size() > 3) {
    return f.err("expected header '<tetrahedra> <nodes per tetrahedron> [<attributes>]'");
  }
  Result<int64_t> n = f.integer(0, "a tetrahedron count", 1, kMaxCount);
  if (!n) return n.error();
  Result<int64_t> perTet = f.integer(1, "nodes per tetrahedron", 0, INT32_MAX);
  if (!perTet) return perTet.error();
  if (perTet.value() != 4 && perTet.value() != 10) {
    return f.err("nodes per tetrahedron must be 4 or 10, found " + std::to_string(perTet.value()));
  }
  int64_t attributes = 0;
  if (f.tok().size() > 2) {
    Result<int64_t> a = f.integer(2, "an attribute count", 0, 1 << 20);
    if (!a) return a.error();
    attributes = a.value();
  }
  const size_t want = 1 + static_cast<size_t>(perTet.value() + attributes);
  const size_t r = static_cast<size_t>(std::min(n.value(), kMaxReserve));
  raw.tetNodeTags.reserve(4 * r);
  raw.tetTags.reserve(r);
  raw.tetLines.reserve(r);
  for (int64_t i = 0; i < n.value(); ++i) {
    if (!f.next()) {
      return f.err("unexpected end of file after " + std::to_string(i) + " of " +
                   std::to_string(n.value()) + " tetrahedra");
    }
    if (f.tok().size() != want) {
      return f.err("expected " + std::to_string(want) + " values (number, " +
                   std::to_string(perTet.value()) + " nodes, " + std::to_string(attributes) +
                   " attributes), found " + std::to_string(f.tok().size()));
    }
    Result<int64_t> tag = f.integer(0, "a tetrahedron number", INT64_MIN, INT64_MAX);
    if (!tag) return tag.error();
    // Only the 4 corners of a 10-node tet are kept (they come first).
    for (size_t k = 1; k <= 4; ++k) {
      int64_t v = 0;
      if (!detail::parseInt(f.tok()[k], v)) {
        return f.err("element " + std::to_string(tag.value()) + ": expected a node number, found " +
                     quote(f.tok()[k]));
      }
      raw.tetNodeTags.push_back(v);
    }
    raw.tetTags.push_back(tag.value());
    raw.tetLines.push_back(f.line());
  }
  return f.expectEnd(n.value(), "tetrahedra");
}

}  // namespace

Result<TetMesh> TetMesh::fromTetGen(const std::string& nodePath, const std::string& elePath,
                                    MeshLoadInfo* info) {
  try {
    detail::RawMesh raw;
    raw.nodeFile = nodePath;
    raw.tetFile = elePath;
    {
      Result<detail::TextFile> file = detail::TextFile::read(nodePath);
      if (!file) return file.error();
      if (Result<void> r = readNodes(file.value(), raw); !r) return r.error();
    }
    {
      Result<detail::TextFile> file = detail::TextFile::read(elePath);
      if (!file) return file.error();
      if (Result<void> r = readEle(file.value(), raw); !r) return r.error();
    }
    return detail::finishRawMesh(std::move(raw), info);
  } catch (const std::exception& e) {
    return fail(nodePath, " / ", elePath, ": ", e.what());
  }
}

}  // namespace gf
