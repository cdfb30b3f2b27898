// Fly-through driver shared by `lfgi fly` / `lfgi profile` and bench/flythrough: a camera on a closed
// Catmull-Rom spline over the world at a constant speed, a time-of-day sweep, the StreamingManager
// updated every frame, and a fixed set of "visible samples" (view rays hitting the ground plane y = 0
// within shadeDistance) sampled through the manager to measure how much of what the camera sees is
// lit by full cells, by the fallback, or by nothing.
//
// Time model: frames advance simulated time by 1 / fps. With StreamingConfig::ioThreads = 0 the IO
// bandwidth is maxInlineLoadsPerFrame cells per frame and the whole run is deterministic; with IO
// threads, loads take real time while frames do not wait for them (a conservative model: a real
// frame takes >= 1/fps of wall time, so loads arrive at least as early in frames as in a real game).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "core/trace.h"
#include "streaming/streaming_manager.h"

namespace lfgi::streaming {

struct FlythroughFrame;

struct FlythroughOptions {
  std::string path = "loop";  // "loop" (closed spline over the world) or "line" (west -> east)
  float speed = 50.0f;        // m/s
  float seconds = 60.0f;      // simulated
  float fps = 60.0f;
  float altitude = 12.0f;                 // m above y = 0
  float pitchDeg = -12.0f;                // view pitch
  float todStart = 6.0f, todEnd = 20.0f;  // time-of-day sweep over the flight (hours)
  float weatherStart = 0.0f,
        weatherEnd = 0.0f;       // overcast sweep over the flight, [0, 1] (FrameInput::weather)
  float shadeDistance = 120.0f;  // m: visible samples farther away use the far-field fallback by design
  int sampleRaysX = 24, sampleRaysY = 12;  // view rays of the visible-sample grid (90 x 50 deg)
  // Pace frames to 1/fps of wall time (sleep the rest of each frame), so IO-thread loads and relights race
  // the real clock as in a game; off: frames run back to back (with IO threads, loads arrive late in
  // simulated time when frames are cheap: a pessimistic model).
  bool realtime = false;
  bool preload = true;  // load everything around the start before the first frame (uncounted)
  StreamingConfig streaming;
  // StreamingManager::onRelight for the flight: game-thread hook after a relit field is swapped in (the
  // re-decode itself is the source's relightInto, run by the manager); empty: none.
  std::function<void(glm::ivec2 cell, ProbeField& field, float timeOfDayHours)> onRelight;
  // Game-thread hook after each frame's update and visible samples, with the manager in that frame's state
  // (`lfgi fly --render` draws the frame here); empty: none. Its time is not in FlythroughFrame::frameMs.
  std::function<void(const FlythroughFrame&, const StreamingManager&)> onFrame;
  // Throws lfgi::Error naming the bad option.
  void validate() const;
};

struct FlythroughFrame {
  FrameStats stats;
  int index = 0;  // flight frame, 0-based (stats.frame also counts preload updates)
  double timeS = 0.0;
  glm::vec3 position{0.0f};
  glm::vec3 direction{0.0f, 0.0f, -1.0f};  // view direction (unit)
  float timeOfDay = 0.0f;
  float weather = 0.0f;
  int visibleSamples = 0;
  int fallbackSamples = 0;  // samples with fallback weight > 1 %
  int missingSamples = 0;   // samples with no GI at all (must be 0)
  double shadeMs = 0.0;     // CPU time sampling the visible points
  double frameMs = 0.0;     // update + shade
  double fallbackFraction() const { return visibleSamples ? double(fallbackSamples) / visibleSamples : 0.0; }
};

struct FlythroughSummary {
  int frames = 0;            // frames flown (fewer than planned when interrupted)
  bool interrupted = false;  // stopped by InterruptGuard (Ctrl-C)
  int framesMissingGi = 0;
  double fallbackFraction = 0.0;  // over all visible samples of the run
  double p50FrameMs = 0.0, p95FrameMs = 0.0, p99FrameMs = 0.0;
  double p50UpdateMs = 0.0, p95UpdateMs = 0.0, p99UpdateMs = 0.0;
  double p99IoMs = 0.0, p99ActivateMs = 0.0, p99RelightMs = 0.0, p99ShadeMs = 0.0;
  double p50IoMs = 0.0, p50ActivateMs = 0.0, p50RelightMs = 0.0, p50ShadeMs = 0.0;
  double p95IoMs = 0.0, p95ActivateMs = 0.0, p95RelightMs = 0.0, p95ShadeMs = 0.0;
  // relightInto time (IO thread, or inline with ioThreads = 0) over the frames where a relight completed.
  double p50RelightIoMs = 0.0, p95RelightIoMs = 0.0;
  size_t peakBytesResident = 0;
  long cellsRequested = 0, cellsEvicted = 0, cellsRelit = 0, cellsFailed = 0;
};

// Runs the flight; perFrame (optional) sees every frame; trace (optional) receives one span per stage
// per frame and counters of memory and budget use.
FlythroughSummary runFlythrough(CellSource& source, const FlythroughOptions& options,
                                const std::function<void(const FlythroughFrame&)>& perFrame = {},
                                TraceWriter* trace = nullptr);

// Camera position on the path at arc length s (metres, wraps for "loop").
glm::vec3 flythroughPosition(const WorldLayout& layout, const FlythroughOptions& options, double s);

// Length of the flight path of options.path over layout (metres; the loop's full circumference).
double flightPathLength(const WorldLayout& layout, const FlythroughOptions& options);

// The cells a flight along options.path needs: every cell of the world whose square lies within `radius`
// (xz) of the path, each once, in the order the flight first comes within `radius` of it (the start
// first, so a bake of this list interrupted half way covers the first half of the flight). Only the path
// matters (not speed, time or fps). `lfgi bake --path` bakes these; `radius` >= shadeDistance keeps every
// visible sample on baked cells. Throws lfgi::Error for a bad path name or radius < 0.
std::vector<glm::ivec2> flightPathCells(const WorldLayout& layout, const FlythroughOptions& options,
                                        float radius);

}  // namespace lfgi::streaming
