#include "app/fly_render.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>

#include "bake/embree_scene.h"
#include "bake/shading_inputs.h"
#include "bake/shading_view.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/hash.h"
#include "core/image.h"
#include "gpu/context.h"
#include "gpu/gbuffer_pass.h"
#include "gpu/probe_shading_pass.h"
#include "gpu/timing.h"
#include "streaming/device_shading.h"

namespace lfgi::app {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

void parseRenderSize(const std::string& text, int& width, int& height) {
  int w = 0, h = 0;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%dx%d%c", &w, &h, &tail) != 2 || w < 16 || h < 16 || w > 4096 || h > 4096)
    fail("--render '{}': expected WIDTHxHEIGHT, each 16 to 4096 (e.g. 320x180)", text);
  width = w;
  height = h;
}

namespace {

constexpr int kStripFrames = 8;

struct RenderedFrame {
  int index = 0, flightFrame = 0;
  double timeS = 0.0, gbufferMs = 0.0, shadeMs = 0.0, uploadMs = 0.0;
  size_t uploadBytes = 0;
  int surfacePixels = 0, missingPixels = 0;
  double fallbackShare = 0.0;  // mean fallback share of the indirect light over surface pixels
  uint64_t hash = 0;           // of the frame's image
  // Against the path-traced reference (reference frames only; < 0: not compared).
  double referenceTotal = -1.0, referenceIndirect = -1.0, referenceSeconds = 0.0;
};

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[size_t(std::lround(q * double(v.size() - 1)))];
}

// The shaded frame in bake/shading_view.h's layers (R/G/B total, direct, indirect = diffuse + specular,
// weight, fallback) and its GI bookkeeping per pixel.
Image frameImage(const gpu::ShadeOutputHost& s, const gpu::GBufferHost& g, RenderedFrame& r) {
  Image img(s.width, s.height,
            {"R", "G", "B", "direct.R", "direct.G", "direct.B", "indirect.R", "indirect.G", "indirect.B",
             "weight", "fallback"});
  double share = 0.0;
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x) {
      const size_t p = size_t(y) * size_t(s.width) + size_t(x);
      for (int c = 0; c < 3; ++c) {
        img.at(x, y, c) = s.total[p][c];
        img.at(x, y, 3 + c) = s.direct[p][c];
        img.at(x, y, 6 + c) = s.diffuse[p][c] + s.specular[p][c];
      }
      img.at(x, y, 9) = s.diffuse[p].w;
      img.at(x, y, 10) = s.direct[p].w;
      const bool surface = g.position[p].w >= 0.0f && g.emission[p].w < 0.5f;
      if (!surface) continue;
      ++r.surfacePixels;
      share += s.direct[p].w;
      if (!(s.diffuse[p].w > 0.0f) && !(s.direct[p].w > 0.0f)) ++r.missingPixels;
    }
  r.fallbackShare = r.surfacePixels ? share / r.surfacePixels : 0.0;
  r.hash = fnv1a(kFnv1aOffset, img.pixels.data(), img.pixels.size() * sizeof(float));
  return img;
}

// Half size by 2 x 2 box filter of the R, G, B channels (the strip's tiles).
Image halfSize(const Image& in) {
  Image out(std::max(1, in.width / 2), std::max(1, in.height / 2), {"R", "G", "B"});
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const int x0 = std::min(2 * x, in.width - 1), y0 = std::min(2 * y, in.height - 1);
        const int x1 = std::min(x0 + 1, in.width - 1), y1 = std::min(y0 + 1, in.height - 1);
        out.at(x, y, c) = 0.25f * (in.at(x0, y0, c) + in.at(x1, y0, c) + in.at(x0, y1, c) + in.at(x1, y1, c));
      }
  return out;
}

std::string framesCsv(const std::vector<RenderedFrame>& frames) {
  std::string csv =
      "index,flight_frame,time_s,gpu_gbuffer_ms,gpu_shade_ms,upload_ms,upload_bytes,surface_pixels,"
      "missing_gi_pixels,fallback_share,hash,reference_total_rel_rms,reference_indirect_rel_rms\n";
  for (const RenderedFrame& f : frames)
    csv += fmt::format("{},{},{:.4f},{:.4f},{:.4f},{:.4f},{},{},{},{:.5f},{:016x},{:.5f},{:.5f}\n", f.index,
                       f.flightFrame, f.timeS, f.gbufferMs, f.shadeMs, f.uploadMs, f.uploadBytes,
                       f.surfacePixels, f.missingPixels, f.fallbackShare, f.hash, f.referenceTotal,
                       f.referenceIndirect);
  return csv;
}

}  // namespace

