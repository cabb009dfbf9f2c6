#pragma once
/// Output files, always written atomically: to a temporary file in the same folder, then
/// renamed over the target, so that a reader never sees a half-written file that looks valid.

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

namespace refdyn::io {

/// Creates `dir` (and parents) if needed and checks that a file can be written in it.
/// Throws refdyn::Error naming the folder and the system's reason.
void prepare_output_dir(const std::filesystem::path& dir);

/// Writes `content` to `path` atomically. Throws refdyn::Error on failure.
void write_text_atomic(const std::filesystem::path& path, const std::string& content);

/// A CSV table: header + rows of numbers (full round-trip precision).
struct CsvTable {
  std::vector<std::string> header;
  std::vector<std::vector<double>> rows;
  void add_row(std::vector<double> r);
  std::string to_string() const;
};
void write_csv_atomic(const std::filesystem::path& path, const CsvTable& table);


}  // namespace refdyn::io
