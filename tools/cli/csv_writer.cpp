#include "cli/csv_writer.h"

#include <cerrno>
#include <cstring>

namespace gf::cli {

CsvWriter::~CsvWriter() {
  if (m_file != nullptr) std::fclose(m_file);
}

Result<void> CsvWriter::open(const std::string& path, const std::vector<std::string>& columns) {
  if (m_file != nullptr) std::fclose(m_file);
  m_path = path;
  m_columns = columns.size();
  m_file = std::fopen(path.c_str(), "w");
  if (m_file == nullptr) return fail(path, ": cannot create: ", std::strerror(errno));
  for (size_t i = 0; i < columns.size(); ++i) {
    std::fputs(columns[i].c_str(), m_file);
    std::fputc(i + 1 < columns.size() ? ',' : '\n', m_file);
  }
  if (std::ferror(m_file)) return fail(path, ": write error");
  return {};
}

Result<void> CsvWriter::row(const std::vector<Value>& values) {
  if (m_file == nullptr) return fail(m_path, ": not open");
  if (values.size() != m_columns) {
    return fail(m_path, ": row has ", std::to_string(values.size()), " values for ",
                std::to_string(m_columns), " columns");
  }
  for (size_t i = 0; i < values.size(); ++i) {
    if (const int64_t* n = std::get_if<int64_t>(&values[i])) {
      std::fprintf(m_file, "%lld", static_cast<long long>(*n));
    } else if (const std::string* s = std::get_if<std::string>(&values[i])) {
      std::fputs(s->c_str(), m_file);
    } else {
      // 10 significant digits: enough to see a 1e-8 energy drift on a 1 J total.
      std::fprintf(m_file, "%.10g", std::get<double>(values[i]));
    }
    std::fputc(i + 1 < values.size() ? ',' : '\n', m_file);
  }
  std::fflush(m_file);
  if (std::ferror(m_file)) return fail(m_path, ": write error: ", std::strerror(errno));
  return {};
}

Result<void> CsvWriter::close() {
  if (m_file == nullptr) return {};
  const bool bad = std::ferror(m_file) != 0;
  const bool closeFailed = std::fclose(m_file) != 0;
  m_file = nullptr;
  if (bad || closeFailed) return fail(m_path, ": write error");
  return {};
}

}  // namespace gf::cli
