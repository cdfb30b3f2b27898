// A host engine with lfgi embedded (docs/embedding.md). It creates its own headless Vulkan device, opens a
// baked world, flies a scripted camera for N frames (update() + upload() each frame, the shading recorded
// into its own command buffer every 30th), then settles at the view and writes OUT.png (tone-mapped
// indirect diffuse) and OUT.pfm (its linear RGB). Also samples GI on the CPU on a ground grid.
// Exit 0 when every surface pixel of the view is lit and no grid point lacks light, 1 when one does or on an
// error, 2 for bad usage.
//   lfgi_example_host WORLD OUT [--frames N] [--size WxH] [--time HOURS] [--camera px,py,pz,tx,ty,tz]
// Only lfgi's headers, Vulkan and the standard library: the PNG is written uncompressed (stored deflate).
#include <lfgi/runtime.h>
#include <lfgi/runtime_vulkan.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

// ---- a minimal PNG writer (RGB8, zlib stored blocks) -----------------------------------------------------

uint32_t crc32(const uint8_t* p, size_t n, uint32_t crc = 0) {
  crc = ~crc;
  for (size_t i = 0; i < n; ++i) {
    crc ^= p[i];
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

void put32(std::vector<uint8_t>& v, uint32_t x) {
  for (int s = 24; s >= 0; s -= 8) v.push_back(uint8_t(x >> s));
}

void chunk(std::vector<uint8_t>& png, const char* type, const std::vector<uint8_t>& data) {
  put32(png, uint32_t(data.size()));
  std::vector<uint8_t> body(type, type + 4);
  body.insert(body.end(), data.begin(), data.end());
  png.insert(png.end(), body.begin(), body.end());
  put32(png, crc32(body.data(), body.size()));
}

bool writePng(const std::string& path, int w, int h, const std::vector<uint8_t>& rgb) {
  std::vector<uint8_t> raw;  // filter byte 0 per row
  for (int y = 0; y < h; ++y) {
    raw.push_back(0);
    raw.insert(raw.end(), rgb.begin() + size_t(y) * size_t(w) * 3,
               rgb.begin() + size_t(y + 1) * size_t(w) * 3);
  }
  std::vector<uint8_t> z = {0x78, 0x01};
  uint32_t a = 1, b = 0;
  for (uint8_t c : raw) a = (a + c) % 65521u, b = (b + a) % 65521u;
  size_t off = 0;
  do {  // stored (uncompressed) deflate blocks of at most 65535 bytes
    const size_t n = std::min<size_t>(65535, raw.size() - off);
    z.push_back(off + n == raw.size() ? 1 : 0);
    z.insert(z.end(), {uint8_t(n), uint8_t(n >> 8), uint8_t(~n), uint8_t(~n >> 8)});
    z.insert(z.end(), raw.begin() + std::ptrdiff_t(off), raw.begin() + std::ptrdiff_t(off + n));
    off += n;
  } while (off < raw.size());
  put32(z, (b << 16) | a);
  std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'}, ihdr;
  put32(ihdr, uint32_t(w)), put32(ihdr, uint32_t(h));
  ihdr.insert(ihdr.end(), {8, 2, 0, 0, 0});  // 8-bit RGB
  chunk(png, "IHDR", ihdr);
  chunk(png, "IDAT", z);
  chunk(png, "IEND", {});
  const std::string tmp = path + ".tmp";
  std::ofstream f(tmp, std::ios::binary);
  f.write(reinterpret_cast<const char*>(png.data()), std::streamsize(png.size()));
  f.close();
  return f && std::rename(tmp.c_str(), path.c_str()) == 0;
}

uint8_t toByte(float linear) {
  const float tone = linear / (1.0f + linear);  // Reinhard, then display gamma
  return uint8_t(std::lround(255.0f * std::pow(std::clamp(tone, 0.0f, 1.0f), 1.0f / 2.2f)));
}

// ---- the host's own Vulkan device ---------------------------------------------------------------------

void vk(VkResult r, const char* what) {
  if (r != VK_SUCCESS)
    throw std::runtime_error(std::string(what) + " failed (VkResult " + std::to_string(r) + ")");
}

struct HostVulkan {
  VkInstance instance = VK_NULL_HANDLE;
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  uint32_t family = 0;
  VkCommandPool pool = VK_NULL_HANDLE;
  VkPhysicalDeviceMemoryProperties memory{};
  std::mutex queueMutex;  // lfgi's IO threads submit on `queue` too (VulkanDevice::queueMutex)

  HostVulkan() {
    VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    app.pApplicationName = "lfgi_example_host";
    app.apiVersion = VK_API_VERSION_1_3;
    VkInstanceCreateInfo ii{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    ii.pApplicationInfo = &app;
    vk(vkCreateInstance(&ii, nullptr, &instance), "vkCreateInstance");
    uint32_t n = 0;
    vkEnumeratePhysicalDevices(instance, &n, nullptr);
    std::vector<VkPhysicalDevice> devices(n);
    vkEnumeratePhysicalDevices(instance, &n, devices.data());
    for (VkPhysicalDevice d : devices) {  // the first Vulkan 1.3 device with a compute queue
      VkPhysicalDeviceProperties p;
      vkGetPhysicalDeviceProperties(d, &p);
      uint32_t nf = 0;
      vkGetPhysicalDeviceQueueFamilyProperties(d, &nf, nullptr);
      std::vector<VkQueueFamilyProperties> fams(nf);
      vkGetPhysicalDeviceQueueFamilyProperties(d, &nf, fams.data());
      for (uint32_t f = 0; f < nf && !physical; ++f)
        if (p.apiVersion >= VK_API_VERSION_1_3 && (fams[f].queueFlags & VK_QUEUE_COMPUTE_BIT))
          physical = d, family = f;
    }
    if (!physical) throw std::runtime_error("no Vulkan 1.3 device with a compute queue");
    vkGetPhysicalDeviceMemoryProperties(physical, &memory);
    // What lfgi's contract asks of the device: push descriptors and maintenance4, and for its VIR
    // visibility 64-bit integers and atomics.
    VkPhysicalDeviceVulkan13Features f13{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES};
    f13.maintenance4 = VK_TRUE;
    VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
    f12.pNext = &f13;
    f12.shaderBufferInt64Atomics = VK_TRUE;
    VkPhysicalDeviceFeatures2 f2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
    f2.pNext = &f12;
    f2.features.shaderInt64 = VK_TRUE;
    const float priority = 1.0f;
    VkDeviceQueueCreateInfo qi{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    qi.queueFamilyIndex = family;
    qi.queueCount = 1;
    qi.pQueuePriorities = &priority;
    const char* extensions[] = {VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME};
    VkDeviceCreateInfo di{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    di.pNext = &f2;
    di.queueCreateInfoCount = 1;
    di.pQueueCreateInfos = &qi;
    di.enabledExtensionCount = 1;
    di.ppEnabledExtensionNames = extensions;
    vk(vkCreateDevice(physical, &di, nullptr, &device), "vkCreateDevice");
    vkGetDeviceQueue(device, family, 0, &queue);
    VkCommandPoolCreateInfo pi{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pi.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    pi.queueFamilyIndex = family;
    vk(vkCreateCommandPool(device, &pi, nullptr, &pool), "vkCreateCommandPool");
  }
  ~HostVulkan() {
    vkDestroyCommandPool(device, pool, nullptr);
    vkDestroyDevice(device, nullptr);
    vkDestroyInstance(instance, nullptr);
  }
  lfgi::VulkanDevice forLfgi() {
    return {instance, physical, device, queue, family, true, true, true, true, &queueMutex};
  }
};

// A host-visible storage buffer (the example reads the output back by mapping).
struct HostBuffer {
  const HostVulkan& vkh;
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  void* mapped = nullptr;
  HostBuffer(const HostVulkan& v, VkDeviceSize size) : vkh(v) {
    VkBufferCreateInfo bi{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    bi.size = size;
    bi.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    vk(vkCreateBuffer(v.device, &bi, nullptr, &buffer), "vkCreateBuffer");
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(v.device, buffer, &req);
    const VkMemoryPropertyFlags want =
        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    uint32_t type = UINT32_MAX;
    for (uint32_t t = 0; t < v.memory.memoryTypeCount && type == UINT32_MAX; ++t)
      if ((req.memoryTypeBits & (1u << t)) && (v.memory.memoryTypes[t].propertyFlags & want) == want)
        type = t;
    if (type == UINT32_MAX) throw std::runtime_error("no host-visible memory type");
    VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    ai.allocationSize = req.size;
    ai.memoryTypeIndex = type;
    vk(vkAllocateMemory(v.device, &ai, nullptr, &memory), "vkAllocateMemory");
    vk(vkBindBufferMemory(v.device, buffer, memory, 0), "vkBindBufferMemory");
    vk(vkMapMemory(v.device, memory, 0, VK_WHOLE_SIZE, 0, &mapped), "vkMapMemory");
  }
  ~HostBuffer() {
    vkDestroyBuffer(vkh.device, buffer, nullptr);
    vkFreeMemory(vkh.device, memory, nullptr);
  }
};

// ---- the frame loop ---------------------------------------------------------------------------------------

struct Options {
  std::string world, out;
  int frames = 300, width = 160, height = 96;
  float time = 12.0f;
  lfgi::View view;
};

bool parse(int argc, char** argv, Options& o) {
  if (argc < 3) return false;
  o.world = argv[1], o.out = argv[2];
  o.view = {{64.0f, 30.0f, 10.0f}, {64.0f, 0.0f, 70.0f}, 60.0f};
  for (int i = 3; i + 1 < argc; i += 2) {
    const std::string k = argv[i], v = argv[i + 1];
    float* p = o.view.position;
    float* t = o.view.target;
    if (k == "--frames")
      o.frames = std::atoi(v.c_str());
    else if (k == "--time")
      o.time = float(std::atof(v.c_str()));
    else if (k == "--size" && std::sscanf(v.c_str(), "%dx%d", &o.width, &o.height) == 2)
      continue;
    else if (k == "--camera" &&
             std::sscanf(v.c_str(), "%f,%f,%f,%f,%f,%f", &p[0], &p[1], &p[2], &t[0], &t[1], &t[2]) == 6)
      continue;
    else
      return false;
  }
  return (argc % 2) == 1 && o.frames >= 0 && o.width > 0 && o.height > 0;
}

// Frame i of the scripted flight: a circle at 40 % of the world's half size around its centre, 30 m up.
lfgi::Frame flight(const lfgi::Runtime& rt, int i, float dt, float hours) {
  const float cx = 0.5f * rt.worldSizeX(), cz = 0.5f * rt.worldSizeZ(), r = 0.4f * std::min(cx, cz);
  const float t = float(i) * dt, w = 0.2f;  // rad/s
  lfgi::Frame f;
  f.position[0] = cx + r * std::cos(w * t), f.position[1] = 30.0f, f.position[2] = cz + r * std::sin(w * t);
  f.velocity[0] = -r * w * std::sin(w * t), f.velocity[2] = r * w * std::cos(w * t);
  const float speed = std::max(1e-6f, r * w);
  f.direction[0] = f.velocity[0] / speed, f.direction[2] = f.velocity[2] / speed;
  f.timeOfDayHours = hours;
  f.dtSeconds = dt;
  return f;
}

// Records the G-buffer (the world's own geometry, lfgi's tool pass) and lfgi's shading into the host's
// command buffer, submits it on the host's queue and waits.
void shadeView(HostVulkan& v, lfgi::VulkanShading& shading, const lfgi::ShadeTarget& target,
               const lfgi::View& view) {
  VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  ai.commandPool = v.pool;
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VkCommandBuffer cmd;
  vk(vkAllocateCommandBuffers(v.device, &ai, &cmd), "vkAllocateCommandBuffers");
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  vk(vkBeginCommandBuffer(cmd, &bi), "vkBeginCommandBuffer");
  shading.recordWorldGBuffer(cmd, target, view);
  shading.record(cmd, target, view);
  VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  mb.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
  mb.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &mb, 0,
                       nullptr, 0, nullptr);
  vk(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  VkFenceCreateInfo fi{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  VkFence fence;
  vk(vkCreateFence(v.device, &fi, nullptr, &fence), "vkCreateFence");
  {
    const std::lock_guard lock(v.queueMutex);
    vk(vkQueueSubmit(v.queue, 1, &si, fence), "vkQueueSubmit");
  }
  vk(vkWaitForFences(v.device, 1, &fence, VK_TRUE, UINT64_MAX), "vkWaitForFences");
  vkDestroyFence(v.device, fence, nullptr);
  vkFreeCommandBuffers(v.device, v.pool, 1, &cmd);
}

bool writePfm(const std::string& path, int w, int h, const float* rgba) {
  std::string data = "PF\n" + std::to_string(w) + " " + std::to_string(h) + "\n-1.0\n";
  for (int y = h - 1; y >= 0; --y)  // PFM rows run bottom to top
    for (int x = 0; x < w; ++x)
      data.append(reinterpret_cast<const char*>(rgba + (size_t(y) * size_t(w) + size_t(x)) * 4), 12);
  const std::string tmp = path + ".tmp";
  std::ofstream f(tmp, std::ios::binary);
  f.write(data.data(), std::streamsize(data.size()));
  f.close();
  return f && std::rename(tmp.c_str(), path.c_str()) == 0;
}

// GI sampled on the CPU on a top-down grid of points 1 m up (normals up): how many have no light at all
// (missing: none may, inside the world), and how many are dark (zero light: inside closed buildings).
int missingGroundPoints(const lfgi::Runtime& rt, int& dark) {
  const int n = 64;
  std::vector<float> pos, nrm;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      pos.insert(pos.end(), {(float(x) + 0.5f) / float(n) * rt.worldSizeX(), 1.0f,
                             (float(y) + 0.5f) / float(n) * rt.worldSizeZ()});
      nrm.insert(nrm.end(), {0.0f, 1.0f, 0.0f});
    }
  std::vector<lfgi::GiSample> gi(size_t(n) * size_t(n));
  rt.sample(pos, nrm, gi);
  int missing = 0;
  dark = 0;
  for (const lfgi::GiSample& s : gi) {
    missing += s.missing;
    dark += !s.missing && !(s.irradiance[0] + s.irradiance[1] + s.irradiance[2] > 0.0f);
  }
  return missing;
}

int run(const Options& o) {
  HostVulkan v;
  lfgi::RuntimeConfig config;
  config.world = o.world;
  const std::unique_ptr<lfgi::Runtime> rt = lfgi::Runtime::open(config, v.forLfgi());
  std::unique_ptr<lfgi::VulkanShading> shading = lfgi::VulkanShading::create(*rt, v.forLfgi());
  std::printf("lfgi %s: world %.0f x %.0f m, %.0f m cells\n", lfgi::runtimeVersion(), rt->worldSizeX(),
              rt->worldSizeZ(), rt->cellSize());
  const VkDeviceSize bytes = VkDeviceSize(o.width) * VkDeviceSize(o.height) * 16;
  HostBuffer position(v, bytes), normal(v, bytes), albedo(v, bytes), emission(v, bytes), diffuse(v, bytes);
  const lfgi::ShadeTarget target{uint32_t(o.width), uint32_t(o.height), position.buffer, normal.buffer,
                                 albedo.buffer,     emission.buffer,    diffuse.buffer,  VK_NULL_HANDLE};
  // The flight: update + upload every frame (the game thread), shading recorded every 30th.
  const float dt = 1.0f / 30.0f;
  double worstMs = 0.0;
  size_t peak = 0, uploaded = 0;
  for (int i = 0; i < o.frames; ++i) {
    const lfgi::Frame f = flight(*rt, i, dt, o.time);
    const lfgi::FrameReport r = rt->update(f);
    worstMs = std::max(worstMs, r.updateMs);
    peak = std::max(peak, r.bytesResident);
    uploaded += shading->upload();
    if (i % 30 == 29) {
      lfgi::View ahead{{f.position[0], f.position[1], f.position[2]},
                       {f.position[0] + 20.0f * f.direction[0], 0.0f, f.position[2] + 20.0f * f.direction[2]},
                       60.0f};
      shadeView(v, *shading, target, ahead);
    }
  }
  // Teleport to the view (velocity 0) and let its cells load and fade in.
  lfgi::Frame at;
  std::memcpy(at.position, o.view.position, sizeof at.position);
  at.timeOfDayHours = o.time;
  at.dtSeconds = dt;
  lfgi::FrameReport r;
  for (int settled = 0, i = 0; settled < 30 && i < 3000; ++i) {
    r = rt->update(at);
    settled = r.loadingCells == 0 ? settled + 1 : 0;
    uploaded += shading->upload();
  }
  shadeView(v, *shading, target, o.view);
  const float* rgba = static_cast<const float*>(diffuse.mapped);
  const float* gpos = static_cast<const float*>(position.mapped);
  std::vector<uint8_t> rgb;
  int surface = 0, unlit = 0;
  for (int p = 0; p < o.width * o.height; ++p) {
    const float* c = rgba + size_t(p) * 4;
    const bool hit = gpos[size_t(p) * 4 + 3] >= 0.0f;
    surface += hit;
    if (hit && !(c[0] + c[1] + c[2] > 0.0f && std::isfinite(c[0] + c[1] + c[2]))) ++unlit;
    for (int k = 0; k < 3; ++k) rgb.push_back(toByte(c[k]));
  }
  int dark = 0;
  const int missing = missingGroundPoints(*rt, dark);
  if (!writePng(o.out + ".png", o.width, o.height, rgb) || !writePfm(o.out + ".pfm", o.width, o.height, rgba))
    throw std::runtime_error(o.out + ": cannot write the PNG / PFM");
  std::printf(
      "%d frames: peak %.1f MB of %.0f MB, worst update %.2f ms, %.1f MB uploaded to the device; at the "
      "view: "
      "%d cells resident, %.1f MB on the device; %dx%d view: %d surface pixels, %d unlit; CPU samples at "
      "4096 "
      "ground points: %d missing, %d dark (inside buildings); wrote %s.png and %s.pfm\n",
      o.frames, double(peak) / 1048576.0, double(config.memoryBudgetBytes) / 1048576.0, worstMs,
      double(uploaded) / 1048576.0, r.residentCells, double(shading->deviceBytes()) / 1048576.0, o.width,
      o.height, surface, unlit, missing, dark, o.out.c_str(), o.out.c_str());
  shading.reset();  // lfgi's objects go; the device stays the host's (destroyed by ~HostVulkan)
  return unlit == 0 && missing == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  if (!parse(argc, argv, o)) {
    std::fprintf(stderr,
                 "usage: lfgi_example_host WORLD OUT [--frames N] [--size WxH] [--time HOURS] "
                 "[--camera px,py,pz,tx,ty,tz]\n");
    return 2;
  }
  try {
    return run(o);
  } catch (const lfgi::RuntimeError& e) {
    std::fprintf(stderr, "lfgi: %s\n", e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "host: %s\n", e.what());
  }
  return 1;
}
