// Graphics pipelines for headless rendering (Vulkan 1.3 dynamic rendering, no render passes or
// framebuffers): a move-only 2D Image with its view, and a GraphicsProgram (vertex + fragment SPIR-V,
// set-0 buffer layout and push-constant size from SPIRV-Cross reflection of both stages, like Program).
// Vertex pulling only: no vertex-input state; triangle lists; no culling; viewport and scissor dynamic.
// Used by the cubemap baseline (cubemap_raster.h).
#pragma once

#include <vulkan/vulkan.h>

#include <cstddef>
#include <initializer_list>
#include <span>
#include <string>
#include <vector>

#include "gpu/buffer.h"
#include "gpu/context.h"
#include "gpu/program.h"

namespace lfgi::gpu {

// Device-local 2D image (one mip, one layer) and a view of it. Throws lfgi::Error if the format does
// not support `usage` with optimal tiling or the size exceeds maxImageDimension2D.
class Image {
 public:
  Image() = default;
  Image(Context& ctx, uint32_t width, uint32_t height, VkFormat format, VkImageUsageFlags usage);
  Image(Image&& other) noexcept;
  Image& operator=(Image&& other) noexcept;
  Image(const Image&) = delete;
  Image& operator=(const Image&) = delete;
  ~Image();

  VkImage handle() const { return image_; }
  VkImageView view() const { return view_; }
  VkFormat format() const { return format_; }
  VkImageAspectFlags aspect() const { return aspect_; }
  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }

 private:
  void release();
  VkDevice device_ = VK_NULL_HANDLE;
  VkImage image_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkImageView view_ = VK_NULL_HANDLE;
  VkFormat format_ = VK_FORMAT_UNDEFINED;
  VkImageAspectFlags aspect_ = 0;
  uint32_t width_ = 0, height_ = 0;
};

// Records a layout transition of the whole image with a full barrier between the given stages/accesses.
void imageBarrier(VkCommandBuffer cmd, const Image& image, VkImageLayout from, VkImageLayout to,
                  VkPipelineStageFlags srcStage, VkAccessFlags srcAccess, VkPipelineStageFlags dstStage,
                  VkAccessFlags dstAccess);

struct GraphicsPipelineDesc {
  std::string vertexShader;    // name of <shaderDirectory()>/<name>.spv
  std::string fragmentShader;  // idem
  std::vector<VkFormat> colorFormats;
  VkFormat depthFormat = VK_FORMAT_UNDEFINED;  // none when undefined
  VkCompareOp depthCompare = VK_COMPARE_OP_GREATER;
};

class GraphicsProgram {
 public:
  // Loads and reflects both stages (set 0, storage/uniform buffers only, bindings dense across the two
  // stages, one push-constant block visible to both). Throws lfgi::Error naming the shader otherwise.
  GraphicsProgram(Context& ctx, const GraphicsPipelineDesc& desc);
  GraphicsProgram(const GraphicsProgram&) = delete;
  GraphicsProgram& operator=(const GraphicsProgram&) = delete;
  ~GraphicsProgram();

  const std::string& name() const { return name_; }
  const std::vector<ShaderBinding>& bindings() const { return bindings_; }
  uint32_t pushConstantBytes() const { return pushConstantBytes_; }
  VkPipeline pipeline() const { return pipeline_; }
  VkPipelineLayout layout() const { return layout_; }

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  std::string name_;
  std::vector<ShaderBinding> bindings_;
  uint32_t pushConstantBytes_ = 0;
  VkDescriptorSetLayout setLayout_ = VK_NULL_HANDLE;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
};

// Binds the pipeline and pushes the buffers (binding order 0..n-1). Throws if the count differs.
void bindGraphics(Context& ctx, VkCommandBuffer cmd, const GraphicsProgram& program,
                  std::initializer_list<const Buffer*> buffers);

// Pushes constants to both stages. Throws if the size differs from the reflected block.
void pushGraphicsConstants(VkCommandBuffer cmd, const GraphicsProgram& program,
                           std::span<const std::byte> bytes);
template <typename Params>
void pushGraphicsConstants(VkCommandBuffer cmd, const GraphicsProgram& program, const Params& params) {
  pushGraphicsConstants(cmd, program, std::as_bytes(std::span(&params, 1)));
}

}  // namespace lfgi::gpu
