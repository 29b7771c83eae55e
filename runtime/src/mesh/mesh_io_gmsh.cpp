// Gmsh ASCII reader, formats 2.2 and 4.1. Only what a tet mesh needs is read: nodes and
// 4-node tetrahedra (type 4); other sections are skipped to their $End marker and other
// element types are ignored. Counts in headers are untrusted: they bound loops and are
// checked against what is actually found, but never size an allocation beyond a small cap.
#include <cmath>
#include <cstdint>
#include <exception>

#include "mesh/mesh_internal.h"

namespace gf {
namespace {

using detail::quote;

constexpr int64_t kMaxCount = INT32_MAX - 1;  // node indices are int32
constexpr int64_t kMaxReserve = 1 << 16;      // reserve no more than this from a header
constexpr int kTet4 = 4, kTet10 = 11;         // Gmsh element types

class GmshReader {
 public:
  GmshReader(detail::TextFile& f, detail::RawMesh& raw) : m_f(f), m_raw(raw) {}

  Result<void> run() {
    if (m_f.blank()) return fail(m_f.path(), ": empty file");
    if (!nextTokens() || m_tok[0] != "$MeshFormat") {
      return err("not a Gmsh .msh file: expected $MeshFormat, found " + quote(m_line));
    }
    if (Result<void> r = readFormat(); !r) return r;
    while (nextTokens()) {
      const std::string_view name = m_tok[0];
      if (name.empty() || name[0] != '$') {
        return err("expected a section such as $Nodes, found " + quote(m_line));
      }
      Result<void> r;
      if (name == "$Nodes") {
        if (m_sawNodes) return err("second $Nodes section");
        m_sawNodes = true;
        r = m_v4 ? readNodes4() : readNodes2();
      } else if (name == "$Elements") {
        if (m_sawElements) return err("second $Elements section");
        m_sawElements = true;
        r = m_v4 ? readElements4() : readElements2();
      } else {
        r = skipSection(name);
      }
      if (!r) return r;
    }
    if (!m_sawNodes) return fail(m_f.path(), ": no $Nodes section");
    if (!m_sawElements) return fail(m_f.path(), ": no $Elements section");
    if (m_raw.tetTags.empty()) {
      std::string why = m_f.path() + ": no 4-node tetrahedra (element type 4)";
      if (m_tet10 > 0) {
        why += "; found " + std::to_string(m_tet10) +
               " 10-node tetrahedra (type 11), which are not supported";
      }
      return Error{why};
    }
    return {};
  }

 private:
  Error err(const std::string& why) const { return Error{m_f.where() + why}; }

  // Next non-blank line, split; false at end of file.
  bool nextTokens() {
    while (m_f.next(m_line)) {
      detail::splitTokens(m_line, m_tok);
      if (!m_tok.empty()) return true;
    }
    return false;
  }

  Result<int64_t> count(std::string_view tok, const char* what) const {
    int64_t v = 0;
    if (!detail::parseInt(tok, v))
      return err(std::string("expected ") + what + ", found " + quote(tok));
    if (v < 0 || v > kMaxCount)
      return err(std::string(what) + " " + std::string(tok) + " is out of range");
    return v;
  }

  Result<int64_t> integer(std::string_view tok, const char* what) const {
    int64_t v = 0;
    if (!detail::parseInt(tok, v))
      return err(std::string("expected ") + what + ", found " + quote(tok));
    return v;
  }

  // A record line was expected; explain a short file or an early $End.
  Error missing(int64_t got, int64_t want, const char* what, bool eof) const {
    const std::string n = std::to_string(got) + " of " + std::to_string(want) + " " + what;
    if (eof) return err("unexpected end of file after " + n);
    return err("section ended after " + n + " (count in the header is larger), found " +
               quote(m_line));
  }

  bool nextRecord(bool& eof) {
    eof = !nextTokens();
    return !eof && m_tok[0][0] != '$';
  }

  Result<void> expectEnd(const char* end, const std::string& after) {
    if (!nextTokens()) return err(std::string("unexpected end of file: missing ") + end);
    if (m_tok[0] != end) {
      return err(std::string("expected ") + end + " after " + after +
                 " (more records than the header's count?), found " + quote(m_line));
    }
    return {};
  }

  Result<void> readFormat() {
    if (!nextTokens()) return err("unexpected end of file in $MeshFormat");
    if (m_tok.size() < 3)
      return err("expected 'version file-type data-size', found " + quote(m_line));
    const std::string_view version = m_tok[0];
    if (version == "4.1") {
      m_v4 = true;
    } else if (version.substr(0, 2) == "2." || version == "2") {
      m_v4 = false;
    } else {
      return err("unsupported Gmsh format version " + quote(version) + " (expected 2.2 or 4.1)");
    }
    if (m_tok[1] != "0") {
      return err("binary .msh files are not supported (file-type " + std::string(m_tok[1]) +
                 "); save as ASCII");
    }
    return expectEnd("$EndMeshFormat", "the format line");
  }