struct FlyRenderer::Impl {
  Impl(FlyRenderOptions options, const streaming::CellFileSource& s, float keep, TraceWriter* t)
      : o(std::move(options)), source(s), keepRadius(keep), trace(t) {}
  FlyRenderOptions o;
  const streaming::CellFileSource& source;
  float keepRadius;
  TraceWriter* trace;
  std::unique_ptr<gpu::Context> ctx;  // first: destroyed last
  std::optional<streaming::DeviceShading> shading;
  std::optional<gpu::GpuTimer> timer;
  gpu::GBuffer gbuffer;
  gpu::ShadeOutput out;
  std::optional<float> exposureEv;  // the first frame's auto exposure, kept for the flight
  std::vector<RenderedFrame> frames;
  std::vector<Image> strip;  // up to kStripFrames frames spread over the flight, half size
  size_t deviceBytesPeak = 0;

  void start(const streaming::StreamingManager& manager);
  // Frames the flight will render (frames 0, every, 2 every, ... of the planned flight).
  int plannedRendered() const { return std::max(1, (o.plannedFrames + o.every - 1) / o.every); }
  // The G-buffer's cells: those within the shading distance of the camera's cell.
  int sceneRing() const { return std::max(1, int(std::ceil(o.shadeDistance / source.layout().cellSize))); }
  void render(const streaming::FlythroughFrame& f, RenderedFrame& r);
  void writeFrame(const Image& img, const RenderedFrame& r);
  bool isReference(int index) const;
  void compareWithReference(const streaming::FlythroughFrame& f, const Image& img, RenderedFrame& r);
  std::optional<std::string> writeStrip() const;
  std::optional<std::string> writeVideo(std::string& note) const;
};

void FlyRenderer::Impl::start(const streaming::StreamingManager& manager) {
  ctx = gpu::createContext();
  shading.emplace(*ctx, manager, source, keepRadius);
  timer.emplace(*ctx, 3);
  gbuffer = gpu::createGBuffer(*ctx, o.width, o.height);
  out = gpu::createShadeOutput(*ctx, o.width, o.height);
  fs::create_directories(o.outDir / "frames");
  spdlog::info("render: {}x{} every {} frames on {}", o.width, o.height, o.every, ctx->info.name);
}

// Upload, then one submit: G-buffer and shading between GPU timestamps.
void FlyRenderer::Impl::render(const streaming::FlythroughFrame& f, RenderedFrame& r) {
  const auto t0 = Clock::now();
  const double uploadStartUs = trace ? trace->nowUs() : 0.0;
  r.uploadBytes = shading->upload(f.position);
  r.uploadMs = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  const shared::GpuCamera camera =
      gpu::makeGpuCamera(f.position, f.position + f.direction, o.verticalFovDeg, o.width, o.height);
  const streaming::WorldLayout l = source.layout();
  const int ring = sceneRing();
  const gpu::GpuSceneBuffers& scene = shading->worldScene(l.cellOf(f.position), ring);
  gpu::ShadingOptions options;  // direct light with shadow rays, indirect from the probes
  const double submitUs = trace ? trace->nowUs() : 0.0;
  gpu::submitAndWait(*ctx, [&](VkCommandBuffer cmd) {
    timer->reset(cmd);
    timer->stamp(cmd, 0);
    shading->recordWorldGBuffer(cmd, camera, l.cellOf(f.position), gbuffer, ring);
    timer->stamp(cmd, 1);
    shading->recordShade(cmd, camera, o.width, o.height, f.timeOfDay, f.weather, scene, options, gbuffer,
                         out);
    timer->stamp(cmd, 2);
  });
  r.gbufferMs = timer->elapsedMs(0, 1);
  r.shadeMs = timer->elapsedMs(1, 2);
  deviceBytesPeak = std::max(deviceBytesPeak, shading->deviceBytes());
  if (trace) {
    trace->complete("render upload", "render", uploadStartUs, r.uploadMs * 1e3);
    trace->complete("gpu gbuffer", "gpu", submitUs, r.gbufferMs * 1e3);
    trace->complete("gpu shade", "gpu", submitUs + r.gbufferMs * 1e3, r.shadeMs * 1e3);
  }
}

void FlyRenderer::Impl::writeFrame(const Image& img, const RenderedFrame& r) {
  if (!exposureEv) exposureEv = std::log2(0.18f / medianLuminance(img));
  writePng(o.outDir / "frames" / fmt::format("frame_{:05d}.png", r.index), img, *exposureEv);
}

