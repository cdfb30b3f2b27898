#include "bake/bake_records.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <fstream>
#include <sstream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "bake/parallel_work.h"
#include "core/error.h"
#include "core/file_util.h"

namespace lfgi::bake {

namespace fs = std::filesystem;

namespace {

fs::path cellPathWithExtension(const fs::path& outDir, worlds::CellCoord c, const char* extension) {
  fs::path p = cellFilePath(outDir, c);
  p.replace_extension(extension);
  return p;
}

std::optional<worlds::CellKind> kindFromName(const std::string& name) {
  for (size_t k = 0; k < kCellKindCount; ++k)
    if (worlds::cellKindName(worlds::CellKind(k)) == name) return worlds::CellKind(k);
  return std::nullopt;
}

CellBakeRecord parseRecord(const fs::path& file) {
  const std::vector<std::byte> bytes = readFileBytes(file);
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(reinterpret_cast<const char*>(bytes.data()),
                              reinterpret_cast<const char*>(bytes.data()) + bytes.size());
    CellBakeRecord r;
    r.cell = {j.at("cell").at(0).get<int>(), j.at("cell").at(1).get<int>()};
    const std::string kind = j.at("kind").get<std::string>();
    const std::optional<worlds::CellKind> k = kindFromName(kind);
    if (!k) fail("{}: unknown cell kind '{}'", file.string(), kind);
    r.kind = *k;
    r.inputHash = std::stoull(j.at("input_hash").get<std::string>(), nullptr, 16);
    r.probes = j.at("probes").get<size_t>();
    r.network = j.at("network").get<bool>();
    r.model = j.at("model").get<std::string>();
    const nlohmann::json& s = j.at("seconds");
    r.prepareSeconds = s.at("prepare").get<double>();
    r.captureSeconds = s.at("capture").get<double>();
    r.trainingSeconds = s.at("training").get<double>();
    r.totalSeconds = s.at("total").get<double>();
    if (!(r.totalSeconds >= 0.0) || !std::isfinite(r.totalSeconds))
      fail("{}: seconds.total {} is not a duration", file.string(), r.totalSeconds);
    r.bytes = j.at("bytes").get<uint64_t>();
    r.host = j.at("host").get<std::string>();
    r.finishedUtc = j.at("finished_utc").get<std::string>();
    return r;
  } catch (const nlohmann::json::exception& e) {
    fail("{}: not a cell bake record: {}", file.string(), e.what());
  } catch (const std::invalid_argument&) {
    fail("{}: input_hash is not hexadecimal", file.string());
  } catch (const std::out_of_range&) {
    fail("{}: input_hash is out of range", file.string());
  }
}

}  // namespace

fs::path cellRecordPath(const fs::path& outDir, worlds::CellCoord c) {
  return cellPathWithExtension(outDir, c, ".json");
}
fs::path cellFailurePath(const fs::path& outDir, worlds::CellCoord c) {
  return cellPathWithExtension(outDir, c, ".failed");
}

void writeCellBakeRecord(const fs::path& outDir, const CellBakeRecord& r) {
  nlohmann::ordered_json j;
  j["cell"] = {r.cell.x, r.cell.z};
  j["kind"] = std::string(worlds::cellKindName(r.kind));
  j["input_hash"] = fmt::format("{:016x}", r.inputHash);
  j["probes"] = r.probes;
  j["network"] = r.network;
  j["model"] = r.model;
  j["seconds"] = {{"prepare", r.prepareSeconds},
                  {"capture", r.captureSeconds},
                  {"training", r.trainingSeconds},
                  {"total", r.totalSeconds}};
  j["bytes"] = r.bytes;
  j["host"] = r.host;
  j["finished_utc"] = r.finishedUtc;
  writeFileAtomic(cellRecordPath(outDir, r.cell), j.dump(2) + "\n");
}

std::optional<CellBakeRecord> readCellBakeRecord(const fs::path& outDir, worlds::CellCoord c) {
  const fs::path file = cellRecordPath(outDir, c);
  std::error_code ec;
  if (!fs::exists(file, ec)) return std::nullopt;
  return parseRecord(file);
}

std::vector<CellBakeRecord> readAllCellBakeRecords(const fs::path& outDir) {
  std::vector<CellBakeRecord> records;
  std::error_code ec;
  const fs::path dir = outDir / "cells";
  if (!fs::is_directory(dir, ec)) return records;
  std::vector<fs::path> files;
  for (const fs::directory_entry& e : fs::directory_iterator(dir, ec))
    if (e.path().extension() == ".json" && e.path().filename().string().starts_with("cell_"))
      files.push_back(e.path());
  std::sort(files.begin(), files.end());  // directory order differs between file systems
  for (const fs::path& f : files) {
    try {
      records.push_back(parseRecord(f));
    } catch (const Error& e) {
      spdlog::warn("skipping bake record: {}", e.what());
    }
  }
  return records;
}

void writeCellBakeFailure(const fs::path& outDir, worlds::CellCoord c, const std::string& error) {
  std::string firstLine = error.substr(0, error.find('\n'));
  writeFileAtomic(cellFailurePath(outDir, c),
                  fmt::format("{}\nhost: {}\ntime: {}\n", firstLine, hostName(), utcNow()));
}

void clearCellBakeFailure(const fs::path& outDir, worlds::CellCoord c) {
  std::error_code ec;
  fs::remove(cellFailurePath(outDir, c), ec);
}

