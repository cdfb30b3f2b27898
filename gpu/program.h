// Compute programs: SPIR-V loaded from the build tree, layout and workgroup size from SPIR-V reflection
// (SPIRV-Cross), so a shader edit cannot silently disagree with the C++ that binds it: dispatch() checks
// the number of buffers and the push-constant size against the reflected layout.
//
// Descriptors: set 0 only, storage/uniform buffers only, bound with VK_KHR_push_descriptor (no pools).
#pragma once

#include <vulkan/vulkan.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <span>
#include <string>
#include <vector>

#include "gpu/buffer.h"
#include "gpu/context.h"

namespace lfgi::gpu {

struct ShaderBinding {
  uint32_t binding = 0;
  VkDescriptorType type = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  std::string name;
};

struct ShaderReflection {
  uint32_t localSize[3] = {1, 1, 1};
  std::vector<ShaderBinding> bindings;  // set 0, sorted by binding; bindings are dense 0..n-1
  uint32_t pushConstantBytes = 0;
};

// Reflects a compute shader. Throws lfgi::Error naming `name` if the SPIR-V is invalid, is not a compute
// shader, uses a descriptor set other than 0, non-dense bindings, or resource types other than buffers.
ShaderReflection reflectComputeShader(std::span<const uint32_t> spirv, const std::string& name);

// Where compiled shaders are found: $LFGI_SHADER_DIR if set, else "<dir of this executable>/../shaders"
// (the build tree layout build/bin + build/shaders), else "<dir of this executable>/shaders".
std::filesystem::path shaderDirectory();

class Program {
 public:
  // Loads <shaderDirectory()>/<name>.spv. Throws lfgi::Error naming the path if missing or invalid, or if
  // the workgroup size exceeds the device limits.
  Program(Context& ctx, const std::string& name);
  Program(Program&&) noexcept;
  Program& operator=(Program&&) = delete;
  Program(const Program&) = delete;
  Program& operator=(const Program&) = delete;
  ~Program();

  const std::string& name() const { return name_; }
  const ShaderReflection& reflection() const { return reflection_; }
  VkPipeline pipeline() const { return pipeline_; }
  VkPipelineLayout layout() const { return layout_; }

 private:
  void release();
  VkDevice device_ = VK_NULL_HANDLE;
  std::string name_;
  ShaderReflection reflection_;
  VkDescriptorSetLayout setLayout_ = VK_NULL_HANDLE;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
};

struct DispatchSize {
  uint32_t x = 1, y = 1, z = 1;
};

// Binds program and buffers (in binding order 0..n-1), pushes constants and dispatches enough workgroups
// to cover `threads` invocations (rounding up by the reflected local size). Throws lfgi::Error if the
// buffer count or push-constant size differs from the shader's.
void dispatch(Context& ctx, VkCommandBuffer cmd, const Program& program,
              std::initializer_list<const Buffer*> buffers, std::span<const std::byte> pushConstants,
              DispatchSize threads);

template <typename Params>
void dispatch(Context& ctx, VkCommandBuffer cmd, const Program& program,
              std::initializer_list<const Buffer*> buffers, const Params& params, DispatchSize threads) {
  dispatch(ctx, cmd, program, buffers, std::as_bytes(std::span(&params, 1)), threads);
}

}  // namespace lfgi::gpu