// K reference frames spread over the planned rendered frames: the first, the last and evenly between.
bool FlyRenderer::Impl::isReference(int index) const {
  const int planned = plannedRendered(), k = o.referenceFrames;
  if (k <= 0) return false;
  if (k == 1) return index == planned / 2;
  for (int i = 0; i < k; ++i)
    if (index == int(std::lround(double(i) * (planned - 1) / (k - 1)))) return true;
  return false;
}

// The same view path-traced over the same cells' geometry (Embree) and the relative RMS against it.
void FlyRenderer::Impl::compareWithReference(const streaming::FlythroughFrame& f, const Image& img,
                                             RenderedFrame& r) {
  const bake::EmbreeScene scene(shading->worldMesh(source.layout().cellOf(f.position), sceneRing()),
                                fmt::format("fly frame {}", f.index));
  worlds::SkyState sky;
  sky.timeOfDayHours = f.timeOfDay;
  sky.overcast = f.weather;
  bake::RenderOptions ro;
  ro.width = o.width;
  ro.height = o.height;
  ro.samplesPerPixel = o.referenceSpp;
  ro.maxBounces = o.referenceBounces;
  const bake::RenderResult ref = bake::renderShadingReference(
      scene, worlds::makeSky(sky),
      bake::PinholeCamera{f.position, f.position + f.direction, o.verticalFovDeg}, ro);
  if (ref.interrupted) return;
  const std::vector<uint8_t> mask = bake::shadedSurfaceMask(img, ref.image, 1e30f);
  r.referenceTotal = bake::layerRelativeRms(img, "", ref.image, "", &mask);
  r.referenceIndirect = bake::layerRelativeRms(img, "indirect.", ref.image, "indirect.", &mask);
  r.referenceSeconds = ref.seconds;
  const fs::path dir = o.outDir / "frames";
  writePng(dir / fmt::format("frame_{:05d}_reference.png", r.index), ref.image, exposureEv.value_or(0.0f));
  writePng(dir / fmt::format("frame_{:05d}_error.png", r.index),
           bake::errorHeatMap(img, "indirect.", ref.image, "indirect."), 1.0f);  // as `lfgi render --compare`
  spdlog::info("render: frame {} vs a {} spp path-traced reference: total {:.4f}, indirect {:.4f} ({:.1f} s)",
               r.index, o.referenceSpp, r.referenceTotal, r.referenceIndirect, ref.seconds);
}

std::optional<std::string> FlyRenderer::Impl::writeStrip() const {
  if (strip.empty()) return std::nullopt;
  const int tw = strip.front().width, th = strip.front().height;
  Image s(int(strip.size()) * tw, th, {"R", "G", "B"});  // one row, in flight order
  for (size_t k = 0; k < strip.size(); ++k)
    for (int y = 0; y < th; ++y)
      for (int x = 0; x < tw; ++x)
        for (int c = 0; c < 3; ++c) s.at(int(k) * tw + x, y, c) = strip[k].at(x, y, c);
  writePng(o.outDir / "strip.png", s, exposureEv.value_or(0.0f));
  return "strip.png";
}

// flight.mp4 from the PNG frames by ffmpeg (H.264, yuv420p), written to a temporary name and renamed.
std::optional<std::string> FlyRenderer::Impl::writeVideo(std::string& note) const {
  if (frames.size() < 2) {
    note = "fewer than 2 rendered frames";
    return std::nullopt;
  }
  if (std::system("command -v ffmpeg >/dev/null 2>&1") != 0) {
    note = "ffmpeg is not installed (scripts/apt-packages.txt lists it); the PNG frames are in frames/";
    return std::nullopt;
  }
  const fs::path tmp = o.outDir / "flight.tmp.mp4", mp4 = o.outDir / "flight.mp4";
  const std::string cmd = fmt::format(
      "ffmpeg -y -loglevel error -framerate {:.3f} -i '{}' -c:v libx264 -pix_fmt yuv420p "
      "-vf 'scale=trunc(iw/2)*2:trunc(ih/2)*2' '{}'",
      double(o.fps) / o.every, (o.outDir / "frames" / "frame_%05d.png").string(), tmp.string());
  if (std::system(cmd.c_str()) != 0) {
    std::error_code ec;
    fs::remove(tmp, ec);
    note = "ffmpeg failed: " + cmd;
    spdlog::warn("render: {}", note);
    return std::nullopt;
  }
  fs::rename(tmp, mp4);
  note = fmt::format("H.264 at {:.1f} fps", double(o.fps) / o.every);
  return "flight.mp4";
}

