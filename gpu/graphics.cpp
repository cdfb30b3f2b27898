#include "gpu/graphics.h"

#include <spirv_cross/spirv_cross_c.h>

#include <algorithm>
#include <cstring>
#include <utility>

#include "core/error.h"
#include "core/file_util.h"

namespace lfgi::gpu {
namespace {

bool isDepthFormat(VkFormat f) {
  return f == VK_FORMAT_D32_SFLOAT || f == VK_FORMAT_D16_UNORM || f == VK_FORMAT_D24_UNORM_S8_UINT ||
         f == VK_FORMAT_D32_SFLOAT_S8_UINT || f == VK_FORMAT_X8_D24_UNORM_PACK32;
}

uint32_t deviceLocalMemoryType(const Context& ctx, uint32_t typeBits) {
  const VkPhysicalDeviceMemoryProperties& mp = ctx.memoryProperties;
  for (VkMemoryPropertyFlags want :
       {VkMemoryPropertyFlags(VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT), VkMemoryPropertyFlags(0)})
    for (uint32_t i = 0; i < mp.memoryTypeCount; ++i)
      if ((typeBits & (1u << i)) && (mp.memoryTypes[i].propertyFlags & want) == want) return i;
  fail("no memory type for an image on '{}'", ctx.info.name);
}

std::vector<uint32_t> loadSpirv(const std::string& name) {
  const std::filesystem::path path = shaderDirectory() / (name + ".spv");
  std::vector<std::byte> bytes = readFileBytes(path);
  if (bytes.size() % 4 != 0 || bytes.size() < 20)
    fail("{}: size {} is not SPIR-V", path.string(), bytes.size());
  std::vector<uint32_t> words(bytes.size() / 4);
  std::memcpy(words.data(), bytes.data(), bytes.size());
  if (words[0] != 0x07230203u) fail("{}: not SPIR-V (bad magic)", path.string());
  return words;
}

struct StageReflection {
  std::vector<ShaderBinding> bindings;
  uint32_t pushConstantBytes = 0;
};

StageReflection reflectStage(std::span<const uint32_t> spirv, const std::string& name,
                             SpvExecutionModel model) {
  spvc_context sc = nullptr;
  if (spvc_context_create(&sc) != SPVC_SUCCESS) fail("SPIRV-Cross: cannot create context");
  StageReflection out;
  try {
    spvc_parsed_ir ir = nullptr;
    spvc_compiler comp = nullptr;
    if (spvc_context_parse_spirv(sc, spirv.data(), spirv.size(), &ir) != SPVC_SUCCESS ||
        spvc_context_create_compiler(sc, SPVC_BACKEND_NONE, ir, SPVC_CAPTURE_MODE_TAKE_OWNERSHIP, &comp) !=
            SPVC_SUCCESS)
      fail("shader '{}': invalid SPIR-V ({})", name, spvc_context_get_last_error_string(sc));
    if (spvc_compiler_get_execution_model(comp) != model)
      fail("shader '{}': wrong stage (expected {})", name,
           model == SpvExecutionModelVertex ? "vertex" : "fragment");
    spvc_resources res = nullptr;
    if (spvc_compiler_create_shader_resources(comp, &res) != SPVC_SUCCESS)
      fail("shader '{}': reflection failed", name);
    for (auto [type, vkType] :
         {std::pair{SPVC_RESOURCE_TYPE_STORAGE_BUFFER, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
          std::pair{SPVC_RESOURCE_TYPE_UNIFORM_BUFFER, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER}}) {
      const spvc_reflected_resource* list = nullptr;
      size_t count = 0;
      spvc_resources_get_resource_list_for_type(res, type, &list, &count);
      for (size_t i = 0; i < count; ++i) {
        if (spvc_compiler_get_decoration(comp, list[i].id, SpvDecorationDescriptorSet) != 0)
          fail("shader '{}': resource '{}' is not in descriptor set 0", name, list[i].name);
        out.bindings.push_back({spvc_compiler_get_decoration(comp, list[i].id, SpvDecorationBinding), vkType,
                                list[i].name ? list[i].name : ""});
      }
    }
    for (spvc_resource_type unsupported :
         {SPVC_RESOURCE_TYPE_STORAGE_IMAGE, SPVC_RESOURCE_TYPE_SAMPLED_IMAGE,
          SPVC_RESOURCE_TYPE_SEPARATE_IMAGE, SPVC_RESOURCE_TYPE_SEPARATE_SAMPLERS}) {
      const spvc_reflected_resource* list = nullptr;
      size_t count = 0;
      spvc_resources_get_resource_list_for_type(res, unsupported, &list, &count);
      if (count > 0)
        fail("shader '{}': resource '{}' is not a buffer; only buffers are supported", name, list[0].name);
    }
    const spvc_reflected_resource* pc = nullptr;
    size_t pcCount = 0;
    spvc_resources_get_resource_list_for_type(res, SPVC_RESOURCE_TYPE_PUSH_CONSTANT, &pc, &pcCount);
    if (pcCount > 0) {
      size_t bytes = 0;
      if (spvc_compiler_get_declared_struct_size(
              comp, spvc_compiler_get_type_handle(comp, pc[0].base_type_id), &bytes) != SPVC_SUCCESS)
        fail("shader '{}': cannot size push constant block", name);
      out.pushConstantBytes = uint32_t(bytes);
    }
  } catch (...) {
    spvc_context_destroy(sc);
    throw;
  }
  spvc_context_destroy(sc);
  return out;
}

VkShaderModule createModule(VkDevice device, std::span<const uint32_t> words) {
  VkShaderModuleCreateInfo info{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  info.codeSize = words.size_bytes();
  info.pCode = words.data();
  VkShaderModule m = VK_NULL_HANDLE;
  check(vkCreateShaderModule(device, &info, nullptr, &m), "vkCreateShaderModule");
  return m;
}

// The push-descriptor set layout and the pipeline layout; each handle is written as it is created, so
// the caller's cleanup sees whatever exists when a later step throws.
void createLayouts(VkDevice device, const std::vector<ShaderBinding>& bindings, uint32_t pushConstantBytes,
                   VkShaderStageFlags stages, VkDescriptorSetLayout& setLayout, VkPipelineLayout& layout) {
  std::vector<VkDescriptorSetLayoutBinding> lb;
  for (const ShaderBinding& b : bindings) lb.push_back({b.binding, b.type, 1, stages, nullptr});
  VkDescriptorSetLayoutCreateInfo setInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  setInfo.flags = VK_DESCRIPTOR_SET_LAYOUT_CREATE_PUSH_DESCRIPTOR_BIT_KHR;
  setInfo.bindingCount = uint32_t(lb.size());
  setInfo.pBindings = lb.data();
  check(vkCreateDescriptorSetLayout(device, &setInfo, nullptr, &setLayout), "vkCreateDescriptorSetLayout");
  VkPushConstantRange range{stages, 0, pushConstantBytes};
  VkPipelineLayoutCreateInfo layoutInfo{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  layoutInfo.setLayoutCount = 1;
  layoutInfo.pSetLayouts = &setLayout;
  layoutInfo.pushConstantRangeCount = pushConstantBytes > 0 ? 1 : 0;
  layoutInfo.pPushConstantRanges = &range;
  check(vkCreatePipelineLayout(device, &layoutInfo, nullptr, &layout), "vkCreatePipelineLayout");
}

// The shader modules (left in vm and fm for the caller to destroy) and the graphics pipeline.
void createPipeline(VkDevice device, const GraphicsPipelineDesc& desc, const std::vector<uint32_t>& vs,
                    const std::vector<uint32_t>& fs, VkPipelineLayout layout, VkShaderModule& vm,
                    VkShaderModule& fm, VkPipeline& pipeline) {
  vm = createModule(device, vs);
  fm = createModule(device, fs);
  VkPipelineShaderStageCreateInfo st[2] = {{VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO},
                                           {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO}};
  st[0].stage = VK_SHADER_STAGE_VERTEX_BIT;
  st[0].module = vm;
  st[0].pName = "main";
  st[1].stage = VK_SHADER_STAGE_FRAGMENT_BIT;
  st[1].module = fm;
  st[1].pName = "main";
  VkPipelineVertexInputStateCreateInfo vertexInput{VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
  VkPipelineInputAssemblyStateCreateInfo assembly{
      VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
  assembly.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
  VkPipelineViewportStateCreateInfo viewport{VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO};
  viewport.viewportCount = 1;
  viewport.scissorCount = 1;
  VkPipelineRasterizationStateCreateInfo raster{VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO};
  raster.polygonMode = VK_POLYGON_MODE_FILL;
  raster.cullMode = VK_CULL_MODE_NONE;
  raster.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
  raster.lineWidth = 1.0f;
  VkPipelineMultisampleStateCreateInfo multisample{VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO};
  multisample.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
  VkPipelineDepthStencilStateCreateInfo depth{VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO};
  depth.depthTestEnable = desc.depthFormat != VK_FORMAT_UNDEFINED;
  depth.depthWriteEnable = depth.depthTestEnable;
  depth.depthCompareOp = desc.depthCompare;
  std::vector<VkPipelineColorBlendAttachmentState> blend(desc.colorFormats.size());
  for (auto& b : blend)
    b.colorWriteMask = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT | VK_COLOR_COMPONENT_B_BIT |
                       VK_COLOR_COMPONENT_A_BIT;
  VkPipelineColorBlendStateCreateInfo colorBlend{VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO};
  colorBlend.attachmentCount = uint32_t(blend.size());
  colorBlend.pAttachments = blend.data();
  const VkDynamicState dynamicStates[] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
  VkPipelineDynamicStateCreateInfo dynamic{VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO};
  dynamic.dynamicStateCount = 2;
  dynamic.pDynamicStates = dynamicStates;
  VkPipelineRenderingCreateInfo rendering{VK_STRUCTURE_TYPE_PIPELINE_RENDERING_CREATE_INFO};
  rendering.colorAttachmentCount = uint32_t(desc.colorFormats.size());
  rendering.pColorAttachmentFormats = desc.colorFormats.data();
  rendering.depthAttachmentFormat = desc.depthFormat;

  VkGraphicsPipelineCreateInfo info{VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO};
  info.pNext = &rendering;
  info.stageCount = 2;
  info.pStages = st;
  info.pVertexInputState = &vertexInput;
  info.pInputAssemblyState = &assembly;
  info.pViewportState = &viewport;
  info.pRasterizationState = &raster;
  info.pMultisampleState = &multisample;
  info.pDepthStencilState = &depth;
  info.pColorBlendState = &colorBlend;
  info.pDynamicState = &dynamic;
  info.layout = layout;
  check(vkCreateGraphicsPipelines(device, VK_NULL_HANDLE, 1, &info, nullptr, &pipeline),
        "vkCreateGraphicsPipelines");
}

}  // namespace

Image::Image(Context& ctx, uint32_t width, uint32_t height, VkFormat format, VkImageUsageFlags usage)
    : device_(ctx.device), format_(format), width_(width), height_(height) {
  const uint32_t maxDim = ctx.properties.limits.maxImageDimension2D;
  if (width == 0 || height == 0 || width > maxDim || height > maxDim)
    fail("image {}x{} outside [1, {}] (maxImageDimension2D of '{}')", width, height, maxDim, ctx.info.name);
  aspect_ = isDepthFormat(format) ? VK_IMAGE_ASPECT_DEPTH_BIT : VK_IMAGE_ASPECT_COLOR_BIT;
  VkImageFormatProperties props{};
  if (vkGetPhysicalDeviceImageFormatProperties(ctx.physicalDevice, format, VK_IMAGE_TYPE_2D,
                                               VK_IMAGE_TILING_OPTIMAL, usage, 0, &props) != VK_SUCCESS)
    fail("image format {} does not support usage 0x{:x} on '{}'", int(format), usage, ctx.info.name);
  try {
    VkImageCreateInfo info{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
    info.imageType = VK_IMAGE_TYPE_2D;
    info.format = format;
    info.extent = {width, height, 1};
    info.mipLevels = 1;
    info.arrayLayers = 1;
    info.samples = VK_SAMPLE_COUNT_1_BIT;
    info.tiling = VK_IMAGE_TILING_OPTIMAL;
    info.usage = usage;
    info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    info.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    check(vkCreateImage(device_, &info, nullptr, &image_), "vkCreateImage");
    VkMemoryRequirements req;
    vkGetImageMemoryRequirements(device_, image_, &req);
    VkMemoryAllocateInfo alloc{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    alloc.allocationSize = req.size;
    alloc.memoryTypeIndex = deviceLocalMemoryType(ctx, req.memoryTypeBits);
    check(vkAllocateMemory(device_, &alloc, nullptr, &memory_), "vkAllocateMemory (image)");
    check(vkBindImageMemory(device_, image_, memory_, 0), "vkBindImageMemory");
    VkImageViewCreateInfo view{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
    view.image = image_;
    view.viewType = VK_IMAGE_VIEW_TYPE_2D;
    view.format = format;
    view.subresourceRange = {aspect_, 0, 1, 0, 1};
    check(vkCreateImageView(device_, &view, nullptr, &view_), "vkCreateImageView");
  } catch (...) {
    release();
    throw;
  }
}

Image::Image(Image&& o) noexcept
    : device_(std::exchange(o.device_, VK_NULL_HANDLE)),
      image_(std::exchange(o.image_, VK_NULL_HANDLE)),
      memory_(std::exchange(o.memory_, VK_NULL_HANDLE)),
      view_(std::exchange(o.view_, VK_NULL_HANDLE)),
      format_(o.format_),
      aspect_(o.aspect_),
      width_(o.width_),
      height_(o.height_) {}

Image& Image::operator=(Image&& o) noexcept {
  if (this != &o) {
    release();
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    image_ = std::exchange(o.image_, VK_NULL_HANDLE);
    memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
    view_ = std::exchange(o.view_, VK_NULL_HANDLE);
    format_ = o.format_;
    aspect_ = o.aspect_;
    width_ = o.width_;
    height_ = o.height_;
  }
  return *this;
}

Image::~Image() {
  release();
}

void Image::release() {
  if (!device_) return;
  if (view_) vkDestroyImageView(device_, view_, nullptr);
  if (image_) vkDestroyImage(device_, image_, nullptr);
  if (memory_) vkFreeMemory(device_, memory_, nullptr);
  view_ = VK_NULL_HANDLE;
  image_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
  device_ = VK_NULL_HANDLE;
}

void imageBarrier(VkCommandBuffer cmd, const Image& image, VkImageLayout from, VkImageLayout to,
                  VkPipelineStageFlags srcStage, VkAccessFlags srcAccess, VkPipelineStageFlags dstStage,
                  VkAccessFlags dstAccess) {
  VkImageMemoryBarrier b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
  b.srcAccessMask = srcAccess;
  b.dstAccessMask = dstAccess;
  b.oldLayout = from;
  b.newLayout = to;
  b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.image = image.handle();
  b.subresourceRange = {image.aspect(), 0, 1, 0, 1};
  vkCmdPipelineBarrier(cmd, srcStage, dstStage, 0, 0, nullptr, 0, nullptr, 1, &b);
}

GraphicsProgram::GraphicsProgram(Context& ctx, const GraphicsPipelineDesc& desc)
    : device_(ctx.device), name_(desc.vertexShader + "+" + desc.fragmentShader) {
  if (!ctx.features.dynamicRendering)
    fail("{}: device '{}' lacks dynamicRendering (mandatory in Vulkan 1.3)", name_, ctx.info.name);
  const std::vector<uint32_t> vs = loadSpirv(desc.vertexShader), fs = loadSpirv(desc.fragmentShader);
  const StageReflection rv = reflectStage(vs, desc.vertexShader, SpvExecutionModelVertex);
  const StageReflection rf = reflectStage(fs, desc.fragmentShader, SpvExecutionModelFragment);
  bindings_ = rv.bindings;
  for (const ShaderBinding& b : rf.bindings) {
    auto same = std::find_if(bindings_.begin(), bindings_.end(),
                             [&](const ShaderBinding& x) { return x.binding == b.binding; });
    if (same == bindings_.end())
      bindings_.push_back(b);
    else if (same->type != b.type)
      fail("{}: binding {} has different types in the two stages", name_, b.binding);
  }
  std::sort(bindings_.begin(), bindings_.end(),
            [](const ShaderBinding& a, const ShaderBinding& b) { return a.binding < b.binding; });
  for (size_t i = 0; i < bindings_.size(); ++i)
    if (bindings_[i].binding != i)
      fail("{}: bindings must be dense 0..{} across both stages", name_, bindings_.size() - 1);
  if (rv.pushConstantBytes && rf.pushConstantBytes && rv.pushConstantBytes != rf.pushConstantBytes)
    fail("{}: push-constant blocks differ ({} vs {} bytes)", name_, rv.pushConstantBytes,
         rf.pushConstantBytes);
  pushConstantBytes_ = std::max(rv.pushConstantBytes, rf.pushConstantBytes);
  if (pushConstantBytes_ > ctx.properties.limits.maxPushConstantsSize)
    fail("{}: {} push-constant bytes exceed the device limit", name_, pushConstantBytes_);

  const VkShaderStageFlags stages = VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT;
  VkShaderModule vm = VK_NULL_HANDLE, fm = VK_NULL_HANDLE;
  auto cleanup = [&] {
    if (vm) vkDestroyShaderModule(device_, vm, nullptr);
    if (fm) vkDestroyShaderModule(device_, fm, nullptr);
  };
  try {
    createLayouts(device_, bindings_, pushConstantBytes_, stages, setLayout_, layout_);
    createPipeline(device_, desc, vs, fs, layout_, vm, fm, pipeline_);
  } catch (...) {
    cleanup();
    if (layout_) vkDestroyPipelineLayout(device_, layout_, nullptr);
    if (setLayout_) vkDestroyDescriptorSetLayout(device_, setLayout_, nullptr);
    throw;
  }
  cleanup();
}

GraphicsProgram::~GraphicsProgram() {
  if (pipeline_) vkDestroyPipeline(device_, pipeline_, nullptr);
  if (layout_) vkDestroyPipelineLayout(device_, layout_, nullptr);
  if (setLayout_) vkDestroyDescriptorSetLayout(device_, setLayout_, nullptr);
}

void bindGraphics(Context& ctx, VkCommandBuffer cmd, const GraphicsProgram& program,
                  std::initializer_list<const Buffer*> buffers) {
  if (buffers.size() != program.bindings().size())
    fail("bindGraphics '{}': {} buffers given, shaders declare {}", program.name(), buffers.size(),
         program.bindings().size());
  std::vector<VkDescriptorBufferInfo> infos;
  infos.reserve(buffers.size());
  for (const Buffer* b : buffers) {
    if (b == nullptr || b->handle() == VK_NULL_HANDLE) fail("bindGraphics '{}': null buffer", program.name());
    infos.push_back({b->handle(), 0, VK_WHOLE_SIZE});
  }
  std::vector<VkWriteDescriptorSet> writes;
  for (size_t i = 0; i < infos.size(); ++i) {
    VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    w.dstBinding = program.bindings()[i].binding;
    w.descriptorCount = 1;
    w.descriptorType = program.bindings()[i].type;
    w.pBufferInfo = &infos[i];
    writes.push_back(w);
  }
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, program.pipeline());
  if (!writes.empty())
    ctx.cmdPushDescriptorSet(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, program.layout(), 0,
                             uint32_t(writes.size()), writes.data());
}

void pushGraphicsConstants(VkCommandBuffer cmd, const GraphicsProgram& program,
                           std::span<const std::byte> bytes) {
  if (bytes.size() != program.pushConstantBytes())
    fail("pushGraphicsConstants '{}': {} bytes given, shaders declare {}", program.name(), bytes.size(),
         program.pushConstantBytes());
  vkCmdPushConstants(cmd, program.layout(), VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0,
                     uint32_t(bytes.size()), bytes.data());
}

}  // namespace lfgi::gpu
