#include "bench/bench_output.h"

#include <fmt/format.h>

#include <cstdlib>

#include "core/error.h"
#include "core/file_util.h"

namespace lfgi::bench {

std::string num(double v) {
  return fmt::format("{:.6g}", v);
}

BenchOutput::BenchOutput(std::filesystem::path dir, bool quick) : dir_(std::move(dir)), quick_(quick) {
  std::error_code ec;
  std::filesystem::create_directories(dir_, ec);
  if (ec) fail("{}: cannot create benchmark output directory ({})", dir_.string(), ec.message());
}

void BenchOutput::setColumns(std::vector<std::string> columns) {
  columns_ = std::move(columns);
}

void BenchOutput::addRow(const std::vector<std::string>& values) {
  if (values.size() != columns_.size())
    fail("benchmark row has {} values for {} columns", values.size(), columns_.size());
  rows_.push_back(values);
}

void BenchOutput::save() const {
  std::string csv;
  for (size_t i = 0; i < columns_.size(); ++i) csv += (i ? "," : "") + columns_[i];
  csv += "\n";
  for (const auto& row : rows_) {
    for (size_t i = 0; i < row.size(); ++i) csv += (i ? "," : "") + row[i];
    csv += "\n";
  }
  writeFileAtomic(dir_ / "results.csv", csv);
  nlohmann::ordered_json s = summary_;
  const char* commit = std::getenv("LFGI_COMMIT");
  s["commit"] = commit && *commit ? commit : "unknown";
  s["quick"] = quick_;
  writeFileAtomic(dir_ / "summary.json", s.dump(2) + "\n");
}

}  // namespace lfgi::bench
