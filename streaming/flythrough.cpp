#include "streaming/flythrough.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <thread>

#include "core/error.h"
#include "core/progress.h"

namespace lfgi::streaming {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

glm::vec2 catmullRom(glm::vec2 p0, glm::vec2 p1, glm::vec2 p2, glm::vec2 p3, float t) {
  float t2 = t * t, t3 = t2 * t;
  return 0.5f * ((2.0f * p1) + (-p0 + p2) * t + (2.0f * p0 - 5.0f * p1 + 4.0f * p2 - p3) * t2 +
                 (-p0 + 3.0f * p1 - 3.0f * p2 + p3) * t3);
}

// The path as a polyline of kSamples points with cumulative arc length (built once per call; cheap).
struct PathTable {
  std::vector<glm::vec2> points;
  std::vector<double> length;  // cumulative
  bool closed = true;
};

PathTable buildPath(const WorldLayout& layout, const FlythroughOptions& o) {
  const glm::vec2 size = glm::vec2(layout.cells) * layout.cellSize, centre = layout.originXZ + 0.5f * size;
  std::vector<glm::vec2> ctrl;
  PathTable table;
  if (o.path == "line") {
    table.closed = false;
    for (int i = 0; i < 4; ++i)
      ctrl.push_back(layout.originXZ + glm::vec2((0.1f + 0.8f * float(i) / 3.0f) * size.x, 0.5f * size.y));
  } else {
    // A closed loop with radial wiggles (fixed, so every run flies the same path).
    const float wiggle[8] = {0.0f, 0.12f, -0.08f, 0.1f, -0.12f, 0.06f, 0.1f, -0.05f};
    for (int i = 0; i < 8; ++i) {
      double a = 2.0 * std::numbers::pi * i / 8.0;
      float r = 0.34f + wiggle[i];
      ctrl.push_back(centre + glm::vec2(float(std::cos(a)) * r * size.x, float(std::sin(a)) * r * size.y));
    }
  }
  const int segments = table.closed ? int(ctrl.size()) : int(ctrl.size()) - 1, perSegment = 512;
  auto at = [&](int i) {
    int n = int(ctrl.size());
    if (table.closed) return ctrl[size_t(((i % n) + n) % n)];
    return ctrl[size_t(std::clamp(i, 0, n - 1))];
  };
  for (int s = 0; s < segments; ++s)
    for (int k = 0; k < perSegment; ++k)
      table.points.push_back(catmullRom(at(s - 1), at(s), at(s + 1), at(s + 2), float(k) / perSegment));
  table.points.push_back(table.closed ? table.points.front() : ctrl.back());
  table.length.assign(table.points.size(), 0.0);
  for (size_t i = 1; i < table.points.size(); ++i)
    table.length[i] = table.length[i - 1] + double(glm::length(table.points[i] - table.points[i - 1]));
  return table;
}

glm::vec2 pointAt(const PathTable& t, double s) {
  const double total = t.length.back();
  s = t.closed ? std::fmod(std::fmod(s, total) + total, total) : std::clamp(s, 0.0, total);
  size_t i = size_t(std::upper_bound(t.length.begin(), t.length.end(), s) - t.length.begin());
  i = std::clamp<size_t>(i, 1, t.points.size() - 1);
  double seg = t.length[i] - t.length[i - 1], f = seg > 0.0 ? (s - t.length[i - 1]) / seg : 0.0;
  return glm::mix(t.points[i - 1], t.points[i], float(f));
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  size_t i = size_t(std::clamp(q * double(v.size() - 1) + 0.5, 0.0, double(v.size() - 1)));
  return v[i];
}

// Preloads around the start (a game's loading screen): not counted, so the numbers describe flying.
void preloadStart(StreamingManager& manager, const PathTable& path, const FlythroughOptions& o) {
  glm::vec2 p0 = pointAt(path, 0.0);
  FrameInput in;
  in.position = {p0.x, o.altitude, p0.y};
  in.timeOfDayHours = o.todStart;
  in.weather = o.weatherStart;
  in.dtSeconds = 1e3f;  // completes every cross-fade
  for (int i = 0; i < 10000; ++i) {
    FrameStats st = manager.update(in);
    if (st.loading == 0 && st.requested == 0 && st.activated == 0) break;
    if (st.loading > 0) manager.drainIo();
  }
  manager.update(in);
}

void shadeSamples(const StreamingManager& manager, const WorldLayout& layout, const FlythroughOptions& o,
                  float pitch, glm::vec2 fwd2, FlythroughFrame& fr) {
  // Visible samples: view rays to the ground plane within the shading distance.
  auto ts = Clock::now();
  const float yaw0 = std::atan2(fwd2.y, fwd2.x);
  for (int j = 0; j < o.sampleRaysY; ++j)
    for (int i = 0; i < o.sampleRaysX; ++i) {
      float yaw = yaw0 + glm::radians(-45.0f + 90.0f * (float(i) + 0.5f) / float(o.sampleRaysX));
      float pt = pitch + glm::radians(-25.0f + 50.0f * (float(j) + 0.5f) / float(o.sampleRaysY));
      glm::vec3 d(std::cos(yaw) * std::cos(pt), std::sin(pt), std::sin(yaw) * std::cos(pt));
      if (d.y >= -1e-3f) continue;
      float dist = o.altitude / -d.y;
      if (dist > o.shadeDistance) continue;
      glm::vec3 q = fr.position + dist * d;
      q.y = 0.0f;
      if (!layout.contains(layout.cellOf(q))) continue;  // off the world's edge: nothing to light
      IrradianceSample smp = manager.sample(q, {0.0f, 1.0f, 0.0f});
      ++fr.visibleSamples;
      if (smp.missing || !std::isfinite(smp.irradiance.x + smp.irradiance.y + smp.irradiance.z))
        ++fr.missingSamples;
      else if (smp.fallbackWeight > 0.01f)
        ++fr.fallbackSamples;
    }
  fr.shadeMs = msSince(ts);
}

void traceFrame(TraceWriter& trace, const FlythroughFrame& fr, int f, double frameStartUs) {
  double u = fr.stats.updateMs * 1e3;
  trace.complete("update", "streaming", frameStartUs, u,
                 {{"frame", f},
                  {"requested", fr.stats.requested},
                  {"activated", fr.stats.activated},
                  {"evicted", fr.stats.evicted},
                  {"relit", fr.stats.relit}});
  trace.complete("shade samples", "shade", frameStartUs + u, fr.shadeMs * 1e3,
                 {{"visible", fr.visibleSamples}});
  trace.counter("resident MB", frameStartUs, {{"resident", double(fr.stats.bytesResident) / 1e6}});
  trace.counter("cells", frameStartUs, {{"resident", fr.stats.resident}, {"loading", fr.stats.loading}});
  trace.counter("fallback %", frameStartUs, {{"fallback", 100.0 * fr.fallbackFraction()}});
  trace.counter("stage ms", frameStartUs,
                {{"io", fr.stats.ioMs},
                 {"activate", fr.stats.activateMs},
                 {"relight", fr.stats.relightMs},
                 {"shade", fr.shadeMs}});
}

// Per-frame timings and sample counts of a flight, for the summary's percentiles and fractions.
struct FlightTimings {
  std::vector<double> frameMs, updateMs, ioMs, activateMs, relightMs, shadeMs, relightIoMs;
  long visible = 0, fallback = 0;
};

void accumulateFrame(const FlythroughFrame& fr, FlightTimings& ft, FlythroughSummary& sum) {
  ft.visible += fr.visibleSamples;
  ft.fallback += fr.fallbackSamples;
  sum.framesMissingGi += fr.missingSamples > 0;
  sum.peakBytesResident = std::max(sum.peakBytesResident, fr.stats.bytesResident);
  sum.cellsRequested += fr.stats.requested;
  sum.cellsEvicted += fr.stats.evicted;
  sum.cellsRelit += fr.stats.relit;
  sum.cellsFailed += fr.stats.failed;
  ft.frameMs.push_back(fr.frameMs);
  ft.updateMs.push_back(fr.stats.updateMs);
  ft.ioMs.push_back(fr.stats.ioMs);
  ft.activateMs.push_back(fr.stats.activateMs);
  ft.relightMs.push_back(fr.stats.relightMs);
  if (fr.stats.relightIoMs > 0.0) ft.relightIoMs.push_back(fr.stats.relightIoMs);
  ft.shadeMs.push_back(fr.shadeMs);
}

void summariseFlight(const FlightTimings& ft, FlythroughSummary& sum) {
  sum.fallbackFraction = ft.visible ? double(ft.fallback) / double(ft.visible) : 0.0;
  sum.p50FrameMs = percentile(ft.frameMs, 0.5);
  sum.p95FrameMs = percentile(ft.frameMs, 0.95);
  sum.p99FrameMs = percentile(ft.frameMs, 0.99);
  sum.p50UpdateMs = percentile(ft.updateMs, 0.5);
  sum.p95UpdateMs = percentile(ft.updateMs, 0.95);
  sum.p99UpdateMs = percentile(ft.updateMs, 0.99);
  sum.p99IoMs = percentile(ft.ioMs, 0.99);
  sum.p99ActivateMs = percentile(ft.activateMs, 0.99);
  sum.p99RelightMs = percentile(ft.relightMs, 0.99);
  sum.p99ShadeMs = percentile(ft.shadeMs, 0.99);
  sum.p50IoMs = percentile(ft.ioMs, 0.5);
  sum.p50ActivateMs = percentile(ft.activateMs, 0.5);
  sum.p50RelightMs = percentile(ft.relightMs, 0.5);
  sum.p50ShadeMs = percentile(ft.shadeMs, 0.5);
  sum.p95IoMs = percentile(ft.ioMs, 0.95);
  sum.p95ActivateMs = percentile(ft.activateMs, 0.95);
  sum.p95RelightMs = percentile(ft.relightMs, 0.95);
  sum.p95ShadeMs = percentile(ft.shadeMs, 0.95);
  if (!ft.relightIoMs.empty()) {
    sum.p50RelightIoMs = percentile(ft.relightIoMs, 0.5);
    sum.p95RelightIoMs = percentile(ft.relightIoMs, 0.95);
  }
}

}  // namespace