FlyRenderer::FlyRenderer(FlyRenderOptions options, const streaming::CellFileSource& source, float keepRadius,
                         TraceWriter* trace)
    : impl_(std::make_unique<Impl>(std::move(options), source, keepRadius, trace)) {
  if (impl_->o.width <= 0 || impl_->o.height <= 0) fail("FlyRenderer: no frame size");
  if (impl_->o.every < 1) fail("--render-every {}: must be >= 1", impl_->o.every);
}

FlyRenderer::~FlyRenderer() = default;

void FlyRenderer::frame(const streaming::FlythroughFrame& f, const streaming::StreamingManager& manager) {
  Impl& m = *impl_;
  if (f.index % m.o.every != 0) return;
  if (!m.ctx) m.start(manager);
  RenderedFrame r;
  r.index = int(m.frames.size());
  r.flightFrame = f.index;
  r.timeS = f.timeS;
  m.render(f, r);
  const Image img = frameImage(gpu::readShadeOutput(*m.ctx, m.out), gpu::readGBuffer(*m.ctx, m.gbuffer), r);
  m.writeFrame(img, r);
  if (m.isReference(r.index)) m.compareWithReference(f, img, r);
  // Strip tiles: frames 0, stride, 2 stride, ... of the planned flight (at most kStripFrames).
  const int stride = std::max(1, (m.plannedRendered() + kStripFrames - 1) / kStripFrames);
  if (r.index % stride == 0 && int(m.strip.size()) < kStripFrames) m.strip.push_back(halfSize(img));
  m.frames.push_back(r);
}

nlohmann::ordered_json FlyRenderer::finish() {
  Impl& m = *impl_;
  nlohmann::ordered_json j;
  j["width"] = m.o.width;
  j["height"] = m.o.height;
  j["every"] = m.o.every;
  j["frames"] = m.frames.size();
  if (m.frames.empty()) return j;
  writeFileAtomic(m.o.outDir / "render_frames.csv", framesCsv(m.frames));
  std::vector<double> gb, sh, up;
  long missing = 0, surface = 0;
  int framesMissing = 0;
  double share = 0.0;
  uint64_t hash = kFnv1aOffset;
  for (const RenderedFrame& f : m.frames) {
    gb.push_back(f.gbufferMs);
    sh.push_back(f.shadeMs);
    up.push_back(f.uploadMs);
    missing += f.missingPixels;
    surface += f.surfacePixels;
    framesMissing += f.missingPixels > 0;
    share += f.fallbackShare;
    hash = fnv1aValue(hash, f.hash);
  }
  const double mpix = double(m.o.width) * m.o.height / 1e6;
  j["device"] = m.ctx->info.name;
  j["surface_pixels"] = surface;
  j["pixels_missing_gi"] = missing;
  j["frames_missing_gi"] = framesMissing;
  j["fallback_share_mean"] = share / double(m.frames.size());
  j["gpu_gbuffer_ms_p50"] = percentile(gb, 0.5);
  j["gpu_gbuffer_ms_p99"] = percentile(gb, 0.99);
  j["gpu_shade_ms_p50"] = percentile(sh, 0.5);
  j["gpu_shade_ms_p99"] = percentile(sh, 0.99);
  j["shade_ms_per_mpixel"] = percentile(sh, 0.5) / mpix;
  j["shade_to_gbuffer_ratio_p50"] =
      percentile(gb, 0.5) > 0.0 ? percentile(sh, 0.5) / percentile(gb, 0.5) : 0.0;
  j["upload_ms_p50"] = percentile(up, 0.5);
  j["upload_ms_p99"] = percentile(up, 0.99);
  j["device_bytes_peak"] = m.deviceBytesPeak;
  j["exposure_ev"] = m.exposureEv.value_or(0.0f);
  j["frames_hash"] = fmt::format("{:016x}", hash);
  nlohmann::ordered_json refs = nlohmann::ordered_json::array();
  double refIndirect = 0.0;
  for (const RenderedFrame& f : m.frames) {
    if (f.referenceIndirect < 0.0) continue;
    refs.push_back({{"frame", f.index},
                    {"flight_frame", f.flightFrame},
                    {"spp", m.o.referenceSpp},
                    {"total_rel_rms", f.referenceTotal},
                    {"indirect_rel_rms", f.referenceIndirect},
                    {"seconds", f.referenceSeconds}});
    refIndirect += f.referenceIndirect;
  }
  j["reference_indirect_rel_rms_mean"] = refs.empty() ? 0.0 : refIndirect / double(refs.size());
  j["reference"] = refs;
  j["frames_dir"] = "frames";
  j["strip"] = m.writeStrip().value_or("");
  std::string note;
  const std::optional<std::string> video = m.writeVideo(note);
  j["video"] = video.value_or("");
  j["video_note"] = note;
  return j;
}

}  // namespace lfgi::app
