// lfgi: the command line. Subcommands are small functions in app/; library code does the work.
// Exit codes: 0 success, 1 runtime error (message names the file/device and the problem), 2 bad usage.
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <cstdio>
#include <optional>
#include <string>
#include <string_view>

#include "app/cli_args.h"
#include "app/commands.h"
#include "core/error.h"

namespace {

// Every subcommand's options, filled by the parse.
struct CliOptions {
  bool verbose = false;
  lfgi::app::DeviceOptions device;
  lfgi::app::DemoOptions demo;
  lfgi::app::WorldGenerateOptions generate;
  lfgi::app::WorldInfoOptions info;
  lfgi::app::WorldExportOptions exportCell;
  lfgi::app::WorldEditOptions edit;
  lfgi::app::CaptureCommandOptions capture;
  lfgi::app::ReferenceCommandOptions reference;
  lfgi::app::VirCommandOptions vir;
  lfgi::app::RenderCommandOptions render;
  lfgi::app::WorldBakeOptions bake;
  lfgi::app::PackOptions pack;
  lfgi::app::BakeStatusOptions bakeStatus;
  lfgi::app::FlyOptions fly, profile;
  lfgi::app::InspectOptions inspect;
  lfgi::app::DebugWriteCellOptions debugCell;
};

// The registered subcommands; after the parse, the one the command line named is set.
struct Subcommands {
  CLI::App* device = nullptr;
  CLI::App* demo = nullptr;
  CLI::App* generate = nullptr;
  CLI::App* info = nullptr;
  CLI::App* exportCell = nullptr;
  CLI::App* edit = nullptr;
  CLI::App* capture = nullptr;
  CLI::App* reference = nullptr;
  CLI::App* vir = nullptr;
  CLI::App* render = nullptr;
  CLI::App* bake = nullptr;
  CLI::App* pack = nullptr;
  CLI::App* bakeStatus = nullptr;
  CLI::App* fly = nullptr;
  CLI::App* profile = nullptr;
  CLI::App* inspect = nullptr;
  CLI::App* debugCell = nullptr;
};

void addDeviceCommand(CLI::App& app, CliOptions& opt, Subcommands& cmd) {
  cmd.device = app.add_subcommand("device", "Print the Vulkan device lfgi would use and its limits");
  cmd.device->add_flag("--json", opt.device.json, "Print JSON instead of text");
}

void addDemoCommand(CLI::App& app, CliOptions& opt, Subcommands& cmd) {
  lfgi::app::DemoOptions& demoOpt = opt.demo;
  CLI::App* demo = app.add_subcommand(
      "demo",
      "End-to-end run on the small default world: sky probe on the GPU, world cells, preview, report");
  cmd.demo = demo;
  demo->add_option("--out", demoOpt.outDir, "Output directory")->capture_default_str();
  demo->add_option("--resolution", demoOpt.resolution,
                   "Sky probe octahedral map resolution (texels per side)")
      ->check(CLI::Range(4, 512))
      ->capture_default_str();
  demo->add_option("--time", demoOpt.timeOfDay, "Time of day, hours")
      ->check(CLI::Range(0.0, 24.0))
      ->capture_default_str();
  demo->add_option("--overcast", demoOpt.overcast, "Weather, 0 clear .. 1 overcast")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  demo->add_option("--seed", demoOpt.seed, "World seed")->capture_default_str();
  demo->add_option("--world-size", demoOpt.worldSizeM, "World size in metres")
      ->check(CLI::Range(64.0, 1024.0))
      ->capture_default_str();
}

// `lfgi world edit`: the edits keep their command-line order across the three flags.
void addWorldEditCommand(CLI::App* world, CliOptions& opt, Subcommands& cmd) {
  lfgi::app::WorldEditOptions& editOpt = opt.edit;
  CLI::App* editCmd = world->add_subcommand("edit",
                                            "Append edits to a world (add a building or a box, clear a "
                                            "region); prints the cells whose content changed");
  cmd.edit = editCmd;
  editCmd->add_option("dir", editOpt.dir, "World directory")->required();
  for (const char* kind : {"add-building", "add-box", "clear-region"}) {
    const char* help = std::string_view(kind) == "add-building"
                           ? "Building on footprint X0,Z0,X1,Z1[,STOREYS] (inside one cell)"
                       : std::string_view(kind) == "add-box"
                           ? "Solid box X0,Y0,Z0,X1,Y1,Z1[,CATEGORY] (clipped per cell)"
                           : "Remove buildings and props overlapping X0,Z0,X1,Z1";
    editCmd
        ->add_option_function<std::string>(
            std::string("--") + kind,
            [&editOpt, kind](const std::string& v) { editOpt.edits.emplace_back(kind, v); }, help)
        ->trigger_on_parse()
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  }
}

void addWorldCommands(CLI::App& app, CliOptions& opt, Subcommands& cmd) {
  CLI::App* world = app.add_subcommand("world", "Synthetic world: generate cells, summarise, export")
                        ->require_subcommand(1);
  lfgi::app::WorldGenerateOptions& genOpt = opt.generate;
  CLI::App* gen =
      world->add_subcommand("generate", "Write a world manifest and (with --all or --cells) its cells");
  cmd.generate = gen;
  gen->add_option("--size", genOpt.sizeM, "World size in metres (square)")->capture_default_str();
  gen->add_option("--cell", genOpt.cellM, "Streaming cell size in metres")->capture_default_str();
  gen->add_option("--seed", genOpt.seed, "World seed")->capture_default_str();
  gen->add_option("--out", genOpt.outDir, "Output directory")->required();
  gen->add_flag("--all", genOpt.all, "Generate every cell now (resumable; progress on stderr)");
  gen->add_option("--cells", genOpt.cells, "Generate these cells, e.g. --cells 0,0 1,0");
  gen->add_option("--threads", genOpt.threads, "Worker threads (default: all cores)")
      ->check(CLI::Range(0, 256));
  lfgi::app::WorldInfoOptions& infoOpt = opt.info;
  CLI::App* info = world->add_subcommand("info", "Cells, triangles, surfels, probes, per-category counts");
  cmd.info = info;
  info->add_option("dir", infoOpt.dir, "World directory")->required();
  info->add_flag("--json", infoOpt.json, "Print JSON");
  lfgi::app::WorldExportOptions& exportOpt = opt.exportCell;
  CLI::App* exportCell = world->add_subcommand("export-cell", "Write one cell as a binary glTF (.glb)");
  cmd.exportCell = exportCell;
  exportCell->add_option("dir", exportOpt.dir, "World directory")->required();
  exportCell->add_option("--cell", exportOpt.cell, "Cell as X,Z")->required();
  exportCell->add_option("--out", exportOpt.out, "Output .glb file")->required();
  addWorldEditCommand(world, opt, cmd);
}

void addCaptureCommand(CLI::App& app, CliOptions& opt, Subcommands& cmd) {
  lfgi::app::CaptureCommandOptions& capOpt = opt.capture;
  CLI::App* capture =
      app.add_subcommand("capture", "Ground-truth probe capture of world cells or a test scene (resumable)");
  cmd.capture = capture;
  CLI::Option* capWorld = capture->add_option("--world", capOpt.world, "World directory (with --cells)");
  capture->add_option("--cells", capOpt.cells, "Cells to capture, e.g. --cells 0,0 1,0");
  capture->add_option("--scene", capOpt.scene, "Scene preset name or .gltf/.glb file")->excludes(capWorld);
  capture->add_option("--scenes-dir", capOpt.scenesDir, "Folder of the scene presets")->capture_default_str();
  capture->add_option("--scale", capOpt.scale, "Unit scale of a scene file (metres per unit)")
      ->check(CLI::PositiveNumber);
  capture->add_option("--probes", capOpt.probes, "Scene probe grid NX,NY,NZ (default: the preset's)");
  capture->add_option("--time", capOpt.timeOfDay, "Time of day, hours")
      ->check(CLI::Range(0.0, 24.0))
      ->capture_default_str();
  capture->add_option("--overcast", capOpt.overcast, "Weather, 0 clear .. 1 overcast")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  capture->add_option("--resolution", capOpt.resolution, "Octahedral map resolution")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  capture->add_option("--spp", capOpt.spp, "Samples per texel")
      ->check(CLI::Range(1, 65536))
      ->capture_default_str();
  capture->add_option("--bounces", capOpt.bounces, "Maximum bounces")
      ->check(CLI::Range(0, 256))
      ->capture_default_str();
  capture->add_option("--seed", capOpt.seed, "Random seed")->capture_default_str();
  capture->add_option("--out", capOpt.outDir, "Output directory")->required();
  capture->add_option("--threads", capOpt.threads, "Worker threads (default: all cores)")
      ->check(CLI::Range(0, 256));
}

void addReferenceCommand(CLI::App& app, CliOptions& opt, Subcommands& cmd) {
  lfgi::app::ReferenceCommandOptions& refOpt = opt.reference;
  CLI::App* reference =
      app.add_subcommand("reference", "Path-traced reference image with direct/indirect layers (EXR + PNG)");
  cmd.reference = reference;
  CLI::Option* refWorld = reference->add_option("--world", refOpt.world,
                                                "World directory (the camera's cell and its neighbours)");
  reference->add_option("--scene", refOpt.scene, "Scene preset name or .gltf/.glb file")->excludes(refWorld);
  reference->add_option("--scenes-dir", refOpt.scenesDir, "Folder of the scene presets")
      ->capture_default_str();
  reference->add_option("--scale", refOpt.scale, "Unit scale of a scene file (metres per unit)")
      ->check(CLI::PositiveNumber);
  reference->add_option("--camera", refOpt.camera, "Camera position and target: px,py,pz,tx,ty,tz")
      ->required();
  reference->add_option("--fov", refOpt.fov, "Vertical field of view, degrees")->capture_default_str();
  reference->add_option("--size", refOpt.size, "Image size WIDTHxHEIGHT")->capture_default_str();
  reference->add_option("--spp", refOpt.spp, "Samples per pixel")
      ->check(CLI::Range(1, 65536))
      ->capture_default_str();
  reference->add_option("--bounces", refOpt.bounces, "Maximum bounces")
      ->check(CLI::Range(0, 256))
      ->capture_default_str();
  reference->add_option("--time", refOpt.timeOfDay, "Time of day, hours")
      ->check(CLI::Range(0.0, 24.0))
      ->capture_default_str();
  reference->add_option("--overcast", refOpt.overcast, "Weather, 0 clear .. 1 overcast")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  reference->add_option("--seed", refOpt.seed, "Random seed")->capture_default_str();
  reference->add_option("--out", refOpt.out, "Output .exr (a .png is written beside it)")->required();
  reference->add_option("--threads", refOpt.threads, "Worker threads (default: all cores)")
      ->check(CLI::Range(0, 256));
}

void addVirCommand(CLI::App& app, CliOptions& opt, Subcommands& cmd) {
  lfgi::app::VirCommandOptions& virOpt = opt.vir;
  CLI::App* virCmd = app.add_subcommand(
      "vir", "Relight one world cell and splat it into its probes (VIR): EXR atlases + contact sheet");
  cmd.vir = virCmd;
  virCmd->add_option("--world", virOpt.world, "World directory")->required();
  virCmd->add_option("--cell", virOpt.cell, "Cell as X,Z")->required();
  virCmd->add_option("--time", virOpt.timeOfDay, "Time of day, hours")
      ->check(CLI::Range(0.0, 24.0))
      ->capture_default_str();
  virCmd->add_option("--overcast", virOpt.overcast, "Weather, 0 clear .. 1 overcast")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  virCmd->add_option("--out", virOpt.outDir, "Output directory")->required();
  virCmd->add_option("--resolution", virOpt.resolution, "Octahedral map resolution")
      ->check(CLI::Range(4, 128))
      ->capture_default_str();
  virCmd->add_option("--bounces", virOpt.bounces, "Indirect bounces (relight frames - 1)")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
}

// The render flags that select the probe source's settings, the PNG exposure, AO and the world's
// streaming fallback (after --threads, in this order in the help).
void addRenderSourceFlags(CLI::App* renderCmd, CLI::Option* renWorld,
                          lfgi::app::RenderCommandOptions& renderOpt) {
  renderCmd->add_option("--cell-file", renderOpt.cellFile,
                        "--probes codec: cell file of --cell (default WORLD/baked/cells/cell_X_Z.vdb)");
  renderCmd
      ->add_option("--vir-frames", renderOpt.virFrames,
                   "--probes vir: relight frames (1: direct light, each more: one bounce)")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  renderCmd
      ->add_option("--surfel-spacing", renderOpt.surfelSpacing,
                   "--probes vir on a scene: surfel spacing in m (0: bounding-box diagonal / 64)")
      ->check(CLI::Range(0.0, 100.0));
  renderCmd
      ->add_option("--exposure", renderOpt.exposure,
                   "Fixed PNG exposure in EV (default: auto, median luminance -> 0.18)")
      ->check(CLI::Range(-40.0, 40.0));
  renderCmd
      ->add_option("--ao-radius", renderOpt.aoRadius,
                   "Ray-traced ambient occlusion radius in m on indirect diffuse (0: off)")
      ->check(CLI::Range(0.0, 1e4));
  renderCmd
      ->add_flag("--neighbours-fallback", renderOpt.neighboursFallback,
                 "World: the 8 neighbour cells on their SH L1 streaming fallback instead of their probes "
                 "(shows the border blend)")
      ->needs(renWorld);
  renderCmd
      ->add_option("--cell-fade", renderOpt.cellFade,
                   "World: the cell's streaming cross-fade weight, 1 its probes .. 0 its SH L1 fallback")
      ->check(CLI::Range(0.0, 1.0))
      ->needs(renWorld)
      ->capture_default_str();
}

void addRenderCommand(CLI::App& app, CliOptions& opt, Subcommands& cmd) {
  lfgi::app::RenderCommandOptions& renderOpt = opt.render;
  CLI::App* renderCmd = app.add_subcommand("render",
                                           "Shade one view from light-field probes (EXR layers + PNG; "
                                           "--compare: path-traced reference, error map)");
  cmd.render = renderCmd;
  CLI::Option* renWorld = renderCmd->add_option("--world", renderOpt.world, "World directory (with --cell)");
  renderCmd->add_option("--cell", renderOpt.cell, "Cell as X,Z (its probes and its neighbours')");
  renderCmd->add_option("--scene", renderOpt.scene, "Scene preset name or .gltf/.glb file")
      ->excludes(renWorld);
  renderCmd->add_option("--scenes-dir", renderOpt.scenesDir, "Folder of the scene presets")
      ->capture_default_str();
  renderCmd->add_option("--scale", renderOpt.scale, "Unit scale of a scene file (metres per unit)")
      ->check(CLI::PositiveNumber);
  renderCmd->add_option("--grid", renderOpt.grid, "Scene probe grid NX,NY,NZ (default: the preset's)");
  renderCmd->add_option("--camera", renderOpt.camera, "Camera position and target: px,py,pz,tx,ty,tz")
      ->required();
  renderCmd->add_option("--fov", renderOpt.fov, "Vertical field of view, degrees")->capture_default_str();
  renderCmd->add_option("--size", renderOpt.size, "Image size WIDTHxHEIGHT")->capture_default_str();
  renderCmd->add_option("--time", renderOpt.timeOfDay, "Time of day, hours")
      ->check(CLI::Range(0.0, 24.0))
      ->capture_default_str();
  renderCmd->add_option("--overcast", renderOpt.overcast, "Weather, 0 clear .. 1 overcast")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  renderCmd
      ->add_option(
          "--probes", renderOpt.probes,
          "Probe source: capture (Embree), vir (GPU relight + VIR of surfels) or codec (baked cell files)")
      ->capture_default_str();
  renderCmd->add_option("--resolution", renderOpt.resolution, "Probe octahedral map resolution")
      ->check(CLI::Range(2, 128))
      ->capture_default_str();
  renderCmd->add_option("--spp", renderOpt.spp, "Capture samples per texel")
      ->check(CLI::Range(1, 65536))
      ->capture_default_str();
  renderCmd->add_option("--bounces", renderOpt.bounces, "Maximum bounces (capture and reference)")
      ->check(CLI::Range(0, 256))
      ->capture_default_str();
  renderCmd->add_option("--specular-levels", renderOpt.specularLevels, "GGX-prefiltered roughness levels")
      ->check(CLI::Range(1, 16))
      ->capture_default_str();
  renderCmd
      ->add_option(
          "--probe-radius", renderOpt.probeRadius,
          "World: capture the probes this close to the camera (m; default 0: those around visible surfaces)")
      ->check(CLI::Range(0.0, 1e5))
      ->capture_default_str();
  renderCmd->add_flag("--no-chebyshev", renderOpt.noChebyshev, "Turn off visibility weights (shows leaks)");
  renderCmd->add_flag("--compare", renderOpt.compare,
                      "Also path-trace the reference, write an error map, print the relative RMS");
  renderCmd->add_option("--reference-spp", renderOpt.referenceSpp, "Reference samples per pixel")
      ->check(CLI::Range(1, 65536))
      ->capture_default_str();
  renderCmd->add_option("--seed", renderOpt.seed, "Random seed")->capture_default_str();
  renderCmd->add_option("--out", renderOpt.out, "Output .exr (PNGs are written beside it)")->required();
  renderCmd->add_option("--threads", renderOpt.threads, "Worker threads (default: all cores)")
      ->check(CLI::Range(0, 256));
  addRenderSourceFlags(renderCmd, renWorld, renderOpt);
}

// The bake flags, shared by bake and bake-status (the input hash depends on every setting).
void addBakeFlags(CLI::App* c, lfgi::app::WorldBakeOptions& o) {
  c->add_option("--world", o.world, "World directory (lfgi world generate)")->required();
  c->add_option("--cells", o.cells, "Cells: X,Z or linear index ranges A-B (default: all)");
  c->add_option("--path", o.path,
                "Instead of --cells: the cells within --path-radius of the fly-through path loop or line "
                "(lfgi fly --path), in flight order")
      ->check(CLI::IsMember({"loop", "line"}));
  c->add_option("--path-radius", o.pathRadius, "With --path: metres around the path")
      ->check(CLI::Range(0.0, 100000.0))
      ->capture_default_str();
  c->add_option("--array-index", o.arrayIndex, "Slurm job-array task index (with --array-size)")
      ->check(CLI::NonNegativeNumber);
  c->add_option("--array-size", o.arraySize, "Split the selected cells into this many contiguous shares")
      ->check(CLI::Range(1, 1000000));
  c->add_option("--out", o.outDir, "Output directory (default WORLD/baked)");
  c->add_option("--error-target", o.settings.errorTarget, "Irradiance relative RMS target per cell")
      ->check(CLI::Range(0.001, 1.0))
      ->capture_default_str();
  c->add_option("--keys", o.settings.keys, "Lighting keys HOURS[:OVERCAST],...")->capture_default_str();
  c->add_option("--resolution", o.settings.resolution, "Probe map resolution (8, 16 or 32)")
      ->check(CLI::IsMember({8, 16, 32}))
      ->capture_default_str();
  c->add_option("--spp", o.settings.spp, "Capture samples per texel")
      ->check(CLI::Range(1, 65536))
      ->capture_default_str();
  c->add_option("--bounces", o.settings.bounces, "Capture bounces")
      ->check(CLI::Range(0, 256))
      ->capture_default_str();
  c->add_option("--max-steps", o.settings.maxSteps, "Training steps per candidate model")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  c->add_option("--threads", o.settings.threads, "Training threads")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  c->add_option("--seed", o.settings.seed, "Seed (capture and training)")->capture_default_str();
  c->add_option("--model-widths", o.settings.modelWidths,
                "Generator search: only these base widths (8,16,32,64; default all)")
      ->delimiter(',')
      ->check(CLI::IsMember({8, 16, 32, 64}));
  c->add_option("--model-latents", o.settings.modelLatents,
                "Generator search: only these latent sizes (4,8,16; default all)")
      ->delimiter(',')
      ->check(CLI::IsMember({4, 8, 16}));
  c->add_option("--codec", o.settings.codec,
                "per-cell (each cell its own smallest generator) or shared (one generator per world, "
                "OUT/shared_model.vdb; cells store latents + a FiLM adapter; "
                "--model-widths/--model-latents' first entries size it) or sh-l1 (no network: each probe's "
                "SH L1 per key, int8 APV split, 15 B per probe per key)")
      ->check(CLI::IsMember({"per-cell", "shared", "sh-l1"}))
      ->capture_default_str();
  c->add_option("--shared-steps", o.settings.sharedSteps,
                "--codec shared: pre-training steps of the shared generator")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
}

void addBakeCommands(CLI::App& app, CliOptions& opt, Subcommands& cmd) {
  lfgi::app::WorldBakeOptions& bakeOpt = opt.bake;
  CLI::App* bakeCmd =
      app.add_subcommand("bake",
                         "Bake world cells into cell files: capture, smallest model meeting the error "
                         "target, int8, OpenVDB (resumable, skips unchanged cells)");
  cmd.bake = bakeCmd;
  addBakeFlags(bakeCmd, bakeOpt);
  bakeCmd->add_flag("--reproducible", bakeOpt.reproducible,
                    "No timings in the cell files (the default; training seconds 0, real ones in "
                    "cells/cell_X_Z.json): byte-identical files for the same inputs");
  bakeCmd->add_flag(
      "--record-training-time{false}", bakeOpt.reproducible,
      "Store the wall-clock training seconds in each cell file (files then differ between runs)");
  bakeCmd
      ->add_option("--region-cells", bakeOpt.regionCells,
                   "After the bake, pack the cells into OUT/regions with NxN cells per region file (0: "
                   "no packing; array shares never pack: run lfgi pack after the array)")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
  CLI::App* packCmd = app.add_subcommand(
      "pack",
      "Pack a baked world's cell files into region files (OUT/regions: regions.json + content-"
      "addressed .lfgr files, what streaming reads); rewrites only regions that changed");
  cmd.pack = packCmd;
  packCmd->add_option("--world", opt.pack.world, "World directory (lfgi world generate)")->required();
  packCmd->add_option("--out", opt.pack.outDir, "Bake directory (default WORLD/baked)");
  packCmd->add_option("--region-cells", opt.pack.regionCells, "Cells per region side")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  lfgi::app::BakeStatusOptions& statusOpt = opt.bakeStatus;
  CLI::App* statusCmd =
      app.add_subcommand("bake-status",
                         "World bake status: cells done / stale / missing / failed / corrupt, ETA; --plan: "
                         "projected bake hours for larger worlds on N nodes");
  cmd.bakeStatus = statusCmd;
  addBakeFlags(statusCmd, statusOpt.bake);
  statusCmd->add_flag(
      "--plan", statusOpt.plan,
      "Cost model: measured seconds per cell by kind x the kind mix of larger worlds / nodes");
  statusCmd->add_option("--nodes", statusOpt.nodes, "Nodes for the ETA and the plan")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  statusCmd->add_option("--size-km2", statusOpt.sizesKm2, "World sizes for --plan, km^2")
      ->check(CLI::Range(1e-4, 1e5))
      ->capture_default_str();
  statusCmd
      ->add_option("--plan-out", statusOpt.planOut, "Directory for plan.csv + plan.json (empty: print only)")
      ->capture_default_str();
  statusCmd->add_flag("--list-stale", statusOpt.listStale, "List the stale cells");
  statusCmd->add_flag("-q,--quiet", statusOpt.quiet, "No progress line");
}

// The flags of fly and profile.
void addFlyOptions(CLI::App* c, lfgi::app::FlyOptions& o) {
  c->add_option("--world", o.world,
                "World directory or http(s):// URL of one served by a static server (cell layout, baked "
                "cells); default: 4096 m with 64 m cells");
  c->add_option("--path", o.path, "Camera path: loop or line")->capture_default_str();
  c->add_option("--speed", o.speed, "Camera speed, m/s")
      ->check(CLI::Range(0.0, 10000.0))
      ->capture_default_str();
  c->add_option("--seconds", o.seconds, "Simulated flight time")
      ->check(CLI::Range(0.01, 3600.0))
      ->capture_default_str();
  c->add_option("--fps", o.fps, "Frames per simulated second")
      ->check(CLI::Range(1.0, 1000.0))
      ->capture_default_str();
  c->add_option("--budget-mb", o.budgetMb, "Resident light-field memory budget, MB")
      ->check(CLI::Range(0.01, 1e6))
      ->capture_default_str();
  c->add_option("--decode-radius", o.decodeRadius, "Cells nearer than this are loaded, m")
      ->check(CLI::Range(1.0, 1e5))
      ->capture_default_str();
  c->add_option("--io-threads", o.ioThreads, "IO threads (0: inline, --loads-per-frame per frame)")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
  c->add_flag("--realtime", o.realtime, "Pace frames to 1/fps of wall time (IO threads race the real clock)");
  c->add_option("--loads-per-frame", o.loadsPerFrame, "IO bandwidth with --io-threads 0, cells per frame")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  c->add_option("--load-delay-us", o.loadDelayUs, "Simulated read + decode time per cell")
      ->check(CLI::Range(0, 10000000))
      ->capture_default_str();
  c->add_option("--resolution", o.resolution, "Probe octahedral resolution of the synthetic cells")
      ->check(CLI::Range(2, 64))
      ->capture_default_str();
  c->add_option("--tod-start", o.todStart, "Time of day at the start of the flight, hours")
      ->check(CLI::Range(0.0, 24.0))
      ->capture_default_str();
  c->add_option("--tod-end", o.todEnd,
                "Time of day at the end of the flight, hours (= --tod-start: no relight)")
      ->check(CLI::Range(0.0, 24.0))
      ->capture_default_str();
  c->add_option("--render", o.render,
                "Draw the flight on the Vulkan device at WIDTHxHEIGHT (e.g. 320x180): PNG frames, strip.png, "
                "flight.mp4, GPU times; needs a baked --world");
  c->add_option("--render-every", o.renderEvery, "With --render: draw every N-th frame")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  c->add_option(
       "--render-reference", o.renderReference,
       "With --render: path-trace this many of the rendered frames (spread over the flight) and report "
       "the image error against them")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  c->add_option("--render-reference-spp", o.renderReferenceSpp, "Samples per pixel of those references")
      ->check(CLI::Range(1, 65536))
      ->capture_default_str();
  c->add_option("--relight", o.relight,
                "Relight of resident cells: codec (re-decode) or vir (GPU VIR relight of the world's "
                "surfels; needs --world)")
      ->check(CLI::IsMember({"codec", "vir"}))
      ->capture_default_str();
  c->add_option("--weather-start", o.weatherStart, "Overcast at the start of the flight, [0, 1]")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  c->add_option("--weather-end", o.weatherEnd, "Overcast at the end of the flight, [0, 1]")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  c->add_option("--out", o.outDir, "Output directory (default out/fly or out/profile)");
  c->add_option("--decoder", o.decoder,
                "Generator decode of baked cells: cpu, gpu or auto (the faster, timed once)")
      ->check(CLI::IsMember({"cpu", "gpu", "auto"}))
      ->capture_default_str();
}

void addFlyCommands(CLI::App& app, CliOptions& opt, Subcommands& cmd) {
  opt.profile.profile = true;
  cmd.fly = app.add_subcommand(
      "fly", "Fly a camera over the world through the streaming manager: frames.csv + summary.json");
  addFlyOptions(cmd.fly, opt.fly);
  cmd.profile = app.add_subcommand(
      "profile", "Streaming budget profiler: fly-through + Chrome trace (Perfetto), charts, summary.html");
  addFlyOptions(cmd.profile, opt.profile);
}

void addInspectCommands(CLI::App& app, CliOptions& opt, Subcommands& cmd) {
  lfgi::app::InspectOptions& inspectOpt = opt.inspect;
  CLI::App* inspect = app.add_subcommand(
      "inspect", "Show a cell file: model, bytes by part, error reached, probes, training time");
  cmd.inspect = inspect;
  inspect->add_option("cellfile", inspectOpt.file, "Cell file (.vdb)")->required();
  inspect->add_flag("--json", inspectOpt.json, "Print JSON");
  lfgi::app::DebugWriteCellOptions& debugCellOpt = opt.debugCell;
  CLI::App* debugCell =
      app.add_subcommand("debug-write-cell", "Write a small synthetic cell file (tests)")->group("");
  cmd.debugCell = debugCell;
  debugCell->add_option("--out", debugCellOpt.out, "Output cell file")->required();
  debugCell->add_flag("--no-network", debugCellOpt.noNetwork, "Fallback only");
  debugCell->add_flag("--fp16", debugCellOpt.fp16, "FP16 weights instead of int8");
  debugCell->add_option("--latent-bits", debugCellOpt.latentBits, "8 or 4")->check(CLI::IsMember({4, 8}));
}

// Registers every subcommand, in the order of the help.
void addSubcommands(CLI::App& app, CliOptions& opt, Subcommands& cmd) {
  addDeviceCommand(app, opt, cmd);
  addDemoCommand(app, opt, cmd);
  addWorldCommands(app, opt, cmd);
  addCaptureCommand(app, opt, cmd);
  addReferenceCommand(app, opt, cmd);
  addVirCommand(app, opt, cmd);
  addRenderCommand(app, opt, cmd);
  addBakeCommands(app, opt, cmd);
  addFlyCommands(app, opt, cmd);
  addInspectCommands(app, opt, cmd);
}

// Parses the command line; returns the exit code when parsing ends the run (help, version: 0; bad
// usage: 2), nothing when a subcommand (or none) is to run.
std::optional<int> parseCommandLine(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "lfgi: %s\nRun 'lfgi --help' for usage.\n", e.what());
    return 2;
  }
  return std::nullopt;
}