void FlythroughOptions::validate() const {
  if (path != "loop" && path != "line") fail("--path '{}': expected loop or line", path);
  if (!(speed >= 0.0f && speed <= 10000.0f)) fail("--speed {}: expected 0..10000 m/s", speed);
  if (!(seconds > 0.0f && seconds <= 3600.0f)) fail("--seconds {}: expected (0, 3600]", seconds);
  if (!(fps >= 1.0f && fps <= 1000.0f)) fail("--fps {}: expected 1..1000", fps);
  if (!(shadeDistance > 0.0f)) fail("shadeDistance {} must be > 0", shadeDistance);
  if (!(weatherStart >= 0.0f && weatherStart <= 1.0f && weatherEnd >= 0.0f && weatherEnd <= 1.0f))
    fail("weather {} -> {}: expected overcast in [0, 1]", weatherStart, weatherEnd);
  if (sampleRaysX < 1 || sampleRaysY < 1)
    fail("sample ray grid {}x{} must be >= 1x1", sampleRaysX, sampleRaysY);
  streaming.validate();
}

glm::vec3 flythroughPosition(const WorldLayout& layout, const FlythroughOptions& options, double s) {
  PathTable t = buildPath(layout, options);
  glm::vec2 p = pointAt(t, s);
  return {p.x, options.altitude, p.y};
}

