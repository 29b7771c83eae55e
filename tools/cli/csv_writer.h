// A minimal CSV writer for numeric tables: a header, then rows of numbers, flushed per row so
// that a run that is interrupted still leaves every finished frame on disk.
#pragma once

#include <graphfrac/status.h>

#include <cstdint>
#include <cstdio>
#include <string>
#include <variant>
#include <vector>

namespace gf::cli {

/// Writes one CSV file; numbers only (no quoting needed).
class CsvWriter {
 public:
  using Value = std::variant<int64_t, double, std::string>;  ///< strings are written as is

  CsvWriter() = default;
  ~CsvWriter();
  CsvWriter(const CsvWriter&) = delete;
  CsvWriter& operator=(const CsvWriter&) = delete;

  /// Creates (truncates) the file and writes the header row.
  Result<void> open(const std::string& path, const std::vector<std::string>& columns);
  /// Writes one row; the number of values must match the header.
  Result<void> row(const std::vector<Value>& values);
  /// Closes the file, reporting a late write error (e.g. a full disk).
  Result<void> close();

 private:
  std::FILE* m_file = nullptr;
  std::string m_path;
  size_t m_columns = 0;
};

}  // namespace gf::cli
