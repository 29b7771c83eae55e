#include "cli/results_regions.h"

#include <algorithm>

namespace gf::cli {

std::string regionMarker(const std::string& name, bool begin) {
  return "<!-- report:" + name + (begin ? ":begin" : ":end") + " -->";
}

namespace {

// A marker line: "<!-- report:NAME:begin -->" or ":end", surrounding blanks allowed. Any other
// line that starts with "<!-- report:" is a malformed marker, not text, so that a typo cannot
// leave a region silently unmanaged.
struct Marker {
  bool isMarker = false, malformed = false, begin = false;
  std::string name;
};

Marker readMarker(const std::string& line) {
  Marker m;
  const size_t first = line.find_first_not_of(" \t");
  if (first == std::string::npos) return m;
  const size_t last = line.find_last_not_of(" \t\r\n");
  const std::string s = line.substr(first, last - first + 1);
  const std::string open = "<!-- report:", close = " -->";
  if (s.rfind(open, 0) != 0) return m;
  m.isMarker = true;
  if (s.size() < open.size() + close.size() ||
      s.compare(s.size() - close.size(), close.size(), close) != 0) {
    m.malformed = true;
    return m;
  }
  const std::string body = s.substr(open.size(), s.size() - open.size() - close.size());
  const size_t colon = body.rfind(':');
  if (colon == std::string::npos || colon == 0) {
    m.malformed = true;
    return m;
  }
  const std::string kind = body.substr(colon + 1);
  m.name = body.substr(0, colon);
  if (kind != "begin" && kind != "end") m.malformed = true;
  m.begin = kind == "begin";
  return m;
}

}  // namespace

Result<MarkedText> parseMarkedText(const std::string& path, const std::string& content,
                                   const std::vector<std::string>& known) {
  MarkedText out;
  std::string knownList;
  for (const std::string& k : known) knownList += (knownList.empty() ? "" : ", ") + k;
  std::string current;  // the piece being collected
  std::string open;     // the region whose body is being collected ("" outside)
  int openLine = 0;
  std::vector<std::string> seen;
  size_t pos = 0;
  int lineNo = 0;
  while (pos < content.size()) {
    const size_t nl = content.find('\n', pos);
    const size_t end = nl == std::string::npos ? content.size() : nl + 1;
    const std::string line = content.substr(pos, end - pos);
    pos = end;
    ++lineNo;
    const Marker m = readMarker(line);
    const std::string where = path + ":" + std::to_string(lineNo) + ": ";
    if (!m.isMarker) {
      current += line;
      continue;
    }
    if (m.malformed)
      return fail(where, "malformed report marker '",
                  line.substr(0, line.find_last_not_of("\r\n") + 1), "' (expected ",
                  regionMarker("NAME", true), " or ", regionMarker("NAME", false), ")");
    if (std::find(known.begin(), known.end(), m.name) == known.end())
      return fail(where, "unknown region '", m.name, "' (known regions: ", knownList, ")");
    if (m.begin) {
      if (!open.empty())
        return fail(path, ":", std::to_string(openLine), ": region '", open,
                    "': missing end marker ", regionMarker(open, false), " (region '", m.name,
                    "' begins inside it at line ", std::to_string(lineNo), ")");
      if (std::find(seen.begin(), seen.end(), m.name) != seen.end())
        return fail(where, "region '", m.name, "' appears twice");
      current += line;
      out.text.push_back(std::move(current));
      current.clear();
      open = m.name;
      openLine = lineNo;
      seen.push_back(m.name);
    } else {
      if (open != m.name)
        return fail(where, "region '", m.name, "': end marker without its begin marker ",
                    regionMarker(m.name, true),
                    open.empty() ? "" : " (inside region '" + open + "')");
      out.names.push_back(open);
      out.contents.push_back(std::move(current));
      current = line;
      open.clear();
    }
  }
  if (!open.empty())
    return fail(path, ":", std::to_string(openLine), ": region '", open, "': missing end marker ",
                regionMarker(open, false));
  out.text.push_back(std::move(current));
  for (const std::string& k : known)
    if (std::find(seen.begin(), seen.end(), k) == seen.end())
      return fail(path, ": region '", k, "' is missing: add the lines ", regionMarker(k, true),
                  " and ", regionMarker(k, false), " where its generated table belongs");
  return out;
}

std::string spliceRegions(const MarkedText& marked,
                          const std::map<std::string, std::string>& replace) {
  std::string s = marked.text.empty() ? std::string() : marked.text[0];
  for (size_t i = 0; i < marked.names.size(); ++i) {
    const auto it = replace.find(marked.names[i]);
    if (it == replace.end()) {
      s += marked.contents[i];
    } else {
      s += it->second;
      if (!it->second.empty() && it->second.back() != '\n') s += '\n';
    }
    s += marked.text[i + 1];
  }
  return s;
}

}  // namespace gf::cli
