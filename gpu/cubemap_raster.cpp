#include "gpu/cubemap_raster.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "gpu/timing.h"

namespace lfgi::gpu {

namespace {

constexpr VkFormat kNormalDistanceFormat = VK_FORMAT_R32G32B32A32_SFLOAT;
constexpr VkFormat kAlbedoFormat = VK_FORMAT_R16G16B16A16_SFLOAT;
constexpr VkFormat kEmissionFormat = VK_FORMAT_R16G16B16A16_SFLOAT;
constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;

GraphicsPipelineDesc rasterDesc() {
  GraphicsPipelineDesc d;
  d.vertexShader = "cubemap_raster_face";
  d.fragmentShader = "cubemap_raster_gbuffer";
  d.colorFormats = {kNormalDistanceFormat, kAlbedoFormat, kEmissionFormat};
  d.depthFormat = kDepthFormat;
  d.depthCompare = VK_COMPARE_OP_GREATER;  // reversed depth, see cubemap_raster_face.vert
  return d;
}

struct BatchLayout {  // face tiles per batch and the atlas they share
  uint32_t F;
  size_t probesPerBatch;
  uint32_t tilesX;
  uint32_t atlasW, atlasH;
  size_t batches;
};

BatchLayout planBatches(const Context& ctx, const CubemapScene& scene, std::span<const glm::vec3> probes,
                        const CubemapRasterOptions& o) {
  if (scene.triangles.empty() || probes.empty())
    fail("cubemap raster: {} triangles, {} probes: need at least one of each", scene.triangles.size(),
         probes.size());
  if (scene.vertices.size() != 3 * scene.triangles.size())
    fail("cubemap raster: {} vertices for {} triangles (need 3 per triangle)", scene.vertices.size(),
         scene.triangles.size());
  if (o.resolution < 1 || o.resolution > 1024)
    fail("cubemap raster: resolution {} outside [1, 1024]", o.resolution);
  if (o.faceResolution < 0 || o.faceResolution > 4096)
    fail("cubemap raster: faceResolution {} outside [0, 4096]", o.faceResolution);
  if (!(std::isfinite(o.nearPlane) && o.nearPlane > 0.0f))
    fail("cubemap raster: nearPlane {} must be finite and > 0", o.nearPlane);
  const uint32_t F = uint32_t(o.faceResolution > 0 ? o.faceResolution : o.resolution);
  const int64_t tileTexels = int64_t(F) * F;
  if (o.maxAtlasTexels < 6 * tileTexels)
    fail("cubemap raster: maxAtlasTexels {} below one probe's 6 faces of {}^2", o.maxAtlasTexels, F);
  if (scene.vertices.size() > 0xFFFFFFFFull)
    fail("cubemap raster: {} vertices exceed 2^32", scene.vertices.size());

  const uint32_t maxDim = ctx.properties.limits.maxImageDimension2D;
  const uint32_t maxTilesPerRow = std::max(1u, maxDim / F);
  const size_t probesPerBatch =
      std::min(probes.size(), size_t(std::min<int64_t>(o.maxAtlasTexels / (6 * tileTexels),
                                                       int64_t(maxTilesPerRow) * maxTilesPerRow / 6)));
  const uint32_t tiles = uint32_t(probesPerBatch * 6);
  const uint32_t tilesX = std::min(maxTilesPerRow, uint32_t(std::ceil(std::sqrt(double(tiles)))));
  const uint32_t tilesY = (tiles + tilesX - 1) / tilesX;
  const uint32_t atlasW = tilesX * F, atlasH = tilesY * F;
  if (atlasH > maxDim)
    fail("cubemap raster: atlas {}x{} exceeds maxImageDimension2D {}", atlasW, atlasH, maxDim);
  const size_t batches = (probes.size() + probesPerBatch - 1) / probesPerBatch;
  const uint32_t* maxGroups = ctx.properties.limits.maxComputeWorkGroupCount;
  if ((uint64_t(o.resolution) + 7) / 8 > maxGroups[0] || probesPerBatch > maxGroups[2])
    fail("cubemap raster: N = {} x {} probes per batch exceeds the dispatch limits", o.resolution,
         probesPerBatch);
  return {F, probesPerBatch, tilesX, atlasW, atlasH, batches};
}

// Renders the 6 faces of probes [first, first + count) into the atlas tiles.
void recordRaster(Context& ctx, VkCommandBuffer cmd, const GraphicsProgram& raster, const Image (&images)[3],
                  const Image& depth, const Buffer& vertexBuf, const Buffer& triangleBuf,
                  std::span<const glm::vec3> probes, size_t first, size_t count, const BatchLayout& layout,
                  const CubemapRasterOptions& o, uint32_t vertexCount) {
  const uint32_t F = layout.F, tilesX = layout.tilesX, atlasW = layout.atlasW, atlasH = layout.atlasH;
  // The previous batch's copy read the images: its contents are dead, so UNDEFINED -> attachment.
  for (const Image& im : images)
    imageBarrier(cmd, im, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                 VK_PIPELINE_STAGE_TRANSFER_BIT, 0, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                 VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT);
  imageBarrier(cmd, depth, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL,
               VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT, 0,
               VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT,
               VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);

  VkRenderingAttachmentInfo color[3];
  for (int i = 0; i < 3; ++i) {
    color[i] = {VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    color[i].imageView = images[i].view();
    color[i].imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    color[i].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
    color[i].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    color[i].clearValue.color = {{0.0f, 0.0f, 0.0f, 0.0f}};  // albedo a = 0 marks sky
  }
  VkRenderingAttachmentInfo depthAtt{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
  depthAtt.imageView = depth.view();
  depthAtt.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
  depthAtt.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
  depthAtt.storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
  depthAtt.clearValue.depthStencil = {0.0f, 0};  // reversed depth: 0 is infinitely far
  VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO};
  rendering.renderArea = {{0, 0}, {atlasW, atlasH}};
  rendering.layerCount = 1;
  rendering.colorAttachmentCount = 3;
  rendering.pColorAttachments = color;
  rendering.pDepthAttachment = &depthAtt;
  vkCmdBeginRendering(cmd, &rendering);
  bindGraphics(ctx, cmd, raster, {&vertexBuf, &triangleBuf});
  for (size_t p = 0; p < count; ++p) {
    shared::CubemapRasterParams params{};
    params.probe = glm::vec4(probes[first + p], o.nearPlane);
    for (uint32_t f = 0; f < 6; ++f) {
      const uint32_t tile = uint32_t(p * 6 + f);
      const int32_t x = int32_t((tile % tilesX) * F), y = int32_t((tile / tilesX) * F);
      const VkViewport vp{float(x), float(y), float(F), float(F), 0.0f, 1.0f};
      const VkRect2D sc{{x, y}, {F, F}};
      vkCmdSetViewport(cmd, 0, 1, &vp);
      vkCmdSetScissor(cmd, 0, 1, &sc);
      params.face = f;
      pushGraphicsConstants(cmd, raster, params);
      vkCmdDraw(cmd, vertexCount, 1, 0, 0);
    }
  }
  vkCmdEndRendering(cmd);
}

void recordCopy(VkCommandBuffer cmd, const Image (&images)[3], const Buffer (&copies)[3], uint32_t atlasW,
                uint32_t atlasH) {
  // Attachments -> copy sources; the previous batch's resample has finished reading the copies.
  for (const Image& im : images)
    imageBarrier(cmd, im, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                 VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT,
                 VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
  memoryBarrier(cmd);
  for (int i = 0; i < 3; ++i) {
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {atlasW, atlasH, 1};
    vkCmdCopyImageToBuffer(cmd, images[i].handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, copies[i].handle(),
                           1, &region);
  }
}

CubemapCapture collectCapture(Context& ctx, const GpuTimer& timer, const BatchLayout& layout,
                              const CubemapRasterOptions& o, size_t probeCount, size_t texels,
                              const Buffer& distBuf, const Buffer& normalBuf, const Buffer& albedoBuf,
                              const Buffer& radianceBuf, const Buffer& counters) {
  const uint32_t F = layout.F;
  const size_t probesPerBatch = layout.probesPerBatch, batches = layout.batches;
  CubemapCapture out;
  out.faceResolution = int(F);
  out.probesPerBatch = int(probesPerBatch);
  out.batches = int(batches);
  uint32_t prev = 0;
  for (size_t b = 0; b < batches; ++b) {
    const uint32_t s = uint32_t(1 + 3 * b);
    out.rasterMs += timer.elapsedMs(prev, s);
    out.copyMs += timer.elapsedMs(s, s + 1);
    out.resampleMs += timer.elapsedMs(s + 1, s + 2);
    prev = s + 2;
  }
  ProbeAtlas& atlas = out.atlas;
  atlas.resolution = o.resolution;
  atlas.probeCount = int(probeCount);
  atlas.gpuMs = timer.elapsedMs(0, prev);
  atlas.splatMs = out.rasterMs;
  atlas.resolveMs = out.copyMs + out.resampleMs;
  atlas.distance.resize(texels);
  atlas.normal.resize(texels);
  atlas.albedo.resize(texels);
  atlas.radiance.resize(texels);
  readback<glm::vec2>(ctx, distBuf, atlas.distance);
  readback<glm::vec4>(ctx, normalBuf, atlas.normal);
  readback<glm::vec4>(ctx, albedoBuf, atlas.albedo);
  readback<glm::vec4>(ctx, radianceBuf, atlas.radiance);
  uint32_t holes = 0;
  readback<uint32_t>(ctx, counters, std::span<uint32_t>(&holes, 1));
  atlas.holeFractionBeforeFill = atlas.holeFractionAfterFill = double(holes) / double(texels);
  return out;
}

}  // namespace

void CubemapScene::addTriangle(glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 albedo, glm::vec3 emission) {
  const glm::vec3 cr = glm::cross(b - a, c - a);
  const float len = glm::length(cr);
  const glm::vec3 n = len > 0.0f ? cr / len : glm::vec3(0.0f);
  vertices.push_back(glm::vec4(a, 1.0f));
  vertices.push_back(glm::vec4(b, 1.0f));
  vertices.push_back(glm::vec4(c, 1.0f));
  triangles.push_back({glm::vec4(n, 0.0f), glm::vec4(albedo, 1.0f), glm::vec4(emission, 0.0f)});
}

CubemapRaster::CubemapRaster(Context& ctx)
    : ctx_(ctx), raster_(ctx, rasterDesc()), resample_(ctx, "cubemap_raster_resample") {}

CubemapCapture CubemapRaster::run(const CubemapScene& scene, std::span<const glm::vec3> probes,
                                  const CubemapRasterOptions& o) {
  const BatchLayout layout = planBatches(ctx_, scene, probes, o);
  const uint32_t F = layout.F, tilesX = layout.tilesX, atlasW = layout.atlasW, atlasH = layout.atlasH;
  const size_t probesPerBatch = layout.probesPerBatch, batches = layout.batches;

  const uint32_t n = uint32_t(o.resolution);
  const size_t texels = size_t(n) * n * probes.size();
  const size_t atlasTexels = size_t(atlasW) * atlasH;
  Buffer vertexBuf = createStorageBuffer(ctx_, scene.vertices.size() * sizeof(glm::vec4));
  Buffer triangleBuf = createStorageBuffer(ctx_, scene.triangles.size() * sizeof(shared::CubemapTriangle));
  upload<glm::vec4>(ctx_, vertexBuf, scene.vertices);
  upload<shared::CubemapTriangle>(ctx_, triangleBuf, scene.triangles);
  const VkImageUsageFlags colorUsage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
  Image images[3] = {Image(ctx_, atlasW, atlasH, kNormalDistanceFormat, colorUsage),
                     Image(ctx_, atlasW, atlasH, kAlbedoFormat, colorUsage),
                     Image(ctx_, atlasW, atlasH, kEmissionFormat, colorUsage)};
  Image depth(ctx_, atlasW, atlasH, kDepthFormat, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT);
  Buffer copies[3] = {createStorageBuffer(ctx_, atlasTexels * 16), createStorageBuffer(ctx_, atlasTexels * 8),
                      createStorageBuffer(ctx_, atlasTexels * 8)};
  Buffer distBuf = createStorageBuffer(ctx_, texels * sizeof(glm::vec2));
  Buffer normalBuf = createStorageBuffer(ctx_, texels * sizeof(glm::vec4));
  Buffer albedoBuf = createStorageBuffer(ctx_, texels * sizeof(glm::vec4));
  Buffer radianceBuf = createStorageBuffer(ctx_, texels * sizeof(glm::vec4));
  Buffer counters = createStorageBuffer(ctx_, 4 * sizeof(uint32_t));

  const uint32_t vertexCount = uint32_t(scene.vertices.size());
  GpuTimer timer(ctx_, uint32_t(1 + 3 * batches));
  submitAndWait(ctx_, [&](VkCommandBuffer cmd) {
    timer.reset(cmd);
    timer.stamp(cmd, 0);
    vkCmdFillBuffer(cmd, counters.handle(), 0, VK_WHOLE_SIZE, 0u);
    memoryBarrier(cmd);
    for (size_t b = 0; b < batches; ++b) {
      const size_t first = b * probesPerBatch;
      const size_t count = std::min(probesPerBatch, probes.size() - first);
      recordRaster(ctx_, cmd, raster_, images, depth, vertexBuf, triangleBuf, probes, first, count, layout, o,
                   vertexCount);
      timer.stamp(cmd, uint32_t(1 + 3 * b));

      recordCopy(cmd, images, copies, atlasW, atlasH);
      timer.stamp(cmd, uint32_t(2 + 3 * b));
      memoryBarrier(cmd);

      shared::CubemapResampleParams rp{};
      rp.res = n;
      rp.faceRes = F;
      rp.probeCount = uint32_t(count);
      rp.probeOffset = uint32_t(first);
      rp.tilesX = tilesX;
      rp.atlasWidth = atlasW;
      dispatch(
          ctx_, cmd, resample_,
          {&copies[0], &copies[1], &copies[2], &distBuf, &normalBuf, &albedoBuf, &radianceBuf, &counters}, rp,
          {n, n, uint32_t(count)});
      memoryBarrier(cmd);
      timer.stamp(cmd, uint32_t(3 + 3 * b));
    }
  });

  return collectCapture(ctx_, timer, layout, o, probes.size(), texels, distBuf, normalBuf, albedoBuf,
                        radianceBuf, counters);
}

}  // namespace lfgi::gpu