std::optional<std::string> readCellBakeFailure(const fs::path& outDir, worlds::CellCoord c) {
  const fs::path file = cellFailurePath(outDir, c);
  std::ifstream in(file);
  if (!in) return std::nullopt;
  std::string line;
  std::getline(in, line);
  return line.empty() ? std::string("(no message)") : line;
}

std::string hostName() {
  char buf[256] = {};
  if (gethostname(buf, sizeof buf - 1) != 0) return "unknown";
  return buf;
}

std::string utcNow() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

const char* cellStatusName(CellStatus s) {
  switch (s) {
    case CellStatus::Done:
      return "done";
    case CellStatus::Stale:
      return "stale";
    case CellStatus::Missing:
      return "missing";
    case CellStatus::Failed:
      return "failed";
    case CellStatus::Corrupt:
      return "corrupt";
  }
  return "unknown";
}

std::vector<CellStatusEntry> worldBakeStatus(const worlds::SyntheticWorld& world,
                                             const std::vector<worlds::CellCoord>& cells,
                                             const WorldBakeSettings& settings, const fs::path& outDir,
                                             bool showProgress) {
  settings.validate();
  std::vector<CellStatusEntry> out(cells.size());
  const uint64_t sharedHash =
      currentSharedModelHash(world, settings, outDir);  // 0: per-cell codec or none yet
  // The input hash builds the cell (probe placement) and its neighbours' meshes: the expensive part, so only
  // cells with a readable file pay it; a missing file needs no hash.
  const detail::ParallelWorkResult r =
      detail::runParallelInterruptible(cells.size(), "bake-status", "cells", showProgress, [&](size_t i) {
        CellStatusEntry& e = out[i];
        e.cell = cells[i];
        e.kind = world.cellKind(e.cell);
        const std::optional<std::string> failure = readCellBakeFailure(outDir, e.cell);
        const fs::path file = cellFilePath(outDir, e.cell);
        std::error_code ec;
        if (!fs::exists(file, ec)) {
          e.status = failure ? CellStatus::Failed : CellStatus::Missing;
          if (failure) e.detail = *failure;
          return;
        }
        uint64_t stored = 0;
        try {
          stored = readCellFile(file).inputHash;
        } catch (
            const std::exception& err) {  // lfgi::Error, or e.g. bad_alloc from a reader bug: still corrupt
          e.status = failure ? CellStatus::Failed : CellStatus::Corrupt;
          e.detail = failure ? *failure : std::string(err.what());
          return;
        }
        if (stored == cellInputHash(world, e.cell, settings, sharedHash)) {
          e.status = CellStatus::Done;  // a failure marker beside an up-to-date file is left over
        } else if (failure) {
          e.status = CellStatus::Failed;
          e.detail = *failure;
        } else {
          e.status = CellStatus::Stale;
        }
      });
  if (r.interrupted) fail("bake-status: interrupted after {} of {} cells", r.done, cells.size());
  return out;
}

double BakeCostModel::secondsPerCell(worlds::CellKind kind) const {
  const size_t k = size_t(kind);
  return samples[k] > 0 ? meanSeconds[k] : overallMeanSeconds;
}

BakeCostModel costModelFromRecords(const std::vector<CellBakeRecord>& records) {
  if (records.empty()) fail("cost model: no bake records (cells/cell_X_Z.json); bake some cells first");
  BakeCostModel m;
  double all = 0.0;
  for (const CellBakeRecord& r : records) {
    const size_t k = size_t(r.kind);
    m.meanSeconds[k] += r.totalSeconds;
    ++m.samples[k];
    all += r.totalSeconds;
  }
  for (size_t k = 0; k < kCellKindCount; ++k)
    if (m.samples[k]) m.meanSeconds[k] /= double(m.samples[k]);
  m.totalSamples = records.size();
  m.overallMeanSeconds = all / double(records.size());
  return m;
}

worlds::WorldParams worldParamsForArea(double km2, double cellM, uint64_t seed) {
  if (!(km2 > 0.0) || !std::isfinite(km2)) fail("world area {} km^2: must be positive", km2);
  const double side = std::sqrt(km2) * 1000.0;
  const double cells = std::max(1.0, std::round(side / cellM));
  worlds::WorldParams p{seed, cells * cellM, cellM};
  p.validate();
  return p;
}

KindMix worldKindMix(const worlds::WorldParams& params) {
  const worlds::SyntheticWorld world(params);
  KindMix mix;
  mix.sizeM = params.sizeM;
  mix.cellM = params.cellM;
  mix.km2 = params.sizeM * params.sizeM / 1e6;
  for (int z = 0; z < world.cellsZ(); ++z)
    for (int x = 0; x < world.cellsX(); ++x) ++mix.cellsByKind[size_t(world.cellKind({x, z}))];
  mix.cells = size_t(world.cellsX()) * size_t(world.cellsZ());
  return mix;
}

BakeProjection projectBake(const BakeCostModel& model, const worlds::WorldParams& params) {
  BakeProjection p;
  p.mix = worldKindMix(params);
  for (size_t k = 0; k < kCellKindCount; ++k)
    p.cellSeconds += double(p.mix.cellsByKind[k]) * model.secondsPerCell(worlds::CellKind(k));
  return p;
}

}  // namespace lfgi::bake
