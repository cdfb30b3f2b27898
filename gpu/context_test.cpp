#include "gpu/context.h"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <numeric>
#include <random>
#include <vector>

#include "core/error.h"
#include "gpu/buffer.h"

namespace lfgi::gpu {
namespace {

TEST(GpuContext, CreatesDeviceWithComputeQueue) {
  auto ctx = createContext();
  ASSERT_NE(ctx->device, VK_NULL_HANDLE);
  EXPECT_FALSE(ctx->info.name.empty());
  EXPECT_GE(ctx->properties.apiVersion, VK_API_VERSION_1_3);
  EXPECT_GT(ctx->properties.limits.timestampPeriod, 0.0f);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

TEST(GpuContext, CreatingTwiceInOneProcessWorks) {
  {
    auto first = createContext();
    auto second = createContext();  // two live at once
    EXPECT_EQ(first->info.name, second->info.name);
    EXPECT_NE(first->device, second->device);
  }
  auto third = createContext();  // and again after both are gone
  Buffer b = createStorageBuffer(*third, 1024);
  fillBuffer(*third, b, 0xdeadbeefu);
  std::vector<uint32_t> out(256);
  readback<uint32_t>(*third, b, out);
  for (uint32_t v : out) ASSERT_EQ(v, 0xdeadbeefu);
  EXPECT_EQ(third->validationErrors.load(), 0u);
}

TEST(GpuContext, UnknownDeviceNameListsAvailableDevices) {
  ContextOptions opt;
  opt.deviceName = "no-such-gpu-xyz";
  try {
    createContext(opt);
    FAIL() << "expected lfgi::Error";
  } catch (const Error& e) {
    std::string msg = e.what();
    EXPECT_NE(msg.find("no-such-gpu-xyz"), std::string::npos) << msg;
    EXPECT_NE(msg.find("available:"), std::string::npos) << msg;
    EXPECT_NE(msg.find(listDevices().front().name), std::string::npos) << msg;
  }
}

TEST(GpuContext, DeviceSelectionByEnvironmentSubstring) {
  std::string name = listDevices().front().name;
  std::string piece = name.substr(0, std::min<size_t>(4, name.size()));
  ::setenv("LFGI_VK_DEVICE", piece.c_str(), 1);
  auto ctx = createContext();
  ::unsetenv("LFGI_VK_DEVICE");
  EXPECT_NE(ctx->info.name.find(piece), std::string::npos);
}

TEST(GpuBuffer, RoundTrip64MiBIsExact) {
  auto ctx = createContext();
  const size_t words = (64u << 20) / sizeof(uint32_t);
  std::vector<uint32_t> data(words);
  std::mt19937 rng(12345);
  for (auto& w : data) w = rng();
  Buffer b = createStorageBuffer(*ctx, words * sizeof(uint32_t));
  upload<uint32_t>(*ctx, b, data);
  std::vector<uint32_t> back(words, 0);
  readback<uint32_t>(*ctx, b, back);
  EXPECT_TRUE(back == data);
  EXPECT_EQ(ctx->validationErrors.load(), 0u);
}

TEST(GpuBuffer, PartialRangesAndBoundsChecks) {
  auto ctx = createContext();
  Buffer b = createStorageBuffer(*ctx, 64);
  std::vector<uint32_t> zeros(16, 0), four{1, 2, 3, 4};
  upload<uint32_t>(*ctx, b, zeros);
  upload<uint32_t>(*ctx, b, four, 8);  // words 2..5
  std::vector<uint32_t> back(16);
  readback<uint32_t>(*ctx, b, back);
  std::vector<uint32_t> expect(16, 0);
  std::iota(expect.begin() + 2, expect.begin() + 6, 1u);
  EXPECT_EQ(back, expect);
  EXPECT_THROW(upload<uint32_t>(*ctx, b, four, 56), Error);  // 56 + 16 > 64
  std::vector<uint32_t> tooMany(17);
  EXPECT_THROW(readback<uint32_t>(*ctx, b, tooMany), Error);
  EXPECT_THROW(Buffer(*ctx, 0, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, MemoryUsage::DeviceLocal), Error);
}

TEST(GpuBuffer, MappedUploadAndReadbackBuffers) {
  auto ctx = createContext();
  Buffer up(*ctx, 256, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryUsage::Upload);
  Buffer down(*ctx, 256, VK_BUFFER_USAGE_TRANSFER_DST_BIT, MemoryUsage::Readback);
  ASSERT_NE(up.mapped(), nullptr);
  ASSERT_NE(down.mapped(), nullptr);
  std::vector<uint8_t> bytes(256);
  std::iota(bytes.begin(), bytes.end(), uint8_t{0});
  upload<uint8_t>(*ctx, up, bytes);
  submitAndWait(*ctx, [&](VkCommandBuffer cmd) {
    VkBufferCopy region{0, 0, 256};
    vkCmdCopyBuffer(cmd, up.handle(), down.handle(), 1, &region);
    memoryBarrier(cmd);
  });
  std::vector<uint8_t> back(256);
  readback<uint8_t>(*ctx, down, back);
  EXPECT_EQ(back, bytes);
  Buffer moved = std::move(down);
  EXPECT_EQ(down.handle(), VK_NULL_HANDLE);
  EXPECT_NE(moved.handle(), VK_NULL_HANDLE);
}

}  // namespace
}  // namespace lfgi::gpu
