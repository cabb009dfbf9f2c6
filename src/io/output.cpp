#include "refdyn/io/output.hpp"

#include "refdyn/common/error.hpp"
#include "refdyn/common/text.hpp"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <unistd.h>

namespace refdyn::io {

namespace fs = std::filesystem;

void prepare_output_dir(const fs::path& dir) {
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw Error("output folder '" + dir.string() + "': exists and is not a folder (hint: choose another --output)");
  fs::create_directories(dir, ec);
  if (ec) throw Error("output folder '" + dir.string() + "': cannot be created: " + ec.message());
  if (::access(dir.c_str(), W_OK | X_OK) != 0)
    throw Error("output folder '" + dir.string() + "': not writable: " + std::strerror(errno) +
                " (hint: choose another --output)");
}

void write_text_atomic(const fs::path& path, const std::string& content) {
  const fs::path tmp = path.string() + ".tmp." + std::to_string(::getpid());
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) throw Error("cannot write '" + tmp.string() + "': " + std::strerror(errno));
    f << content;
    f.flush();
    if (!f) {
      std::error_code ec;
      fs::remove(tmp, ec);
      throw Error("cannot write '" + path.string() + "': " + std::strerror(errno));
    }
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw Error("cannot move '" + tmp.string() + "' to '" + path.string() + "': " + ec.message());
  }
}

void CsvTable::add_row(std::vector<double> r) {
  if (r.size() != header.size())
    throw Error(expected_got("CSV row", std::to_string(header.size()) + " values", std::to_string(r.size())));
  rows.push_back(std::move(r));
}

std::string CsvTable::to_string() const {
  std::string s;
  s.reserve(rows.size() * header.size() * 22 + 256);
  for (size_t i = 0; i < header.size(); ++i) s += (i ? "," : "") + header[i];
  s += '\n';
  for (const auto& r : rows) {
    for (size_t i = 0; i < r.size(); ++i) {
      if (i) s += ',';
      s += std::isfinite(r[i]) ? fmt(r[i]) : std::string("nan");
    }
    s += '\n';
  }
  return s;
}

void write_csv_atomic(const fs::path& path, const CsvTable& t) { write_text_atomic(path, t.to_string()); }

}  // namespace refdyn::io