  Result<void> skipSection(std::string_view name) {
    const std::string end = "$End" + std::string(name.substr(1));
    const int start = m_f.line();
    while (nextTokens()) {
      if (m_tok[0] == end) return {};
    }
    return err("unexpected end of file: section " + std::string(name) + " opened on line " +
               std::to_string(start) + " has no " + end);
  }

  // Reads "x y z" from tokens [first, first + 3) of the current line into the raw mesh.
  Result<void> coordinates(size_t first, int64_t tag) {
    for (size_t k = 0; k < 3; ++k) {
      double x = 0;
      if (!detail::parseDouble(m_tok[first + k], x)) {
        return err("node " + std::to_string(tag) + ": expected a coordinate, found " +
                   quote(m_tok[first + k]));
      }
      if (!std::isfinite(x)) {
        return err("node " + std::to_string(tag) + ": non-finite coordinate " +
                   quote(m_tok[first + k]));
      }
      m_raw.positions.push_back(x);
    }
    return {};
  }

  void reserveNodes(int64_t n) {
    const size_t r = static_cast<size_t>(std::min(n, kMaxReserve));
    m_raw.positions.reserve(3 * r);
    m_raw.nodeTags.reserve(r);
    m_raw.nodeLines.reserve(r);
  }

  Result<void> readNodes2() {
    if (!nextTokens()) return err("unexpected end of file in $Nodes");
    Result<int64_t> n = count(m_tok[0], "a node count");
    if (!n) return n.error();
    reserveNodes(n.value());
    for (int64_t i = 0; i < n.value(); ++i) {
      bool eof = false;
      if (!nextRecord(eof)) return missing(i, n.value(), "nodes", eof);
      if (m_tok.size() != 4) {
        return err("expected 'tag x y z' (4 values), found " + std::to_string(m_tok.size()));
      }
      Result<int64_t> tag = integer(m_tok[0], "a node tag");
      if (!tag) return tag.error();
      if (Result<void> r = coordinates(1, tag.value()); !r) return r;
      m_raw.nodeTags.push_back(tag.value());
      m_raw.nodeLines.push_back(m_f.line());
    }
    return expectEnd("$EndNodes", std::to_string(n.value()) + " nodes");
  }

  Result<void> readNodes4() {
    if (!nextTokens()) return err("unexpected end of file in $Nodes");
    if (m_tok.size() != 4) {
      return err("expected 'numEntityBlocks numNodes minNodeTag maxNodeTag', found " +
                 quote(m_line));
    }
    Result<int64_t> blocks = count(m_tok[0], "a block count");
    if (!blocks) return blocks.error();
    Result<int64_t> n = count(m_tok[1], "a node count");
    if (!n) return n.error();
    reserveNodes(n.value());
    int64_t total = 0;
    for (int64_t b = 0; b < blocks.value(); ++b) {
      bool eof = false;
      if (!nextRecord(eof)) return missing(b, blocks.value(), "node blocks", eof);
      if (m_tok.size() != 4) {
        return err("expected 'entityDim entityTag parametric numNodesInBlock', found " +
                   quote(m_line));
      }
      Result<int64_t> parametric = integer(m_tok[2], "the parametric flag");
      if (!parametric) return parametric.error();
      if (parametric.value() != 0 && parametric.value() != 1) {
        return err("parametric flag must be 0 or 1, found " + quote(m_tok[2]));
      }
      Result<int64_t> inBlock = count(m_tok[3], "a block node count");
      if (!inBlock) return inBlock.error();
      if (inBlock.value() > n.value() - total) {
        return err("node blocks hold more than the header's " + std::to_string(n.value()) +
                   " nodes");
      }
      const size_t first = m_raw.nodeTags.size();
      for (int64_t i = 0; i < inBlock.value(); ++i) {
        if (!nextRecord(eof)) return missing(total + i, n.value(), "node tags", eof);
        if (m_tok.size() != 1) return err("expected one node tag, found " + quote(m_line));
        Result<int64_t> tag = integer(m_tok[0], "a node tag");
        if (!tag) return tag.error();
        m_raw.nodeTags.push_back(tag.value());
      }
      for (int64_t i = 0; i < inBlock.value(); ++i) {
        if (!nextRecord(eof)) return missing(total + i, n.value(), "node coordinates", eof);
        const int64_t tag = m_raw.nodeTags[first + static_cast<size_t>(i)];
        if (m_tok.size() < 3)
          return err("node " + std::to_string(tag) + ": expected 'x y z', found " + quote(m_line));
        if (Result<void> r = coordinates(0, tag); !r) return r;
        m_raw.nodeLines.push_back(m_f.line());
      }
      total += inBlock.value();
    }
    if (total != n.value()) {
      return err("node blocks hold " + std::to_string(total) + " nodes but the header says " +
                 std::to_string(n.value()));
    }
    return expectEnd("$EndNodes", std::to_string(blocks.value()) + " node blocks");
  }

  void reserveTets(int64_t n) {
    const size_t r = static_cast<size_t>(std::min(n, kMaxReserve));
    m_raw.tetNodeTags.reserve(4 * r);
    m_raw.tetTags.reserve(r);
    m_raw.tetLines.reserve(r);
  }

