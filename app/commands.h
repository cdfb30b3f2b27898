// Subcommand entry points of the lfgi CLI. Each returns the process exit code; errors are thrown as
// lfgi::Error and turned into exit code 1 by main().
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "bake/world_bake.h"
#include "worlds/gltf_io.h"

namespace lfgi::app {

struct DeviceOptions {
  bool json = false;
};
int runDevice(const DeviceOptions& options);

struct DemoOptions {
  std::string outDir = "out/demo";
  int resolution = 64;      // octahedral radiance map of the sky probe
  float timeOfDay = 15.5f;  // local solar time, hours
  float overcast = 0.0f;    // 0 clear .. 1 overcast
  uint64_t seed = 1;
  double worldSizeM = 256.0;  // the small embedded default world
};
int runDemo(const DemoOptions& options);

struct WorldGenerateOptions {
  double sizeM = 4096;
  double cellM = 64;
  uint64_t seed = 1;
  std::string outDir;
  bool all = false;
  std::vector<std::string> cells;  // "X,Z"
  int threads = 0;                 // 0: all cores
};
// Writes the manifest and the requested cells; resumable; returns 130 when interrupted.
int runWorldGenerate(const WorldGenerateOptions& options);

struct WorldInfoOptions {
  std::string dir;
  bool json = false;
};
int runWorldInfo(const WorldInfoOptions& options);

struct WorldExportOptions {
  std::string dir;
  std::string cell;  // "X,Z"
  std::string out;
};
int runWorldExportCell(const WorldExportOptions& options);

// `lfgi world edit DIR --add-building ... --add-box ... --clear-region ...` (worlds/world_edits.h).
struct WorldEditOptions {
  std::string dir;
  std::vector<std::pair<std::string, std::string>> edits;  // (flag without "--", value) in command-line order
};
// Appends the edits to DIR/world.json atomically; prints the cells whose content changed and the cells
// whose bake inputs changed.
int runWorldEdit(const WorldEditOptions& options);

// `lfgi capture` (app/bake_command.cpp): probe capture of world cells or a test scene; resumable, 130
// when interrupted.
struct CaptureCommandOptions {
  std::string world;               // world directory, or
  std::vector<std::string> cells;  // "X,Z" (with --world)
  std::string scene;               // preset name or .gltf/.glb file
  std::string scenesDir = worlds::defaultScenesDir().string();
  float scale = 1.0f;  // for a scene file
  std::string probes;  // "NX,NY,NZ" probe grid override for scenes
  float timeOfDay = 17.5f;
  float overcast = 0.0f;
  int resolution = 16;
  int spp = 64;
  int bounces = 12;
  uint64_t seed = 1;
  std::string outDir;
  int threads = 0;  // 0: all cores
};
int runCapture(const CaptureCommandOptions& options);

// `lfgi reference`: a layered path-traced EXR (bake/reference_render.h) + a tone-mapped PNG beside it.
struct ReferenceCommandOptions {
  std::string world;
  std::string scene;
  std::string scenesDir = worlds::defaultScenesDir().string();
  float scale = 1.0f;
  std::string camera;  // px,py,pz,tx,ty,tz
  float fov = 60.0f;
  std::string size = "640x360";
  int spp = 64;
  int bounces = 12;
  float timeOfDay = 17.5f;
  float overcast = 0.0f;
  uint64_t seed = 1;
  std::string out;
  int threads = 0;
};
int runReference(const ReferenceCommandOptions& options);

// `lfgi vir` (app/vir_command.cpp): relight + View-Independent Rasterization of one world cell -> probe
// atlases (EXR), a contact sheet (PNG) and vir.json. Returns 130 when interrupted.
struct VirCommandOptions {
  std::string world;
  std::string cell;  // "X,Z"
  float timeOfDay = 17.5f;
  float overcast = 0.0f;
  std::string outDir;
  int resolution = 16;
  int bounces = 3;  // relight frames = bounces + 1
};
int runVir(const VirCommandOptions& options);

// `lfgi render` (app/render_command.cpp): one view shaded from light-field probes -> layered EXR + PNG;
// --compare adds the path-traced reference, an error heat map and the relative RMS.
struct RenderCommandOptions {
  std::string world;
  std::string cell;  // "X,Z" (with --world)
  std::string scene;
  std::string scenesDir = worlds::defaultScenesDir().string();
  float scale = 1.0f;
  std::string grid;  // "NX,NY,NZ" probe grid override for scenes
  std::string camera;
  float fov = 60.0f;
  std::string size = "320x180";
  float timeOfDay = 12.0f;
  float overcast = 0.0f;
  std::string probes = "capture";
  int resolution = 16;
  int spp = 64;
  int bounces = 12;
  int specularLevels = 4;
  float probeRadius = 0.0f;  // 0: the probes around what the camera sees
  bool noChebyshev = false;
  bool compare = false;
  int referenceSpp = 64;
  uint64_t seed = 1;
  std::string out;
  int threads = 0;
  std::string cellFile;  // --probes codec: the centre cell's file (default WORLD/baked/cells/cell_X_Z.vdb)
  int virFrames = 4;     // --probes vir: relight frames (1 = direct light only, each more one bounce)
  float surfelSpacing = 0.0f;  // --probes vir on a scene: surfel spacing (m); 0: bounding-box diagonal / 64
  float exposure = std::numeric_limits<float>::quiet_NaN();  // EV of the PNG; NaN: auto (median -> 0.18)
  float aoRadius = 0.0f;  // m; > 0: ray-traced AO from the G-buffer on indirect diffuse + "ao" layer
  bool neighboursFallback = false;  // world: the 8 neighbours on their SH L1 fallback (not resident)
  float cellFade = 1.0f;            // world: the centre cell's cross-fade weight against its fallback, [0, 1]
};
int runRender(const RenderCommandOptions& options);

// `lfgi fly` / `lfgi profile` (app/fly_command.cpp): the streaming manager along a camera path over the
// world; frames.csv + summary.json; profile adds trace.json (Perfetto), profile.png, summary.html.
struct FlyOptions {
  std::string world;  // world directory for the cell layout (default: 4096 m, 64 m cells)
  std::string path = "loop";
  float speed = 50.0f;
  float seconds = 60.0f;
  float fps = 60.0f;
  float todStart = 6.0f, todEnd = 20.0f;
  double budgetMb = 256.0;
  float decodeRadius = 160.0f;
  int ioThreads = 0;      // 0: inline loads, loadsPerFrame per frame (deterministic)
  bool realtime = false;  // pace frames to 1/fps of wall time (FlythroughOptions::realtime)
  int loadsPerFrame = 2;
  int loadDelayUs = 0;
  int resolution = 8;
  std::string decoder =
      "auto";  // baked cells' generator decode: cpu | gpu | auto (streaming/generator_backend.h)
  std::string relight = "codec";  // codec: CellSource::relightInto as is; vir: VIR relight of the surfels
  float weatherStart = 0.0f, weatherEnd = 0.0f;  // overcast sweep
  std::string outDir;
  bool profile = false;
  std::string render;           // "WxH": draw frames on the device (app/fly_render.h); empty: none
  int renderEvery = 1;          // render every N-th frame
  int renderReference = 0;      // rendered frames also path-traced and compared (0: none)
  int renderReferenceSpp = 16;  // their samples per pixel
};
int runFly(const FlyOptions& options);

// `lfgi inspect CELLFILE` (app/inspect_command.cpp): model, bytes by part, error reached, probe count and
// training time of a cell file (core/cell_file.h); a bad file is an lfgi::Error (exit 1).
struct InspectOptions {
  std::string file;
  bool json = false;
};
int runInspect(const InspectOptions& options);
// Hidden `lfgi debug-write-cell`: writes a small synthetic cell file (CLI tests; trying inspect without a
// bake).
struct DebugWriteCellOptions {
  std::string out;
  bool noNetwork = false;
  bool fp16 = false;
  int latentBits = 8;
};
int runDebugWriteCell(const DebugWriteCellOptions& options);

// `lfgi bake` (app/world_bake_command.cpp): world cells -> cell files (capture, model sizing, int8,
// OpenVDB cell file); idempotent by input hash, resumable, Slurm job-array aware.
struct WorldBakeOptions {
  std::string world;
  std::vector<std::string> cells;  // "X,Z" or linear index ranges "A-B"; empty: every cell
  // --path loop|line: instead of --cells, the cells within pathRadius of that fly-through path
  // (streaming::flightPathCells, in flight order) — a km-scale world baked only where `lfgi fly` goes.
  std::string path;
  float pathRadius = 128.0f;          // m; >= the fly's shade distance (120 m) keeps visible samples baked
  int arrayIndex = 0, arraySize = 0;  // arraySize > 0: bake share arrayIndex of arraySize
  std::string outDir;                 // default WORLD/baked
  bake::WorldBakeSettings settings;   // capture + training settings (they enter the input hash)
  // Store no timing in the cell file (training seconds 0; the real ones stay in cells/cell_X_Z.json), so
  // the same inputs give byte-identical files in any process (Slurm vs single-process, interrupted vs
  // uninterrupted bakes). Default on; --record-training-time stores the wall-clock training seconds.
  bool reproducible = true;
  // After a bake that is not one share of an array: pack OUT/cells into OUT/regions (core/cell_store.h),
  // regionCells x regionCells cells per region file; 0: no packing. Array shares run `lfgi pack` once all
  // shares are done (packing from concurrent shares would race on regions.json).
  int regionCells = 8;
};
int runWorldBake(const WorldBakeOptions& options);

// `lfgi pack`: WORLD/baked/cells -> WORLD/baked/regions (core/cell_store.h packRegions); prints what was
// written and the container bytes per cell.
struct PackOptions {
  std::string world;
  std::string outDir;  // default WORLD/baked
  int regionCells = 8;
};
int runPack(const PackOptions& options);

// `lfgi bake-status` (app/bake_status_command.cpp): cells done / stale / missing / failed / corrupt of a
// world bake against its current inputs (same flags as bake), ETA from the measured cell seconds by kind;
// --plan: the cost model (bake/bake_records.h) projected to larger worlds on 1 and --nodes nodes.
struct BakeStatusOptions {
  WorldBakeOptions bake;  // --world, --out, --cells and the bake settings (the input hash depends on them)
  bool plan = false;
  int nodes = 1;
  std::vector<double> sizesKm2 = {16, 100, 400};
  std::string planOut = "out/bench/bake";  // plan.csv + plan.json; empty: print only
  bool listStale = false;
  bool quiet = false;  // no progress line
};
int runBakeStatus(const BakeStatusOptions& options);

}  // namespace lfgi::app
