// The one output contract of every benchmark (docs/BENCHMARKS.md): out/bench/NAME/results.csv (one
// row per measured configuration, units in column names), summary.json (headline keys + "device",
// "commit", "quick"), and charts drawn by scripts/bench.sh from bench/NAME.gp. Files are written
// atomically so an interrupted run never leaves a half-written summary.
#pragma once

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace lfgi::bench {

class BenchOutput {
 public:
  BenchOutput(std::filesystem::path dir, bool quick);

  // Column names of results.csv (with units, e.g. "gflops"); call once before addRow.
  void setColumns(std::vector<std::string> columns);
  // One row; values are printed as given (numbers via fmt "{}"), count must match the columns.
  void addRow(const std::vector<std::string>& values);
  nlohmann::ordered_json& summary() { return summary_; }
  void setDevice(const std::string& device) { summary_["device"] = device; }

  // Writes results.csv and summary.json (adds "commit" from $LFGI_COMMIT and "quick").
  void save() const;
  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_;
  bool quick_;
  std::vector<std::string> columns_;
  std::vector<std::vector<std::string>> rows_;
  nlohmann::ordered_json summary_;
};

// Formats a number for CSV with full precision.
std::string num(double v);

}  // namespace lfgi::bench