// Runs the subcommand the command line named (the help when none); lfgi::Error and other exceptions
// become exit code 1.
int runSubcommand(const CLI::App& app, const CliOptions& opt, const Subcommands& cmd) {
  try {
    if (*cmd.device) return lfgi::app::runDevice(opt.device);
    if (*cmd.demo) return lfgi::app::runDemo(opt.demo);
    if (*cmd.generate) return lfgi::app::runWorldGenerate(opt.generate);
    if (*cmd.info) return lfgi::app::runWorldInfo(opt.info);
    if (*cmd.exportCell) return lfgi::app::runWorldExportCell(opt.exportCell);
    if (*cmd.edit) return lfgi::app::runWorldEdit(opt.edit);
    if (*cmd.capture) return lfgi::app::runCapture(opt.capture);
    if (*cmd.reference) return lfgi::app::runReference(opt.reference);
    if (*cmd.vir) return lfgi::app::runVir(opt.vir);
    if (*cmd.render) return lfgi::app::runRender(opt.render);
    if (*cmd.fly) return lfgi::app::runFly(opt.fly);
    if (*cmd.bake) return lfgi::app::runWorldBake(opt.bake);
    if (*cmd.pack) return lfgi::app::runPack(opt.pack);
    if (*cmd.bakeStatus) return lfgi::app::runBakeStatus(opt.bakeStatus);
    if (*cmd.profile) return lfgi::app::runFly(opt.profile);
    if (*cmd.inspect) return lfgi::app::runInspect(opt.inspect);
    if (*cmd.debugCell) return lfgi::app::runDebugWriteCell(opt.debugCell);
    std::fputs(app.help().c_str(), stdout);
    return 0;
  } catch (const lfgi::Error& e) {
    std::fprintf(stderr, "lfgi: error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lfgi: internal error: %s\n", e.what());
    return 1;
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"lfgi: streaming open-world global illumination from generative light fields"};
  app.set_version_flag("--version", std::string("lfgi ") + LFGI_VERSION);
  app.require_subcommand(0, 1);
  CliOptions opt;
  app.add_flag("-v,--verbose", opt.verbose, "Log debug messages");
  Subcommands cmd;
  addSubcommands(app, opt, cmd);

  lfgi::app::requireSaneNumbers(app);  // NaN, Inf, negative unsigned and overflowing values: exit 2
  if (std::optional<int> exitCode = parseCommandLine(app, argc, argv)) return *exitCode;
  spdlog::set_level(opt.verbose ? spdlog::level::debug : spdlog::level::info);
  return runSubcommand(app, opt, cmd);
}
