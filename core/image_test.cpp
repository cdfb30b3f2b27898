#include "core/image.h"

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#define STB_IMAGE_STATIC
#define STB_IMAGE_IMPLEMENTATION
#include <stb/stb_image.h>

#include "core/error.h"
#include "core/file_util.h"

namespace lfgi {
namespace {

namespace fs = std::filesystem;

fs::path tmpDir(const std::string& name) {
  const fs::path dir = fs::path(LFGI_TEST_TMP_DIR) / "image_test" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

Image randomImage(int w, int h, std::vector<std::string> channels, unsigned seed) {
  Image image(w, h, std::move(channels));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-2.0f, 2.0f);
  for (float& v : image.pixels) v = u(rng);
  // Values FP16 could not hold and float edge cases: FLOAT channels must keep them bit-exact.
  image.pixels[0] = 1e30f;
  image.pixels[1] = -1e-40f;  // subnormal
  image.pixels[2] = -0.0f;
  image.pixels[3] = 123456.789f;
  return image;
}

std::vector<std::byte> bytesOf(const fs::path& path) {
  return readFileBytes(path);
}

void writeBytes(const fs::path& path, std::span<const std::byte> bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

// Expects readExr(path) to throw lfgi::Error whose message names the path.
void expectReadFails(const fs::path& path, const std::string& context) {
  try {
    (void)readExr(path);
    ADD_FAILURE() << context << ": readExr did not throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << context << ": " << e.what();
  }
}

bool anyTempFiles(const fs::path& dir) {
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.path().filename().string().find(".tmp.") != std::string::npos) return true;
  return false;
}

TEST(Exr, RoundTripIsExactWithLayerNames) {
  const fs::path dir = tmpDir("roundtrip");
  const Image image =
      randomImage(37, 23, {"indirect.R", "indirect.G", "indirect.B", "direct.R", "A", "depth"}, 1);
  const fs::path path = dir / "layers.exr";
  writeExr(path, image);
  const Image back = readExr(path);
  EXPECT_EQ(back.width, image.width);
  EXPECT_EQ(back.height, image.height);
  EXPECT_EQ(back.channels, image.channels);  // write order kept, not OpenEXR's alphabetical order
  ASSERT_EQ(back.pixels.size(), image.pixels.size());
  EXPECT_EQ(std::memcmp(back.pixels.data(), image.pixels.data(), image.pixels.size() * sizeof(float)), 0);
  EXPECT_EQ(back.at(5, 7, 3), image.at(5, 7, 3));
  EXPECT_FALSE(anyTempFiles(dir));
}

TEST(Exr, MissingFileThrowsWithPath) {
  expectReadFails(tmpDir("missing") / "does_not_exist.exr", "missing");
}

TEST(Exr, NonExrFileThrowsWithPath) {
  const fs::path dir = tmpDir("notexr");
  writeFileAtomic(dir / "text.exr", std::string("this is not an EXR file, just text\n"));
  expectReadFails(dir / "text.exr", "text");
  writeFileAtomic(dir / "empty.exr", std::string());
  expectReadFails(dir / "empty.exr", "empty");
  // The right magic number followed by garbage.
  std::string fake = "\x76\x2f\x31\x01";
  fake += std::string(200, '\xab');
  writeFileAtomic(dir / "fake.exr", fake);
  expectReadFails(dir / "fake.exr", "magic + garbage");
  expectReadFails(dir, "directory");
}

TEST(Exr, TruncatedFilesThrowWithPath) {
  const fs::path dir = tmpDir("truncated");
  // Small file: every byte offset. Larger file (many ZIP chunks): 97 offsets spread over it.
  struct Case {
    Image image;
    int step;
  };
  const Case cases[] = {{randomImage(6, 5, {"R", "G", "B"}, 2), 1},
                        {randomImage(64, 80, {"indirect.R", "indirect.G", "indirect.B"}, 3), 0}};
  for (const Case& c : cases) {
    const fs::path full = dir / "full.exr";
    writeExr(full, c.image);
    const std::vector<std::byte> bytes = bytesOf(full);
    std::vector<std::size_t> offsets;
    if (c.step == 1) {
      for (std::size_t k = 0; k < bytes.size(); ++k) offsets.push_back(k);
    } else {
      for (std::size_t k = 0; k < 97; ++k) offsets.push_back(k * bytes.size() / 97);
      for (std::size_t k = 1; k <= 8; ++k) offsets.push_back(bytes.size() - k);
    }
    const fs::path cut = dir / "cut.exr";
    for (std::size_t size : offsets) {
      writeBytes(cut, std::span(bytes.data(), size));
      expectReadFails(cut, "truncated to " + std::to_string(size) + " of " + std::to_string(bytes.size()));
    }
  }
}

// Bad input (docs/ARCHITECTURE.md "Bad input and interruption"): seeded bit flips in a small file are an
// lfgi::Error naming the path or an image of the written size (a flip inside pixel data is not detectable:
// EXR has no checksum); a wrong version field and a huge data window are refused before anything is allocated
// from them.
TEST(Exr, BitFlipsWrongVersionAndHugeWindow) {
  const fs::path dir = tmpDir("corrupt");
  const fs::path full = dir / "full.exr";
  writeExr(full, randomImage(6, 5, {"R", "G", "B"}, 7));
  const std::vector<std::byte> bytes = bytesOf(full);
  const fs::path bad = dir / "bad.exr";
  std::mt19937 rng(1010);
  size_t rejected = 0;
  for (int t = 0; t < 400; ++t) {
    std::vector<std::byte> b = bytes;
    for (int k = 0; k < 1 + t % 3; ++k) b[rng() % b.size()] ^= std::byte(1u << (rng() % 8));
    writeBytes(bad, b);
    try {
      const Image image = readExr(bad);
      image.validate("flipped");
    } catch (const Error& e) {
      ++rejected;
      ASSERT_EQ(std::string(e.what()).rfind(bad.string(), 0), 0u) << "trial " << t << ": " << e.what();
    } catch (const std::exception& e) {
      FAIL() << "trial " << t << ": not an lfgi::Error: " << e.what();
    }
  }
  std::printf("[ measure  ] %zu of 400 bit-flipped EXR files rejected\n", rejected);

  // Byte 4 is the EXR version (2); bytes 5-7 are flags.
  std::vector<std::byte> b = bytes;
  b[4] = std::byte{3};
  writeBytes(bad, b);
  expectReadFails(bad, "version 3");
  // dataWindow: attribute "dataWindow\0box2i\0", u32 size 16, then xMin yMin xMax yMax.
  const std::string key("dataWindow\0box2i\0", 17);
  const auto it = std::search(bytes.begin(), bytes.end(), reinterpret_cast<const std::byte*>(key.data()),
                              reinterpret_cast<const std::byte*>(key.data()) + key.size());
  ASSERT_NE(it, bytes.end());
  const size_t at = size_t(it - bytes.begin()) + key.size() + 4;
  for (const int32_t huge : {int32_t(1) << 30, int32_t(-1)}) {
    b = bytes;
    std::memcpy(b.data() + at + 8, &huge, 4);   // xMax
    std::memcpy(b.data() + at + 12, &huge, 4);  // yMax
    writeBytes(bad, b);
    expectReadFails(bad, "dataWindow max " + std::to_string(huge));
  }
}

// NaN and Inf are pixel values like any other in a FLOAT EXR: they round-trip bit-exactly (a caller that
// feeds them into a bake checks its own inputs).
TEST(Exr, NonFinitePixelsRoundTripExactly) {
  const fs::path dir = tmpDir("nonfinite");
  Image image = randomImage(3, 2, {"R"}, 8);
  image.pixels[0] = std::numeric_limits<float>::quiet_NaN();
  image.pixels[1] = std::numeric_limits<float>::infinity();
  image.pixels[2] = -std::numeric_limits<float>::infinity();
  writeExr(dir / "nan.exr", image);
  const Image back = readExr(dir / "nan.exr");
  ASSERT_EQ(back.pixels.size(), image.pixels.size());
  EXPECT_EQ(std::memcmp(back.pixels.data(), image.pixels.data(), image.pixels.size() * sizeof(float)), 0);
}

TEST(Exr, FailedWritesLeaveNoTemporaryFile) {
  const fs::path dir = tmpDir("failedwrite");
  // Target is an existing directory: the file is written under the temporary name, the rename fails.
  fs::create_directories(dir / "occupied.exr" / "child");
  EXPECT_THROW(writeExr(dir / "occupied.exr", randomImage(4, 4, {"R"}, 4)), Error);
  // OpenEXR itself fails: a directory sits where the temporary file would go, so opening it throws inside
  // the write callback; the error names the final path and the (empty) blocker is cleaned up.
  const fs::path blocked = dir / "blocked.exr";
  fs::create_directories(blocked.string() + ".tmp." + std::to_string(::getpid()));
  try {
    writeExr(blocked, randomImage(4, 4, {"R", "G", "B"}, 5));
    ADD_FAILURE() << "writeExr succeeded with its temporary path blocked";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(blocked.string()), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(blocked));
  // Invalid images are refused before anything is written.
  Image bad = randomImage(4, 4, {"R", "G"}, 6);
  bad.pixels.pop_back();
  EXPECT_THROW(writeExr(dir / "bad.exr", bad), Error);
  EXPECT_THROW(Image(2, 2, {"R", "R"}), Error);
  EXPECT_FALSE(anyTempFiles(dir));
  EXPECT_FALSE(fs::exists(dir / "bad.exr"));
}

TEST(Png, ToneMappedSrgbValues) {
  const fs::path dir = tmpDir("png");
  Image image(4, 2, {"indirect.R", "indirect.G", "indirect.B"});
  image.at(0, 0, 0) = 0.0f;  // black
  image.at(1, 0, 0) = 1e9f;  // saturates
  image.at(2, 0, 0) = std::numeric_limits<float>::quiet_NaN();
  image.at(3, 0, 0) = 0.18f;
  image.at(3, 0, 1) = 0.18f;
  image.at(3, 0, 2) = 0.18f;
  const fs::path path = dir / "out.png";
  writePng(path, image, 0.0f, ToneMap::kReinhard, "indirect.");
  int w = 0, h = 0, comp = 0;
  const std::vector<std::byte> bytes = readFileBytes(path);
  unsigned char* px = stbi_load_from_memory(reinterpret_cast<const unsigned char*>(bytes.data()),
                                            static_cast<int>(bytes.size()), &w, &h, &comp, 3);
  ASSERT_NE(px, nullptr);
  EXPECT_EQ(w, 4);
  EXPECT_EQ(h, 2);
  EXPECT_EQ(px[0], 0);
  EXPECT_EQ(px[3], 255);
  EXPECT_EQ(px[6], 0);
  // Reinhard: 0.18 / 1.18 = 0.15254, sRGB-encoded 0.4275 -> 109.
  EXPECT_EQ(px[9], 109);
  EXPECT_EQ(px[10], 109);
  stbi_image_free(px);
  writePng(dir / "aces.png", image, 1.0f, ToneMap::kAcesFitted, "indirect.");
  EXPECT_TRUE(fs::exists(dir / "aces.png"));
  try {
    writePng(dir / "nochannels.png", image);  // no R, G, B without the layer prefix
    ADD_FAILURE() << "writePng accepted an image without R, G, B";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("nochannels.png"), std::string::npos);
  }
  EXPECT_FALSE(anyTempFiles(dir));
}

}  // namespace
}  // namespace lfgi
