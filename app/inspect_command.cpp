// `lfgi inspect FILE`: what a cell file (or a region file, .lfgr) holds and what each part costs
// (docs/DESIGN.md §3), and
// the hidden `lfgi debug-write-cell`, which writes a small synthetic cell file for the CLI tests and for
// trying inspect without a bake.
#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "app/commands.h"
#include "core/cell_file.h"
#include "core/error.h"
#include "core/generator_cpu.h"
#include "core/half.h"
#include "core/region_file.h"

namespace lfgi::app {

namespace {

std::string archText(const GeneratorArch& a) {
  std::string ch;
  for (size_t i = 0; i < a.convChannels.size(); ++i) ch += (i ? "-" : "") + std::to_string(a.convChannels[i]);
  return fmt::format("latent {} + cond {} -> linear 4x4x{} -> {} transposed convs {} -> {}x{}, {} parameters",
                     a.latentDim, a.condDim, a.convChannels.front(), a.layers(), ch, a.outputResolution(),
                     a.outputResolution(), a.parameterCount());
}

std::string latentText(const CellFile& c) {
  const CellGenerator& g = *c.generator;
  if (g.weights.arch.latentSource == LatentSource::PositionFourier)
    return fmt::format("derived from probe position ({} Fourier octaves, 0 bytes)",
                       g.weights.arch.fourierOctaves);
  return fmt::format("stored per probe, {}-bit", g.latents.bits);
}

// A region file (core/region_file.h): its cells and where its bytes go.
int inspectRegion(const InspectOptions& options) {
  const RegionFile f = RegionFile::open(options.file);
  const RegionFileBytes b = f.bytesByPart();
  nlohmann::ordered_json cells = nlohmann::json::array();
  int64_t probes = 0;
  for (size_t i = 0; i < f.cells().size(); ++i) {
    const CellFile c = f.readCell(i);
    probes += c.activeProbeCount();
    cells.push_back({{"cell", {c.cellX, c.cellZ}},
                     {"probes", c.activeProbeCount()},
                     {"record_bytes", f.cells()[i].length},
                     {"model", c.stats.model}});
  }
  const size_t n = f.cells().size();
  nlohmann::ordered_json j;
  j["file"] = options.file;
  j["region"] = {f.region().x, f.region().y};
  j["cells_per_side"] = f.cellsPerSide();
  j["bytes"] = {{"total", b.total()},        {"head", b.head},
                {"records", b.records},      {"light_field", b.payload},
                {"probe_masks", b.topology}, {"container_per_cell", b.containerPerCell(n)}};
  j["probes"] = probes;
  j["bytes_per_probe"] = probes ? double(b.total()) / double(probes) : 0.0;
  j["cells"] = cells;
  if (options.json) {
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
  std::printf("%s: region (%d, %d), %zu of %dx%d cells, %lld probes\n", options.file.c_str(), f.region().x,
              f.region().y, n, f.cellsPerSide(), f.cellsPerSide(), (long long)probes);
  std::printf(
      "bytes: %llu = head %llu + records %llu; light field %llu, probe masks %llu, container %.1f B/cell; "
      "%.2f B/probe all-in\n",
      (unsigned long long)b.total(), (unsigned long long)b.head, (unsigned long long)b.records,
      (unsigned long long)b.payload, (unsigned long long)b.topology, b.containerPerCell(n),
      j["bytes_per_probe"].get<double>());
  for (const auto& c : cells)
    std::printf("  cell (%d, %d): %lld probes, %llu B, %s\n", c["cell"][0].get<int>(),
                c["cell"][1].get<int>(), (long long)c["probes"].get<int64_t>(),
                (unsigned long long)c["record_bytes"].get<uint64_t>(), c["model"].get<std::string>().c_str());
  return 0;
}

}  // namespace

int runInspect(const InspectOptions& options) {
  if (std::filesystem::path(options.file).extension() == ".lfgr") return inspectRegion(options);
  CellFileBytes bytes;
  CellFile c = readCellFile(options.file, &bytes);
  const int64_t probes = c.activeProbeCount();
  const double perProbe = probes ? double(bytes.total) / double(probes) : 0.0;
  const bool int8 = c.fallback.precision == CellFallback::Precision::L1Int8;
  const char* fallbackKind = c.fallback.kind == CellFallback::Kind::PerCell
                                 ? (int8 ? "SH L1 int8 per cell" : "SH L1 per cell")
                                 : (int8 ? "SH L1 int8 per probe" : "SH L1 per probe");
  const char* fallbackPrecision = int8 ? "L0 FP16 + L1 int8" : "FP16";

  if (options.json) {
    nlohmann::ordered_json j;
    j["file"] = options.file;
    j["format_version"] = bytes.version;
    j["world_seed"] = fmt::format("{:016x}", c.worldSeed);
    j["cell"] = {c.cellX, c.cellZ};
    j["input_hash"] = fmt::format("{:016x}", c.inputHash);
    j["probes"] = probes;
    j["probe_grid"] = {{"dims", {c.grid.dims.x, c.grid.dims.y, c.grid.dims.z}},
                       {"spacing", {c.grid.spacing.x, c.grid.spacing.y, c.grid.spacing.z}},
                       {"origin", {c.grid.origin.x, c.grid.origin.y, c.grid.origin.z}}};
    if (c.generator) {
      const GeneratorArch& a = c.generator->weights.arch;
      j["model"] = {{"network", true},
                    {"latent_dim", a.latentDim},
                    {"cond_dim", a.condDim},
                    {"conv_channels", a.convChannels},
                    {"output_resolution", a.outputResolution()},
                    {"parameters", a.parameterCount()},
                    {"latent_source", a.latentSource == LatentSource::Stored ? "stored" : "position_fourier"},
                    {"latent_bits", a.latentSource == LatentSource::Stored ? c.generator->latents.bits : 0},
                    {"weights", weightPrecisionName(c.generator->weights.precision)}};
      if (c.generator->shared)
        j["model"]["shared_model"] = {{"hash", fmt::format("{:016x}", c.generator->shared->modelHash)},
                                      {"adapter_stages", c.generator->shared->adapter.stages},
                                      {"adapter_bits", c.generator->shared->adapter.bits},
                                      {"adapter_bytes", bytes.adapter}};
    } else {
      j["model"] = {{"network", false}};
    }
    j["fallback"] = fallbackKind;
    {
      nlohmann::ordered_json keys = nlohmann::ordered_json::array();
      for (size_t k = 0; k < c.fallback.keyCount(); ++k)
        keys.push_back({{"hours", c.fallback.keyHours[k]}, {"overcast", c.fallback.keyOvercast[k]}});
      j["fallback_keys"] = keys;
    }
    j["exposure"] = c.outputScale.exposure;
    j["range_m"] = c.outputScale.range;
    j["bytes"] = {{"weights", bytes.weights},     {"adapter", bytes.adapter},   {"latents", bytes.latents},
                  {"metadata", bytes.metadata()}, {"fallback", bytes.fallback}, {"total", bytes.total},
                  {"per_probe", perProbe}};
    j["error_achieved"] = c.stats.errorAchieved;
    j["error_target"] = c.stats.errorTarget;
    j["training_seconds"] = c.stats.trainingSeconds;
    j["chosen_model"] = c.stats.model;
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }

  std::printf("%s: cell (%d, %d) of world seed %016llx, cell file version %d, input hash %016llx\n",
              options.file.c_str(), c.cellX, c.cellZ, static_cast<unsigned long long>(c.worldSeed),
              bytes.version, static_cast<unsigned long long>(c.inputHash));
  if (c.generator && c.generator->shared) {
    const CellSharedModelRef& ref = *c.generator->shared;
    std::printf(
        "model: world-shared %s generator %016llx (shared_model.vdb beside cells/), %s; FiLM adapter %d "
        "stage(s), %d-bit, %zu bytes; latents %s\n",
        weightPrecisionName(c.generator->weights.precision), static_cast<unsigned long long>(ref.modelHash),
        archText(c.generator->weights.arch).c_str(), ref.adapter.stages, ref.adapter.bits, bytes.adapter,
        latentText(c).c_str());
  } else if (c.generator) {
    const GeneratorArch& a = c.generator->weights.arch;
    std::printf("model: %s generator, %s; latents %s\n", weightPrecisionName(c.generator->weights.precision),
                archText(a).c_str(), latentText(c).c_str());
  } else {
    std::printf("model: no network (%s only)\n", fallbackKind);
  }
  std::printf("probes: %lld of %lld (grid %dx%dx%d, spacing %g x %g x %g m, origin %g, %g, %g)\n",
              static_cast<long long>(probes), static_cast<long long>(c.grid.probeCount()), c.grid.dims.x,
              c.grid.dims.y, c.grid.dims.z, double(c.grid.spacing.x), double(c.grid.spacing.y),
              double(c.grid.spacing.z), double(c.grid.origin.x), double(c.grid.origin.y),
              double(c.grid.origin.z));
  std::printf(
      "bytes: weights %zu, adapter %zu, latents %zu, metadata %zu, fallback %zu (%s, %s), total %zu (%.1f "
      "per probe)\n",
      bytes.weights, bytes.adapter, bytes.latents, bytes.metadata(), bytes.fallback, fallbackKind,
      fallbackPrecision, bytes.total, perProbe);
  std::string keys;
  for (size_t k = 0; k < c.fallback.keyCount(); ++k)
    keys += fmt::format(
        "{}{} h{}", k ? ", " : "", c.fallback.keyHours[k],
        c.fallback.keyOvercast[k] > 0.0f ? fmt::format(" overcast {}", c.fallback.keyOvercast[k]) : "");
  std::printf("fallback keys: %s\n", keys.c_str());
  std::printf("error reached: %.4g (target %.4g); training time: %.2f s; chosen model: %s\n",
              c.stats.errorAchieved, c.stats.errorTarget, c.stats.trainingSeconds,
              c.stats.model.empty() ? "-" : c.stats.model.c_str());
  std::printf("exposure %g, distance range %g m\n", double(c.outputScale.exposure),
              double(c.outputScale.range));
  return 0;
}

int runDebugWriteCell(const DebugWriteCellOptions& options) {
  CellFile c;
  c.worldSeed = 42;
  c.cellX = 1;
  c.cellZ = 2;
  c.grid.origin = {64.0f, 0.0f, 128.0f};
  c.grid.spacing = {8.0f, 4.0f, 8.0f};
  c.grid.dims = {4, 3, 4};
  c.active.assign(size_t(c.grid.probeCount()), 1);
  c.active[5] = c.active[17] = 0;  // two probes inside solids
  const int64_t n = c.activeProbeCount();
  c.inputHash = ContentHasher().add(std::string("debug-write-cell")).addValue(n).digest();
  if (!options.noNetwork) {
    GeneratorArch a;
    a.latentDim = 8;
    a.convChannels = {16, 8, kGeneratorChannels};
    CellGenerator g;
    g.weights = quantizeWeights(randomGeneratorWeights(a, 7),
                                options.fp16 ? WeightPrecision::Float16 : WeightPrecision::Int8);
    std::vector<float> lat(size_t(n * a.latentDim));
    for (size_t i = 0; i < lat.size(); ++i) lat[i] = float(int(i * 37 % 17) - 8) / 8.0f;
    g.latents = quantizeLatents(lat, a.latentDim, options.latentBits);
    c.generator = std::move(g);
    c.stats.model = fmt::format("L8 C16-8 {}", options.fp16 ? "fp16" : "int8");
    c.stats.trainingSeconds = 1.5;
    c.stats.errorAchieved = 0.031;
  } else {
    c.stats.model = "no network: SH L1";
    c.stats.errorAchieved = 0.012;
  }
  c.stats.errorTarget = 0.05;
  c.fallback.kind = CellFallback::Kind::PerCell;
  for (int k = 0; k < 12; ++k) c.fallback.shHalf.push_back(floatToHalfClamped(k < 3 ? 1.0f : 0.1f));
  writeCellFile(options.out, c);
  std::printf("wrote %s (%lld probes, %s)\n", options.out.c_str(), static_cast<long long>(n),
              options.noNetwork ? "no network" : "network");
  return 0;
}

}  // namespace lfgi::app