double flightPathLength(const WorldLayout& layout, const FlythroughOptions& options) {
  if (options.path != "loop" && options.path != "line")
    fail("--path '{}': expected loop or line", options.path);
  return buildPath(layout, options).length.back();
}

std::vector<glm::ivec2> flightPathCells(const WorldLayout& layout, const FlythroughOptions& options,
                                        float radius) {
  if (options.path != "loop" && options.path != "line")
    fail("--path '{}': expected loop or line", options.path);
  if (!(radius >= 0.0f) || !std::isfinite(radius))
    fail("path radius {} m: expected a finite value >= 0", radius);
  const PathTable t = buildPath(layout, options);
  std::vector<uint8_t> seen(size_t(layout.cells.x) * size_t(layout.cells.y), 0);
  std::vector<glm::ivec2> out;
  // Path points are ~1-2 m apart on a km-scale world (8 x 512 per loop); every segment is also walked in
  // steps of at most a quarter cell so coarse paths over small worlds miss nothing.
  const float step = 0.25f * layout.cellSize;
  std::vector<std::pair<float, glm::ivec2>> fresh;
  auto visit = [&](glm::vec2 q) {
    const glm::vec3 p{q.x, 0.0f, q.y};
    fresh.clear();
    const glm::ivec2 lo = layout.cellOf(p - glm::vec3(radius, 0.0f, radius));
    const glm::ivec2 hi = layout.cellOf(p + glm::vec3(radius, 0.0f, radius));
    for (int z = std::max(lo.y, 0); z <= std::min(hi.y, layout.cells.y - 1); ++z)
      for (int x = std::max(lo.x, 0); x <= std::min(hi.x, layout.cells.x - 1); ++x) {
        uint8_t& s = seen[size_t(layout.linear({x, z}))];
        const float d = layout.distanceToCell(p, {x, z});
        if (!s && d <= radius) {
          s = 1;
          fresh.push_back({d, glm::ivec2(x, z)});
        }
      }
    // Nearest first among the cells this point reaches first (the start's own cell leads the list).
    std::stable_sort(fresh.begin(), fresh.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    for (const auto& f : fresh) out.push_back(f.second);
  };
  visit(t.points.front());
  for (size_t i = 1; i < t.points.size(); ++i) {
    const glm::vec2 a = t.points[i - 1], b = t.points[i];
    const int n = std::max(1, int(std::ceil(glm::length(b - a) / step)));
    for (int k = 1; k <= n; ++k) visit(glm::mix(a, b, float(k) / float(n)));
  }
  return out;
}

FlythroughSummary runFlythrough(CellSource& source, const FlythroughOptions& o,
                                const std::function<void(const FlythroughFrame&)>& perFrame,
                                TraceWriter* trace) {
  o.validate();
  const WorldLayout layout = source.layout();
  const PathTable path = buildPath(layout, o);
  StreamingManager manager(source, o.streaming);
  manager.onRelight = o.onRelight;
  const int frames = std::max(1, int(std::lround(double(o.seconds) * o.fps)));
  const double dt = 1.0 / o.fps;
  FlythroughSummary sum;
  FlightTimings ft;
  Progress progress("fly-through", size_t(frames), "frames");
  const float pitch = glm::radians(o.pitchDeg);
  if (o.preload) preloadStart(manager, path, o);
  const auto flightStart = Clock::now();
  for (int f = 0; f < frames; ++f) {
    if (InterruptGuard::interrupted()) {
      sum.interrupted = true;
      break;
    }
    const double t = f * dt, s = double(o.speed) * t;
    glm::vec2 p2 = pointAt(path, s), ahead = pointAt(path, s + 1.0);
    glm::vec2 fwd2 = glm::length(ahead - p2) > 1e-4f ? glm::normalize(ahead - p2) : glm::vec2(1.0f, 0.0f);
    FlythroughFrame fr;
    fr.index = f;
    fr.timeS = t;
    fr.position = {p2.x, o.altitude, p2.y};
    fr.timeOfDay = o.todStart + (o.todEnd - o.todStart) * float(f) / float(std::max(1, frames - 1));
    FrameInput in;
    in.position = fr.position;
    in.direction = glm::vec3(fwd2.x * std::cos(pitch), std::sin(pitch), fwd2.y * std::cos(pitch));
    in.velocity = glm::vec3(fwd2.x, 0.0f, fwd2.y) * o.speed;
    in.timeOfDayHours = fr.timeOfDay;
    in.weather = o.weatherStart + (o.weatherEnd - o.weatherStart) * float(f) / float(std::max(1, frames - 1));
    fr.direction = in.direction;
    fr.weather = in.weather;
    in.dtSeconds = float(dt);
    const double frameStartUs = trace ? trace->nowUs() : 0.0;
    auto t0 = Clock::now();
    fr.stats = manager.update(in);
    shadeSamples(manager, layout, o, pitch, fwd2, fr);
    fr.frameMs = msSince(t0);
    if (trace) traceFrame(*trace, fr, f, frameStartUs);
    accumulateFrame(fr, ft, sum);
    if (o.onFrame) o.onFrame(fr, manager);
    if (perFrame) perFrame(fr);
    progress.update(size_t(f + 1));
    ++sum.frames;
    if (o.realtime)
      std::this_thread::sleep_until(flightStart + std::chrono::duration_cast<Clock::duration>(
                                                      std::chrono::duration<double>(double(f + 1) * dt)));
  }
  manager.drainIo();
  progress.finish();
  summariseFlight(ft, sum);
  return sum;
}

}  // namespace lfgi::streaming
