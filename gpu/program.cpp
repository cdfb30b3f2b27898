#include "gpu/program.h"

#include <dlfcn.h>
#include <spirv_cross/spirv_cross_c.h>
#include <unistd.h>

#include <algorithm>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <utility>

#include "core/error.h"
#include "core/file_util.h"

namespace lfgi::gpu {
namespace {

// RAII for the SPIRV-Cross C context (owns every object created from it).
struct SpvcContext {
  spvc_context ctx = nullptr;
  SpvcContext() {
    if (spvc_context_create(&ctx) != SPVC_SUCCESS) fail("SPIRV-Cross: cannot create context");
  }
  ~SpvcContext() { spvc_context_destroy(ctx); }
  SpvcContext(const SpvcContext&) = delete;
  SpvcContext& operator=(const SpvcContext&) = delete;
};

void addResources(spvc_compiler comp, spvc_resources res, spvc_resource_type type, VkDescriptorType vkType,
                  const std::string& name, ShaderReflection& out) {
  const spvc_reflected_resource* list = nullptr;
  size_t count = 0;
  spvc_resources_get_resource_list_for_type(res, type, &list, &count);
  for (size_t i = 0; i < count; ++i) {
    unsigned set = spvc_compiler_get_decoration(comp, list[i].id, SpvDecorationDescriptorSet);
    unsigned binding = spvc_compiler_get_decoration(comp, list[i].id, SpvDecorationBinding);
    if (set != 0)
      fail("shader '{}': resource '{}' uses descriptor set {}; lfgi binds set 0 only", name, list[i].name,
           set);
    out.bindings.push_back({binding, vkType, list[i].name ? list[i].name : ""});
  }
}

}  // namespace

ShaderReflection reflectComputeShader(std::span<const uint32_t> spirv, const std::string& name) {
  if (spirv.size() < 5 || spirv[0] != 0x07230203u)
    fail("shader '{}': not SPIR-V (bad magic or too short)", name);
  SpvcContext sc;
  spvc_parsed_ir ir = nullptr;
  spvc_compiler comp = nullptr;
  if (spvc_context_parse_spirv(sc.ctx, spirv.data(), spirv.size(), &ir) != SPVC_SUCCESS ||
      spvc_context_create_compiler(sc.ctx, SPVC_BACKEND_NONE, ir, SPVC_CAPTURE_MODE_TAKE_OWNERSHIP, &comp) !=
          SPVC_SUCCESS)
    fail("shader '{}': invalid SPIR-V ({})", name, spvc_context_get_last_error_string(sc.ctx));
  if (spvc_compiler_get_execution_model(comp) != SpvExecutionModelGLCompute)
    fail("shader '{}': not a compute shader", name);

  ShaderReflection out;
  for (unsigned i = 0; i < 3; ++i)
    out.localSize[i] = spvc_compiler_get_execution_mode_argument_by_index(comp, SpvExecutionModeLocalSize, i);
  if (out.localSize[0] * out.localSize[1] * out.localSize[2] == 0)
    fail("shader '{}': local size not found (specialisation-constant sizes are not supported)", name);

  spvc_resources res = nullptr;
  if (spvc_compiler_create_shader_resources(comp, &res) != SPVC_SUCCESS)
    fail("shader '{}': reflection failed ({})", name, spvc_context_get_last_error_string(sc.ctx));
  addResources(comp, res, SPVC_RESOURCE_TYPE_STORAGE_BUFFER, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, name, out);
  addResources(comp, res, SPVC_RESOURCE_TYPE_UNIFORM_BUFFER, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, name, out);
  for (spvc_resource_type unsupported :
       {SPVC_RESOURCE_TYPE_STORAGE_IMAGE, SPVC_RESOURCE_TYPE_SAMPLED_IMAGE, SPVC_RESOURCE_TYPE_SEPARATE_IMAGE,
        SPVC_RESOURCE_TYPE_SEPARATE_SAMPLERS, SPVC_RESOURCE_TYPE_ACCELERATION_STRUCTURE}) {
    const spvc_reflected_resource* list = nullptr;
    size_t count = 0;
    spvc_resources_get_resource_list_for_type(res, unsupported, &list, &count);
    if (count > 0)
      fail("shader '{}': resource '{}' is not a buffer; only buffers are supported", name, list[0].name);
  }
  std::sort(out.bindings.begin(), out.bindings.end(),
            [](const ShaderBinding& a, const ShaderBinding& b) { return a.binding < b.binding; });
  for (size_t i = 0; i < out.bindings.size(); ++i)
    if (out.bindings[i].binding != i)
      fail("shader '{}': bindings must be dense 0..{} (found binding {} at position {})", name,
           out.bindings.size() - 1, out.bindings[i].binding, i);

  const spvc_reflected_resource* pc = nullptr;
  size_t pcCount = 0;
  spvc_resources_get_resource_list_for_type(res, SPVC_RESOURCE_TYPE_PUSH_CONSTANT, &pc, &pcCount);
  if (pcCount > 0) {
    size_t bytes = 0;
    spvc_type type = spvc_compiler_get_type_handle(comp, pc[0].base_type_id);
    if (spvc_compiler_get_declared_struct_size(comp, type, &bytes) != SPVC_SUCCESS)
      fail("shader '{}': cannot size push constant block", name);
    out.pushConstantBytes = static_cast<uint32_t>(bytes);
  }
  return out;
}

std::filesystem::path shaderDirectory() {
  if (const char* env = std::getenv("LFGI_SHADER_DIR"); env && *env) return env;
  char buf[PATH_MAX];
  ssize_t n = ::readlink("/proc/self/exe", buf, sizeof(buf) - 1);
  if (n <= 0) fail("cannot locate the running executable to find shaders; set LFGI_SHADER_DIR");
  std::filesystem::path exeDir =
      std::filesystem::path(std::string(buf, static_cast<size_t>(n))).parent_path();
  for (const auto& candidate : {exeDir.parent_path() / "shaders", exeDir / "shaders"})
    if (std::filesystem::is_directory(candidate)) return candidate;
  // Embedded (the installed lfgi::runtime library): PREFIX/lib/liblfgi_runtime.so ->
  // PREFIX/share/lfgi/shaders.
  Dl_info self{};
  if (::dladdr(reinterpret_cast<void*>(&shaderDirectory), &self) != 0 && self.dli_fname) {
    const std::filesystem::path libDir = std::filesystem::path(self.dli_fname).parent_path();
    const std::filesystem::path installed = libDir.parent_path() / "share" / "lfgi" / "shaders";
    if (std::filesystem::is_directory(installed)) return installed;
  }
  fail(
      "no compiled shaders next to {} (looked in ../shaders and ./shaders, and share/lfgi/shaders beside the "
      "library); build the lfgi_shaders target or set LFGI_SHADER_DIR",
      exeDir.string());
}

Program::Program(Context& ctx, const std::string& name) : device_(ctx.device), name_(name) {
  std::filesystem::path path = shaderDirectory() / (name + ".spv");
  std::vector<std::byte> bytes = readFileBytes(path);
  if (bytes.size() % 4 != 0)
    fail("{}: size {} is not a multiple of 4; not SPIR-V", path.string(), bytes.size());
  std::vector<uint32_t> words(bytes.size() / 4);
  std::memcpy(words.data(), bytes.data(), bytes.size());
  reflection_ = reflectComputeShader(words, path.string());

  const VkPhysicalDeviceLimits& lim = ctx.properties.limits;
  const uint32_t* ls = reflection_.localSize;
  if (ls[0] > lim.maxComputeWorkGroupSize[0] || ls[1] > lim.maxComputeWorkGroupSize[1] ||
      ls[2] > lim.maxComputeWorkGroupSize[2] || ls[0] * ls[1] * ls[2] > lim.maxComputeWorkGroupInvocations)
    fail("{}: workgroup {}x{}x{} exceeds the limits of '{}'", path.string(), ls[0], ls[1], ls[2],
         ctx.info.name);
  if (reflection_.pushConstantBytes > lim.maxPushConstantsSize)
    fail("{}: {} push-constant bytes exceed the device limit {}", path.string(),
         reflection_.pushConstantBytes, lim.maxPushConstantsSize);

  try {
    std::vector<VkDescriptorSetLayoutBinding> bindings;
    for (const ShaderBinding& b : reflection_.bindings)
      bindings.push_back({b.binding, b.type, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
    VkDescriptorSetLayoutCreateInfo setInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    setInfo.flags = VK_DESCRIPTOR_SET_LAYOUT_CREATE_PUSH_DESCRIPTOR_BIT_KHR;
    setInfo.bindingCount = static_cast<uint32_t>(bindings.size());
    setInfo.pBindings = bindings.data();
    check(vkCreateDescriptorSetLayout(device_, &setInfo, nullptr, &setLayout_),
          "vkCreateDescriptorSetLayout");

    VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, reflection_.pushConstantBytes};
    VkPipelineLayoutCreateInfo layoutInfo{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    layoutInfo.setLayoutCount = 1;
    layoutInfo.pSetLayouts = &setLayout_;
    layoutInfo.pushConstantRangeCount = reflection_.pushConstantBytes > 0 ? 1 : 0;
    layoutInfo.pPushConstantRanges = &range;
    check(vkCreatePipelineLayout(device_, &layoutInfo, nullptr, &layout_), "vkCreatePipelineLayout");

    VkShaderModuleCreateInfo moduleInfo{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
    moduleInfo.codeSize = bytes.size();
    moduleInfo.pCode = words.data();
    VkShaderModule module = VK_NULL_HANDLE;
    check(vkCreateShaderModule(device_, &moduleInfo, nullptr, &module), "vkCreateShaderModule");

    VkComputePipelineCreateInfo pipeInfo{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    pipeInfo.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    pipeInfo.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    pipeInfo.stage.module = module;
    pipeInfo.stage.pName = "main";
    pipeInfo.layout = layout_;
    VkResult r = vkCreateComputePipelines(device_, VK_NULL_HANDLE, 1, &pipeInfo, nullptr, &pipeline_);
    vkDestroyShaderModule(device_, module, nullptr);
    check(r, "vkCreateComputePipelines");
  } catch (...) {
    release();
    throw;
  }
}

Program::Program(Program&& o) noexcept
    : device_(std::exchange(o.device_, VK_NULL_HANDLE)),
      name_(std::move(o.name_)),
      reflection_(std::move(o.reflection_)),
      setLayout_(std::exchange(o.setLayout_, VK_NULL_HANDLE)),
      layout_(std::exchange(o.layout_, VK_NULL_HANDLE)),
      pipeline_(std::exchange(o.pipeline_, VK_NULL_HANDLE)) {}

Program::~Program() {
  release();
}

void Program::release() {
  if (!device_) return;
  if (pipeline_) vkDestroyPipeline(device_, pipeline_, nullptr);
  if (layout_) vkDestroyPipelineLayout(device_, layout_, nullptr);
  if (setLayout_) vkDestroyDescriptorSetLayout(device_, setLayout_, nullptr);
  pipeline_ = VK_NULL_HANDLE;
  layout_ = VK_NULL_HANDLE;
  setLayout_ = VK_NULL_HANDLE;
  device_ = VK_NULL_HANDLE;
}

void dispatch(Context& ctx, VkCommandBuffer cmd, const Program& program,
              std::initializer_list<const Buffer*> buffers, std::span<const std::byte> pushConstants,
              DispatchSize threads) {
  const ShaderReflection& refl = program.reflection();
  if (buffers.size() != refl.bindings.size())
    fail("dispatch '{}': {} buffers given, shader declares {}", program.name(), buffers.size(),
         refl.bindings.size());
  if (pushConstants.size() != refl.pushConstantBytes)
    fail("dispatch '{}': {} push-constant bytes given, shader declares {}", program.name(),
         pushConstants.size(), refl.pushConstantBytes);

  std::vector<VkDescriptorBufferInfo> infos;
  std::vector<VkWriteDescriptorSet> writes;
  infos.reserve(buffers.size());
  for (const Buffer* b : buffers) {
    if (b == nullptr || b->handle() == VK_NULL_HANDLE) fail("dispatch '{}': null buffer", program.name());
    infos.push_back({b->handle(), 0, VK_WHOLE_SIZE});
  }
  for (size_t i = 0; i < infos.size(); ++i) {
    VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    w.dstBinding = refl.bindings[i].binding;
    w.descriptorCount = 1;
    w.descriptorType = refl.bindings[i].type;
    w.pBufferInfo = &infos[i];
    writes.push_back(w);
  }
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, program.pipeline());
  if (!writes.empty())
    ctx.cmdPushDescriptorSet(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, program.layout(), 0,
                             static_cast<uint32_t>(writes.size()), writes.data());
  if (!pushConstants.empty())
    vkCmdPushConstants(cmd, program.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                       static_cast<uint32_t>(pushConstants.size()), pushConstants.data());
  auto groups = [](uint32_t n, uint32_t local) { return (n + local - 1) / local; };
  vkCmdDispatch(cmd, groups(threads.x, refl.localSize[0]), groups(threads.y, refl.localSize[1]),
                groups(threads.z, refl.localSize[2]));
}

}  // namespace lfgi::gpu
