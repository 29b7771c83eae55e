// Text scanning for the mesh readers. The file is read whole (meshes are at most a few hundred
// MB) and walked with string_views, which is both fast and free of stream error states.
#include <cctype>
#include <charconv>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

#include "mesh/mesh_internal.h"

namespace gf::detail {

Result<TextFile> TextFile::read(const std::string& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) return fail(path, ": cannot open: no such file");
  if (!std::filesystem::is_regular_file(status)) return fail(path, ": not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail(path, ": cannot open for reading");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) return fail(path, ": read error");
  TextFile f;
  f.m_path = path;
  f.m_text = std::move(buffer).str();
  return f;
}

bool TextFile::next(std::string_view& line) {
  if (m_pos >= m_text.size()) return false;
  size_t end = m_text.find('\n', m_pos);
  if (end == std::string::npos) end = m_text.size();
  size_t len = end - m_pos;
  if (len > 0 && m_text[m_pos + len - 1] == '\r') --len;  // Windows line ends
  line = std::string_view(m_text).substr(m_pos, len);
  m_pos = end + 1;
  ++m_line;
  return true;
}

bool TextFile::blank() const {
  for (char c : m_text) {
    if (!std::isspace(static_cast<unsigned char>(c))) return false;
  }
  return true;
}

void splitTokens(std::string_view line, std::vector<std::string_view>& out, char comment) {
  out.clear();
  if (comment != '\0') {
    const size_t c = line.find(comment);
    if (c != std::string_view::npos) line = line.substr(0, c);
  }
  size_t i = 0;
  const size_t n = line.size();
  while (i < n) {
    while (i < n && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    const size_t start = i;
    while (i < n && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
}

bool parseInt(std::string_view token, int64_t& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  return ec == std::errc() && ptr == token.data() + token.size() && !token.empty();
}

bool parseDouble(std::string_view token, double& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  return ec == std::errc() && ptr == token.data() + token.size() && !token.empty();
}

std::string quote(std::string_view token) {
  constexpr size_t kMax = 40;
  std::string s = "'";
  s += token.substr(0, kMax);
  if (token.size() > kMax) s += "...";
  s += "'";
  return s;
}

std::string lowerExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

}  // namespace gf::detail