  // Stores a tet from 4 node-tag tokens starting at `first`.
  Result<void> tet(int64_t tag, size_t first) {
    for (size_t k = 0; k < 4; ++k) {
      int64_t v = 0;
      if (!detail::parseInt(m_tok[first + k], v)) {
        return err("element " + std::to_string(tag) + ": expected a node tag, found " +
                   quote(m_tok[first + k]));
      }
      m_raw.tetNodeTags.push_back(v);
    }
    m_raw.tetTags.push_back(tag);
    m_raw.tetLines.push_back(m_f.line());
    return {};
  }

  Result<void> readElements2() {
    if (!nextTokens()) return err("unexpected end of file in $Elements");
    Result<int64_t> n = count(m_tok[0], "an element count");
    if (!n) return n.error();
    reserveTets(n.value());
    for (int64_t i = 0; i < n.value(); ++i) {
      bool eof = false;
      if (!nextRecord(eof)) return missing(i, n.value(), "elements", eof);
      if (m_tok.size() < 3) return err("expected 'tag type ntags ...', found " + quote(m_line));
      Result<int64_t> tag = integer(m_tok[0], "an element tag");
      if (!tag) return tag.error();
      Result<int64_t> type = integer(m_tok[1], "an element type");
      if (!type) return type.error();
      Result<int64_t> ntags = count(m_tok[2], "a tag count");
      if (!ntags) return ntags.error();
      if (type.value() == kTet10) ++m_tet10;
      if (type.value() != kTet4) continue;
      const size_t want = 3 + static_cast<size_t>(ntags.value()) + 4;
      if (m_tok.size() != want) {
        return err("element " + std::to_string(tag.value()) + ": tetrahedron with " +
                   std::to_string(ntags.value()) + " tags needs " + std::to_string(want) +
                   " values, found " + std::to_string(m_tok.size()));
      }
      if (Result<void> r = tet(tag.value(), 3 + static_cast<size_t>(ntags.value())); !r) return r;
    }
    return expectEnd("$EndElements", std::to_string(n.value()) + " elements");
  }

  Result<void> readElements4() {
    if (!nextTokens()) return err("unexpected end of file in $Elements");
    if (m_tok.size() != 4) {
      return err("expected 'numEntityBlocks numElements minElementTag maxElementTag', found " +
                 quote(m_line));
    }
    Result<int64_t> blocks = count(m_tok[0], "a block count");
    if (!blocks) return blocks.error();
    Result<int64_t> n = count(m_tok[1], "an element count");
    if (!n) return n.error();
    reserveTets(n.value());
    int64_t total = 0;
    for (int64_t b = 0; b < blocks.value(); ++b) {
      bool eof = false;
      if (!nextRecord(eof)) return missing(b, blocks.value(), "element blocks", eof);
      if (m_tok.size() != 4) {
        return err("expected 'entityDim entityTag elementType numElementsInBlock', found " +
                   quote(m_line));
      }
      Result<int64_t> type = integer(m_tok[2], "an element type");
      if (!type) return type.error();
      Result<int64_t> inBlock = count(m_tok[3], "a block element count");
      if (!inBlock) return inBlock.error();
      if (inBlock.value() > n.value() - total) {
        return err("element blocks hold more than the header's " + std::to_string(n.value()) +
                   " elements");
      }
      for (int64_t i = 0; i < inBlock.value(); ++i) {
        if (!nextRecord(eof)) return missing(total + i, n.value(), "elements", eof);
        Result<int64_t> tag = integer(m_tok[0], "an element tag");
        if (!tag) return tag.error();
        if (type.value() == kTet10) ++m_tet10;
        if (type.value() != kTet4) continue;
        if (m_tok.size() != 5) {
          return err("element " + std::to_string(tag.value()) +
                     ": tetrahedron needs a tag and 4 node tags, found " +
                     std::to_string(m_tok.size()) + " values");
        }
        if (Result<void> r = tet(tag.value(), 1); !r) return r;
      }
      total += inBlock.value();
    }
    if (total != n.value()) {
      return err("element blocks hold " + std::to_string(total) + " elements but the header says " +
                 std::to_string(n.value()));
    }
    return expectEnd("$EndElements", std::to_string(blocks.value()) + " element blocks");
  }

  detail::TextFile& m_f;
  detail::RawMesh& m_raw;
  std::string_view m_line;
  std::vector<std::string_view> m_tok;
  bool m_v4 = false, m_sawNodes = false, m_sawElements = false;
  int64_t m_tet10 = 0;
};

}  // namespace

Result<TetMesh> TetMesh::fromGmsh(const std::string& path, MeshLoadInfo* info) {
  // Nothing escapes as an exception: allocation failure on an absurd file becomes an error.
  try {
    Result<detail::TextFile> file = detail::TextFile::read(path);
    if (!file) return file.error();
    detail::RawMesh raw;
    raw.nodeFile = raw.tetFile = path;
    GmshReader reader(file.value(), raw);
    if (Result<void> r = reader.run(); !r) return r.error();
    return detail::finishRawMesh(std::move(raw), info);
  } catch (const std::exception& e) {
    return fail(path, ": ", e.what());
  }
}

}  // namespace gf
