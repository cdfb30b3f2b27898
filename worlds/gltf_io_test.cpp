#include "worlds/gltf_io.h"

#include <gtest/gtest.h>

#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/file_util.h"

namespace lfgi::worlds {
namespace {

namespace fs = std::filesystem;

const fs::path kScenes = LFGI_SCENES_DIR;

fs::path tmpDir(const std::string& name) {
  fs::path dir = fs::path(LFGI_TEST_TMP_DIR) / "gltf_io" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void writeText(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

std::vector<char> readBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<char>(std::istreambuf_iterator<char>(in), {});
}

void writeBytes(const fs::path& path, const char* data, size_t size) {
  std::ofstream out(path, std::ios::binary);
  out.write(data, std::streamsize(size));
}

std::string base64(const std::vector<unsigned char>& bytes) {
  static const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < bytes.size(); i += 3) {
    uint32_t v = uint32_t(bytes[i]) << 16;
    if (i + 1 < bytes.size()) v |= uint32_t(bytes[i + 1]) << 8;
    if (i + 2 < bytes.size()) v |= uint32_t(bytes[i + 2]);
    out += table[(v >> 18) & 63];
    out += table[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? table[(v >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? table[v & 63] : '=';
  }
  return out;
}

template <typename T>
void appendRaw(std::vector<unsigned char>& out, const std::vector<T>& values) {
  const auto* p = reinterpret_cast<const unsigned char*>(values.data());
  out.insert(out.end(), p, p + values.size() * sizeof(T));
}

// A small glTF with one buffer (data URI) holding float VEC3 positions followed by uint16 indices.
// primitive (JSON) is merged into the default primitive; node (JSON) into the default node.
nlohmann::json tinyGltf(const std::vector<float>& positions, const std::vector<uint16_t>& indices) {
  std::vector<unsigned char> bin;
  appendRaw(bin, positions);
  const size_t indexOffset = bin.size();
  appendRaw(bin, indices);
  nlohmann::json j;
  j["asset"] = {{"version", "2.0"}};
  j["scene"] = 0;
  j["scenes"] = nlohmann::json::array({{{"nodes", {0}}}});
  j["nodes"] = nlohmann::json::array({{{"mesh", 0}}});
  j["buffers"] = nlohmann::json::array(
      {{{"byteLength", bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(bin)}}});
  j["bufferViews"] =
      nlohmann::json::array({{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", positions.size() * 4}},
                             {{"buffer", 0},
                              {"byteOffset", indexOffset},
                              {"byteLength", std::max<size_t>(indices.size() * 2, 1)}}});
  j["accessors"] = nlohmann::json::array(
      {{{"bufferView", 0}, {"componentType", 5126}, {"count", positions.size() / 3}, {"type", "VEC3"}},
       {{"bufferView", 1}, {"componentType", 5123}, {"count", indices.size()}, {"type", "SCALAR"}}});
  nlohmann::json prim = {{"attributes", {{"POSITION", 0}}}, {"mode", 4}};
  if (!indices.empty()) prim["indices"] = 1;
  j["meshes"] = nlohmann::json::array({{{"primitives", nlohmann::json::array({prim})}}});
  return j;
}

// Tetrahedron (0,0,0), (1,0,0), (0,1,0), (0,0,1) with outward counter-clockwise faces.
const std::vector<float> kTetraPositions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
const std::vector<uint16_t> kTetraIndices = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};

// Counts triangles whose normal points away from the mesh's vertex centroid.
size_t outwardTriangles(const TriangleMesh& m) {
  glm::vec3 c(0.0f);
  for (const glm::vec3& p : m.positions) c += p;
  c /= float(m.positions.size());
  size_t n = 0;
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    const glm::vec3 mid = (m.vertex(t, 0) + m.vertex(t, 1) + m.vertex(t, 2)) / 3.0f;
    if (glm::dot(m.faceNormal(t), mid - c) > 0.0f) ++n;
  }
  return n;
}

// Runs f, which must throw lfgi::Error; returns its message.
template <typename F>
std::string errorOf(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "not an lfgi::Error: " << e.what();
    return {};
  }
  ADD_FAILURE() << "no exception";
  return {};
}

void expectErrorNames(const std::string& message, const fs::path& file, const std::string& keyword) {
  EXPECT_EQ(message.rfind(file.string(), 0), 0u) << "message does not start with the path: " << message;
  EXPECT_NE(message.find(keyword), std::string::npos) << "no '" << keyword << "' in: " << message;
}

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void expectNear(glm::vec3 a, glm::vec3 b, float tol, const char* what) {
  EXPECT_NEAR(a.x, b.x, tol) << what;
  EXPECT_NEAR(a.y, b.y, tol) << what;
  EXPECT_NEAR(a.z, b.z, tol) << what;
}

// The triangles of material m, in order, as 9 floats each.
std::vector<float> trianglesOfMaterial(const TriangleMesh& mesh, uint32_t m) {
  std::vector<float> out;
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    if (mesh.triangleMaterial[t] != m) continue;
    for (int k = 0; k < 3; ++k) {
      const glm::vec3 p = mesh.vertex(t, k);
      out.insert(out.end(), {p.x, p.y, p.z});
    }
  }
  return out;
}

void expectSameMaterials(const TriangleMesh& a, const TriangleMesh& b) {
  ASSERT_EQ(a.materials.size(), b.materials.size());
  for (size_t i = 0; i < a.materials.size(); ++i) {
    const Material& x = a.materials[i];
    const Material& y = b.materials[i];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.albedo, y.albedo) << x.name;  // exact
    EXPECT_EQ(x.emission, y.emission) << x.name;
    EXPECT_EQ(x.roughness, y.roughness) << x.name;
    EXPECT_EQ(x.metallic, y.metallic) << x.name;
    EXPECT_EQ(x.doubleSided, y.doubleSided) << x.name;
    EXPECT_EQ(y.category, SurfaceCategory::kImported);
  }
}

// ---- scenes -------------------------------------------------------------------------------------------

TEST(GltfImport, CornellBoxInMetres) {
  GltfImportReport report;
  GltfImportOptions options;
  options.scale = 0.001f;
  options.report = &report;
  const auto t0 = std::chrono::steady_clock::now();
  const TriangleMesh m = importGltf(kScenes / "cornell_box/CornellBox.glb", options);
  std::printf("[ measure  ] CornellBox.glb: %zu triangles, %zu vertices, %.1f ms\n", m.triangleCount(),
              m.positions.size(), secondsSince(t0) * 1e3);
  EXPECT_EQ(m.triangleCount(), 36u);
  const Aabb b = m.bounds();
  expectNear(b.min, {-0.556f, 0.0f, -0.5592f}, 1e-4f, "min");
  expectNear(b.max, {0.0f, 0.5488f, 0.0f}, 1e-4f, "max");
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();

  size_t emissive = 0, red = 0, green = 0;
  for (const Material& mat : m.materials) {
    EXPECT_EQ(mat.category, SurfaceCategory::kImported);
    EXPECT_TRUE(mat.doubleSided) << mat.name;
    EXPECT_FLOAT_EQ(mat.metallic, 0.0f) << mat.name;
    EXPECT_FLOAT_EQ(mat.roughness, 0.5f) << mat.name;
    if (mat.emission != glm::vec3(0.0f)) {
      ++emissive;
      EXPECT_EQ(mat.emission, glm::vec3(100.0f)) << "emissiveFactor (1,1,1) x strength 100";
    }
    if (mat.albedo == glm::vec3(0.5f, 0.0f, 0.0f)) ++red;
    if (mat.albedo == glm::vec3(0.0f, 0.5f, 0.0f)) ++green;
  }
  EXPECT_EQ(emissive, 1u);
  EXPECT_EQ(red, 1u);
  EXPECT_EQ(green, 1u);
  // The light is a 130 x 105 mm quad.
  double lightArea = 0.0;
  for (size_t t = 0; t < m.triangleCount(); ++t)
    if (m.materials[m.triangleMaterial[t]].emission != glm::vec3(0.0f)) lightArea += m.triangleArea(t);
  EXPECT_NEAR(lightArea, 0.130 * 0.105, 1e-6);
}

TEST(GltfImport, BoxIsUnitCubeFacingOutward) {
  const TriangleMesh m = importGltf(kScenes / "box/Box.gltf");
  EXPECT_EQ(m.triangleCount(), 12u);
  const Aabb b = m.bounds();
  expectNear(b.min, glm::vec3(-0.5f), 1e-6f, "min");
  expectNear(b.max, glm::vec3(0.5f), 1e-6f, "max");
  EXPECT_NEAR(m.totalArea(), 6.0, 1e-5);
  EXPECT_EQ(outwardTriangles(m), 12u);
  ASSERT_EQ(m.materials.size(), 1u);
  EXPECT_EQ(m.materials[0].albedo, glm::vec3(0.800000011920929f, 0.0f, 0.0f));
  EXPECT_EQ(m.materials[0].metallic, 1.0f);  // not in the file: glTF's default
  EXPECT_EQ(m.materials[0].roughness, 1.0f);
  EXPECT_TRUE(m.uvs.empty());
}

// Sponza is the largest scene (262k instanced triangles; 21 of its 46 images are base colours and get
// decoded). It loads in ~0.5 s in RelWithDebInfo, so it is not labelled slow.
TEST(GltfImport, SponzaCountsAndBounds) {
  GltfImportReport report;
  const auto t0 = std::chrono::steady_clock::now();
  const TriangleMesh m = loadScenePreset(findScenePreset("sponza"), kScenes, &report);
  std::printf("[ measure  ] Sponza.gltf: %zu triangles, %zu vertices, %zu materials, %zu textures, %.0f ms\n",
              m.triangleCount(), m.positions.size(), m.materials.size(), m.textures.size(),
              secondsSince(t0) * 1e3);
  // README: 115,580 unique / 262,087 instanced; the importer flattens every instance.
  EXPECT_EQ(m.triangleCount(), 262087u);
  const Aabb b = m.bounds();
  expectNear(b.min, {-26.845f, 2.282f, -16.478f}, 1e-3f, "min");
  expectNear(b.max, {24.177f, 23.617f, 14.900f}, 1e-3f, "max");
  EXPECT_EQ(report.missingImages, 0u);
  EXPECT_GT(m.textures.size(), 0u);
  EXPECT_EQ(m.uvs.size(), m.positions.size());
  for (const Texture& t : m.textures) EXPECT_EQ(t.rgba.size(), size_t(t.width) * size_t(t.height) * 4);
  for (const std::string& w : report.warnings) std::printf("[ warning  ] %s\n", w.c_str());
}

TEST(GltfImport, BreakfastRoomCountsAndBounds) {
  GltfImportReport report;
  const auto t0 = std::chrono::steady_clock::now();
  const TriangleMesh m = loadScenePreset(findScenePreset("breakfast_room"), kScenes, &report);
  std::printf("[ measure  ] BreakfastRoom.gltf: %zu triangles, %zu vertices, %zu textures, %.0f ms\n",
              m.triangleCount(), m.positions.size(), m.textures.size(), secondsSince(t0) * 1e3);
  EXPECT_EQ(m.triangleCount(), 262687u);  // README: 82,291 unique / 262,687 instanced
  const Aabb b = m.bounds();
  expectNear(b.min, {-1.777f, 0.000f, -2.402f}, 1e-3f, "min");
  expectNear(b.max, {1.942f, 2.998f, 2.249f}, 1e-3f, "max");
  EXPECT_EQ(report.missingImages, 0u);
  EXPECT_EQ(m.textures.size(), 3u);
}

// ---- synthetic files ------------------------------------------------------------------------------------

TEST(GltfImport, NegativeScaleNodeKeepsOutwardWinding) {
  const fs::path dir = tmpDir("mirror");
  for (const char* scale : {"[1, 1, 1]", "[-1, 1, 1]", "[-2, -3, -0.5]"}) {
    nlohmann::json j = tinyGltf(kTetraPositions, kTetraIndices);
    j["nodes"][0]["scale"] = nlohmann::json::parse(scale);
    j["nodes"][0]["translation"] = {5, 0, 0};
    writeText(dir / "tetra.gltf", j.dump());
    const TriangleMesh m = importGltf(dir / "tetra.gltf");
    ASSERT_EQ(m.triangleCount(), 4u) << scale;
    EXPECT_EQ(outwardTriangles(m), 4u) << "scale " << scale;
    EXPECT_GT(m.bounds().max.x, 3.0f);
  }
  // The same through a parent with a mirroring matrix and a child with a positive scale.
  nlohmann::json j = tinyGltf(kTetraPositions, kTetraIndices);
  j["nodes"] = nlohmann::json::array(
      {{{"children", {1}}, {"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1}}}, {{"mesh", 0}}});
  writeText(dir / "tetra_matrix.gltf", j.dump());
  const TriangleMesh m = importGltf(dir / "tetra_matrix.gltf");
  EXPECT_EQ(outwardTriangles(m), 4u);
  EXPECT_EQ(m.bounds().min.z, -1.0f);
}

TEST(GltfImport, InstancesStripsFansAndSkippedPrimitives) {
  const fs::path dir = tmpDir("modes");
  // Quad 0-1-2-3 in z = 0, counter-clockwise seen from +Z.
  const std::vector<float> quad = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  nlohmann::json j = tinyGltf(quad, {0, 1, 2, 0, 2, 3});
  nlohmann::json prims = nlohmann::json::array();
  prims.push_back({{"attributes", {{"POSITION", 0}}}, {"indices", 1}, {"mode", 4}});  // 2 triangles
  prims.push_back({{"attributes", {{"POSITION", 0}}}, {"mode", 6}});                  // fan: 2
  prims.push_back({{"attributes", {{"POSITION", 0}}}, {"mode", 0}});                  // points: skipped
  j["meshes"][0]["primitives"] = prims;
  // The strip 1-2-0-3 covers the same quad (its second triangle is 2-3-0 after the odd-triangle swap).
  std::vector<unsigned char> stripBin;
  appendRaw(stripBin, std::vector<uint16_t>{1, 2, 0, 3});
  j["buffers"].push_back(
      {{"byteLength", stripBin.size()}, {"uri", "data:application/octet-stream;base64," + base64(stripBin)}});
  j["bufferViews"].push_back({{"buffer", 1}, {"byteLength", stripBin.size()}});
  j["accessors"].push_back({{"bufferView", 2}, {"componentType", 5123}, {"count", 4}, {"type", "SCALAR"}});
  nlohmann::json strip = {{"attributes", {{"POSITION", 0}}}, {"indices", 2}, {"mode", 5}};
  j["meshes"].push_back({{"primitives", nlohmann::json::array({strip})}});
  j["nodes"] = nlohmann::json::array(
      {{{"mesh", 0}}, {{"mesh", 0}, {"translation", {0, 0, 2}}}, {{"mesh", 1}, {"translation", {0, 0, 4}}}});
  j["scenes"][0]["nodes"] = {0, 1, 2};
  writeText(dir / "modes.gltf", j.dump());
  GltfImportReport report;
  GltfImportOptions options;
  options.report = &report;
  const TriangleMesh m = importGltf(dir / "modes.gltf", options);
  EXPECT_EQ(report.meshInstances, 3u);
  EXPECT_EQ(report.primitivesSkipped, 2u);  // the points primitive, in both instances of mesh 0
  EXPECT_EQ(report.primitivesImported, 5u);
  EXPECT_FALSE(report.warnings.empty());
  // Mesh 0: 4 triangles per instance (list + fan share vertices), mesh 1: strip of 2 triangles.
  EXPECT_EQ(m.triangleCount(), 4u + 4u + 2u);
  EXPECT_EQ(m.positions.size(), 4u + 4u + 4u);
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    EXPECT_NEAR(m.faceNormal(t).z, 1.0f, 1e-6f) << "triangle " << t;
    EXPECT_NEAR(m.triangleArea(t), 0.5, 1e-6) << "triangle " << t;
  }
  // Primitives without material share one default material with glTF's default values.
  ASSERT_EQ(m.materials.size(), 1u);
  EXPECT_EQ(m.materials[0].name, "default");
  EXPECT_EQ(m.materials[0].albedo, glm::vec3(1.0f));
  EXPECT_EQ(m.materials[0].metallic, 1.0f);
}

TEST(GltfImport, NormalizedTexcoordsAndMissingImageWarns) {
  const fs::path dir = tmpDir("uv");
  nlohmann::json j = tinyGltf(kTetraPositions, kTetraIndices);
  // Normalized unsigned-short uvs in a second buffer.
  std::vector<uint16_t> uv = {0, 0, 65535, 0, 0, 65535, 32768, 32768};
  std::vector<unsigned char> bin;
  appendRaw(bin, uv);
  j["buffers"].push_back(
      {{"byteLength", bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(bin)}});
  j["bufferViews"].push_back({{"buffer", 1}, {"byteLength", bin.size()}});
  j["accessors"].push_back(
      {{"bufferView", 2}, {"componentType", 5123}, {"normalized", true}, {"count", 4}, {"type", "VEC2"}});
  j["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = 2;
  j["meshes"][0]["primitives"][0]["material"] = 0;
  j["materials"] = nlohmann::json::array(
      {{{"name", "tex"},
        {"pbrMetallicRoughness",
         {{"baseColorFactor", {0.25, 0.5, 0.75, 1.0}}, {"baseColorTexture", {{"index", 0}}}}}}});
  j["textures"] = nlohmann::json::array({{{"source", 0}}});
  j["images"] = nlohmann::json::array({{{"uri", "no_such_image.png"}}});
  writeText(dir / "uv.gltf", j.dump());
  GltfImportReport report;
  GltfImportOptions options;
  options.report = &report;
  const TriangleMesh m = importGltf(dir / "uv.gltf", options);
  ASSERT_EQ(m.uvs.size(), 4u);
  EXPECT_EQ(m.uvs[1], glm::vec2(1.0f, 0.0f));
  EXPECT_NEAR(m.uvs[3].x, 32768.0f / 65535.0f, 1e-7f);
  EXPECT_EQ(report.missingImages, 1u);
  EXPECT_TRUE(m.textures.empty());
  ASSERT_EQ(m.materials.size(), 1u);
  EXPECT_EQ(m.materials[0].albedoTexture, -1);
  EXPECT_EQ(m.materials[0].albedo, glm::vec3(0.25f, 0.5f, 0.75f));
  bool named = false;
  for (const std::string& w : report.warnings) named |= w.find("no_such_image.png") != std::string::npos;
  EXPECT_TRUE(named) << "no warning names the missing image";
}

uint32_t crc32(const unsigned char* p, size_t n, uint32_t crc = 0) {
  crc = ~crc;
  for (size_t i = 0; i < n; ++i) {
    crc ^= p[i];
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

// Minimal RGBA PNG (8 or 16 bits per channel; samples big-endian as PNG wants), with stored (uncompressed)
// deflate blocks, so the test does not depend on an encoder.
std::vector<unsigned char> makePng(int w, int h, int bits, const std::vector<uint16_t>& rgba) {
  std::vector<unsigned char> raw;
  const size_t bytesPerSample = bits == 16 ? 2 : 1;
  for (int y = 0; y < h; ++y) {
    raw.push_back(0);  // filter: none
    for (int x = 0; x < w * 4; ++x) {
      const uint16_t v = rgba[size_t(y) * size_t(w) * 4 + size_t(x)];
      if (bytesPerSample == 2) raw.push_back(uint8_t(v >> 8));
      raw.push_back(uint8_t(v & 0xff));
    }
  }
  std::vector<unsigned char> z = {0x78,
                                  0x01,
                                  0x01,
                                  uint8_t(raw.size() & 0xff),
                                  uint8_t(raw.size() >> 8),
                                  uint8_t(~raw.size() & 0xff),
                                  uint8_t((~raw.size() >> 8) & 0xff)};
  z.insert(z.end(), raw.begin(), raw.end());
  uint32_t a = 1, b = 0;
  for (unsigned char c : raw) {
    a = (a + c) % 65521;
    b = (b + a) % 65521;
  }
  const uint32_t adler = (b << 16) | a;
  for (int k = 3; k >= 0; --k) z.push_back(uint8_t(adler >> (8 * k)));
  std::vector<unsigned char> png = {0x89, 'P', 'N', 'G', 0x0d, 0x0a, 0x1a, 0x0a};
  auto chunk = [&](const char* type, const std::vector<unsigned char>& data) {
    for (int k = 3; k >= 0; --k) png.push_back(uint8_t(data.size() >> (8 * k)));
    std::vector<unsigned char> td(type, type + 4);
    td.insert(td.end(), data.begin(), data.end());
    png.insert(png.end(), td.begin(), td.end());
    const uint32_t crc = crc32(td.data(), td.size());
    for (int k = 3; k >= 0; --k) png.push_back(uint8_t(crc >> (8 * k)));
  };
  std::vector<unsigned char> ihdr;
  for (int v : {w, h})
    for (int k = 3; k >= 0; --k) ihdr.push_back(uint8_t(uint32_t(v) >> (8 * k)));
  ihdr.insert(ihdr.end(), {uint8_t(bits), 6, 0, 0, 0});
  chunk("IHDR", ihdr);
  chunk("IDAT", z);
  chunk("IEND", {});
  return png;
}

TEST(GltfImport, DecodesDataUriAndBufferViewImages) {
  const fs::path dir = tmpDir("png");
  const std::vector<unsigned char> png8 = makePng(2, 1, 8, {255, 0, 0, 255, 0, 0, 255, 128});
  const std::vector<unsigned char> png16 = makePng(1, 2, 16, {65535, 32768, 0, 65535, 0x1234, 0, 0xff00, 0});
  nlohmann::json j = tinyGltf(kTetraPositions, kTetraIndices);
  j["buffers"].push_back(
      {{"byteLength", png16.size()}, {"uri", "data:application/octet-stream;base64," + base64(png16)}});
  j["bufferViews"].push_back({{"buffer", 1}, {"byteLength", png16.size()}});
  j["meshes"][0]["primitives"][0]["material"] = 0;
  j["meshes"][0]["primitives"].push_back(j["meshes"][0]["primitives"][0]);
  j["meshes"][0]["primitives"][1]["material"] = 1;
  j["materials"] =
      nlohmann::json::array({{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}},
                             {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 1}}}}}}});
  j["textures"] = nlohmann::json::array({{{"source", 0}}, {{"source", 1}}});
  j["images"] = nlohmann::json::array(
      {{{"uri", "data:image/png;base64," + base64(png8)}}, {{"bufferView", 2}, {"mimeType", "image/png"}}});
  writeText(dir / "png.gltf", j.dump());
  GltfImportReport report;
  GltfImportOptions options;
  options.report = &report;
  const TriangleMesh m = importGltf(dir / "png.gltf", options);
  ASSERT_EQ(m.textures.size(), 2u) << (report.warnings.empty() ? "" : report.warnings.back());
  EXPECT_EQ(report.imagesDecoded, 2u);
  EXPECT_EQ(m.textures[0].width, 2);
  EXPECT_EQ(m.textures[0].height, 1);
  EXPECT_EQ(m.textures[0].rgba, (std::vector<uint8_t>{255, 0, 0, 255, 0, 0, 255, 128}));
  EXPECT_EQ(m.textures[1].width, 1);
  EXPECT_EQ(m.textures[1].height, 2);
  EXPECT_EQ(m.textures[1].rgba, (std::vector<uint8_t>{255, 128, 0, 255, 0x12, 0, 0xff, 0}));  // 16 -> 8 bits
  EXPECT_EQ(m.materials[0].albedoTexture, 0);
  EXPECT_EQ(m.materials[1].albedoTexture, 1);
  EXPECT_EQ(m.triangleCount(), 8u);
  EXPECT_EQ(m.positions.size(), 4u) << "both primitives use the same POSITION accessor";
  // With textures off the materials keep their flat colours only.
  options.loadTextures = false;
  const TriangleMesh flat = importGltf(dir / "png.gltf", options);
  EXPECT_TRUE(flat.textures.empty());
  EXPECT_EQ(flat.materials[0].albedoTexture, -1);
  // An image bufferView past the end of its buffer is an error, not a read out of bounds.
  j["bufferViews"][2]["byteOffset"] = 1000000;
  writeText(dir / "png_bad.gltf", j.dump());
  expectErrorNames(errorOf([&] { importGltf(dir / "png_bad.gltf"); }), dir / "png_bad.gltf", "out of range");
}

TEST(GltfImport, UndecodableAndOversizedImagesGiveFlatColour) {
  const fs::path dir = tmpDir("bad_images");
  std::vector<unsigned char> huge = makePng(1, 1, 8, {1, 2, 3, 4});
  huge[16] = 0x00;  // IHDR width = 0x00100000 (1 M px); stb_image does not check chunk CRCs
  huge[17] = 0x10;
  const std::vector<unsigned char> junk = {'n', 'o', 't', ' ', 'a', 'n', ' ', 'i', 'm', 'a', 'g', 'e'};
  nlohmann::json j = tinyGltf(kTetraPositions, kTetraIndices);
  j["meshes"][0]["primitives"][0]["material"] = 0;
  j["materials"] =
      nlohmann::json::array({{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}},
                             {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 1}}}}}}});
  j["textures"] = nlohmann::json::array({{{"source", 0}}, {{"source", 1}}});
  j["images"] = nlohmann::json::array({{{"uri", "data:image/png;base64," + base64(huge)}},
                                       {{"uri", "data:image/png;base64," + base64(junk)}}});
  writeText(dir / "bad.gltf", j.dump());
  GltfImportReport report;
  GltfImportOptions options;
  options.report = &report;
  const TriangleMesh m = importGltf(dir / "bad.gltf", options);
  EXPECT_EQ(report.missingImages, 2u);
  EXPECT_TRUE(m.textures.empty());
  EXPECT_EQ(m.materials[0].albedoTexture, -1);
  EXPECT_EQ(m.materials[1].albedoTexture, -1);
}

// ---- errors ---------------------------------------------------------------------------------------------

TEST(GltfErrors, MissingFile) {
  const fs::path file = tmpDir("missing") / "nope.gltf";
  expectErrorNames(errorOf([&] { importGltf(file); }), file, "not found");
}

TEST(GltfErrors, JsonGarbage) {
  const fs::path dir = tmpDir("garbage");
  writeText(dir / "garbage.gltf", "this is { not json");
  expectErrorNames(errorOf([&] { importGltf(dir / "garbage.gltf"); }), dir / "garbage.gltf", "parse error");
  writeText(dir / "empty.gltf", "");
  expectErrorNames(errorOf([&] { importGltf(dir / "empty.gltf"); }), dir / "empty.gltf", "glTF");
  writeText(dir / "object.gltf", "{\"hello\": 1}");  // JSON, but no asset.version
  expectErrorNames(errorOf([&] { importGltf(dir / "object.gltf"); }), dir / "object.gltf", "glTF");
  writeText(dir / "bad.glb", std::string("glTF\x02\0\0\0", 8) + std::string(40, 'x'));
  expectErrorNames(errorOf([&] { importGltf(dir / "bad.glb"); }), dir / "bad.glb", "binary");
}

TEST(GltfErrors, MissingBufferFile) {
  const fs::path dir = tmpDir("nobin");
  fs::copy_file(kScenes / "box/Box.gltf", dir / "Box.gltf");
  const std::string msg = errorOf([&] { importGltf(dir / "Box.gltf"); });
  expectErrorNames(msg, dir / "Box.gltf", "Box0.bin");
  EXPECT_NE(msg.find("not found"), std::string::npos) << msg;
}

// A copy of Box.gltf + Box0.bin with the JSON edited by edit.
template <typename Edit>
fs::path editedBox(const std::string& name, Edit edit) {
  const fs::path dir = tmpDir(name);
  fs::copy_file(kScenes / "box/Box0.bin", dir / "Box0.bin");
  nlohmann::json j = nlohmann::json::parse(std::ifstream(kScenes / "box/Box.gltf"));
  edit(j);
  writeText(dir / "Box.gltf", j.dump());
  return dir / "Box.gltf";
}

TEST(GltfErrors, AccessorExceedsBufferView) {
  // POSITION: accessor 2 at offset 288 of the 576-byte bufferView 1; 30 x 12 bytes do not fit.
  const fs::path file =
      editedBox("accessor_range", [](nlohmann::json& j) { j["accessors"][2]["count"] = 30; });
  const std::string msg = errorOf([&] { importGltf(file); });
  expectErrorNames(msg, file, "out of range of bufferView 1");
  // A bufferView that runs past its buffer.
  const fs::path file2 =
      editedBox("view_range", [](nlohmann::json& j) { j["bufferViews"][1]["byteLength"] = 100000; });
  expectErrorNames(errorOf([&] { importGltf(file2); }), file2, "out of range of buffer 0");
  // A huge count must not allocate or overflow.
  const fs::path file3 =
      editedBox("huge_count", [](nlohmann::json& j) { j["accessors"][2]["count"] = 4611686018427387904ull; });
  expectErrorNames(errorOf([&] { importGltf(file3); }), file3, "out of range");
}

TEST(GltfErrors, IndexOutOfVertexRange) {
  // Box's indices reach vertex 23; declare only 20 vertices (all attributes, so the counts agree).
  const fs::path file = editedBox("index_range", [](nlohmann::json& j) {
    j["accessors"][1]["count"] = 20;
    j["accessors"][2]["count"] = 20;
  });
  const std::string msg = errorOf([&] { importGltf(file); });
  expectErrorNames(msg, file, "index");
  EXPECT_NE(msg.find("out of range (20 vertices)"), std::string::npos) << msg;
}

TEST(GltfErrors, AttributeCountMismatch) {
  const fs::path file = editedBox("uv_count", [](nlohmann::json& j) {
    j["accessors"].push_back({{"bufferView", 1}, {"componentType", 5126}, {"count", 10}, {"type", "VEC2"}});
    j["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = 3;
  });
  const std::string msg = errorOf([&] { importGltf(file); });
  expectErrorNames(msg, file, "TEXCOORD_0 has count 10, but POSITION has 24");
}

TEST(GltfErrors, NonFinitePosition) {
  const fs::path dir = tmpDir("nan");
  std::vector<float> p = kTetraPositions;
  p[4] = std::nanf("");
  writeText(dir / "nan.gltf", tinyGltf(p, kTetraIndices).dump());
  expectErrorNames(errorOf([&] { importGltf(dir / "nan.gltf"); }), dir / "nan.gltf", "not finite");
  // Finite in the file, infinite after the node transform.
  nlohmann::json j = tinyGltf(kTetraPositions, kTetraIndices);
  j["nodes"][0]["scale"] = {1e300, 1, 1};
  writeText(dir / "inf.gltf", j.dump());
  expectErrorNames(errorOf([&] { importGltf(dir / "inf.gltf"); }), dir / "inf.gltf", "not finite");
}

TEST(GltfErrors, NodeCycleAndBadReferences) {
  const fs::path dir = tmpDir("refs");
  nlohmann::json j = tinyGltf(kTetraPositions, kTetraIndices);
  j["nodes"] = nlohmann::json::array({{{"mesh", 0}, {"children", {1}}}, {{"children", {0}}}});
  writeText(dir / "cycle.gltf", j.dump());
  expectErrorNames(errorOf([&] { importGltf(dir / "cycle.gltf"); }), dir / "cycle.gltf", "reached twice");
  j = tinyGltf(kTetraPositions, kTetraIndices);
  j["meshes"][0]["primitives"][0]["material"] = 7;
  writeText(dir / "material.gltf", j.dump());
  expectErrorNames(errorOf([&] { importGltf(dir / "material.gltf"); }), dir / "material.gltf", "material 7");
  j = tinyGltf(kTetraPositions, kTetraIndices);
  j["extensionsUsed"] = {"KHR_draco_mesh_compression"};
  j["extensionsRequired"] = {"KHR_draco_mesh_compression"};
  writeText(dir / "draco.gltf", j.dump());
  expectErrorNames(errorOf([&] { importGltf(dir / "draco.gltf"); }), dir / "draco.gltf",
                   "KHR_draco_mesh_compression");
  GltfImportOptions badScale;
  badScale.scale = 0.0f;
  expectErrorNames(errorOf([&] { importGltf(kScenes / "box/Box.gltf", badScale); }), kScenes / "box/Box.gltf",
                   "scale");
}

// Wrong versions (docs/ARCHITECTURE.md "Bad input and interruption"): glTF 1.0 / 3.x JSON, a minVersion
// above 2.0 and a GLB container other than version 2 are refused by name instead of being read as 2.0.
TEST(GltfErrors, WrongVersionsAreRefused) {
  const fs::path dir = tmpDir("versions");
  for (const auto& [version, minVersion] :
       {std::pair<std::string, std::string>{"1.0", ""}, {"3.0", ""}, {"2.0", "2.1"}}) {
    nlohmann::json j = tinyGltf(kTetraPositions, kTetraIndices);
    j["asset"]["version"] = version;
    if (!minVersion.empty()) j["asset"]["minVersion"] = minVersion;
    const fs::path file = dir / ("v" + version + "_" + minVersion + ".gltf");
    writeText(file, j.dump());
    expectErrorNames(errorOf([&] { importGltf(file); }), file,
                     minVersion.empty() ? "asset.version '" + version : "asset.minVersion");
  }
  std::vector<char> glb = readBytes(kScenes / "cornell_box/CornellBox.glb");
  glb[4] = 1;
  writeBytes(dir / "v1.glb", glb.data(), glb.size());
  expectErrorNames(errorOf([&] { importGltf(dir / "v1.glb"); }), dir / "v1.glb", "container version 1");
}

// Every outcome of a damaged file must be an lfgi::Error naming the file, or a valid mesh.
void expectErrorOrValid(const fs::path& file, const std::string& label, size_t& errors) {
  try {
    const TriangleMesh m = importGltf(file);
    m.validate(label);
  } catch (const Error& e) {
    ++errors;
    EXPECT_EQ(std::string(e.what()).rfind(file.string(), 0), 0u) << label << ": " << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << label << ": not an lfgi::Error: " << e.what();
  }
}

TEST(GltfErrors, TruncatedFilesNeverCrash) {
  const fs::path dir = tmpDir("truncated");
  fs::copy_file(kScenes / "box/Box0.bin", dir / "Box0.bin");
  const std::vector<char> gltf = readBytes(kScenes / "box/Box.gltf");
  const std::vector<char> glb = readBytes(kScenes / "cornell_box/CornellBox.glb");
  const std::vector<char> bin = readBytes(kScenes / "box/Box0.bin");
  size_t errors = 0, cases = 0;
  constexpr int kCuts = 20;
  for (int i = 0; i < kCuts; ++i) {
    const size_t gltfCut = gltf.size() * size_t(i) / kCuts;
    writeBytes(dir / "Box.gltf", gltf.data(), gltfCut);
    expectErrorOrValid(dir / "Box.gltf", "Box.gltf cut at " + std::to_string(gltfCut), errors);
    const size_t glbCut = glb.size() * size_t(i) / kCuts + size_t(i % 3);  // also odd offsets
    writeBytes(dir / "Cornell.glb", glb.data(), std::min(glbCut, glb.size() - 1));
    expectErrorOrValid(dir / "Cornell.glb", "CornellBox.glb cut at " + std::to_string(glbCut), errors);
    cases += 2;
  }
  // Intact JSON with a truncated .bin.
  writeBytes(dir / "Box.gltf", gltf.data(), gltf.size());
  for (size_t cut : {size_t(0), size_t(1), bin.size() / 2, bin.size() - 1}) {
    writeBytes(dir / "Box0.bin", bin.data(), cut);
    expectErrorOrValid(dir / "Box.gltf", "Box0.bin cut at " + std::to_string(cut), errors);
    ++cases;
  }
  EXPECT_EQ(errors, cases) << "every truncation here breaks the file";
}

TEST(GltfErrors, CorruptedGlbNeverCrashes) {
  const fs::path dir = tmpDir("corrupt");
  const std::vector<char> glb = readBytes(kScenes / "cornell_box/CornellBox.glb");
  std::mt19937 rng(12345);
  size_t errors = 0;
  for (int i = 0; i < 300; ++i) {
    std::vector<char> bad = glb;
    const int flips = 1 + int(rng() % 4);
    for (int k = 0; k < flips; ++k) {
      const size_t at = rng() % bad.size();
      // Digits in the JSON chunk make plausible but wrong numbers; elsewhere any byte.
      bad[at] =
          (std::isdigit(static_cast<unsigned char>(bad[at])) ? char('0' + rng() % 10) : char(rng() % 256));
    }
    writeBytes(dir / "c.glb", bad.data(), bad.size());
    expectErrorOrValid(dir / "c.glb", "corruption " + std::to_string(i), errors);
  }
  std::printf("[ measure  ] corrupted CornellBox.glb: %zu of 300 rejected\n", errors);
}

// ---- export -------------------------------------------------------------------------------------------

TEST(GltfExport, CornellRoundTripIsExact) {
  GltfImportOptions options;
  options.scale = 0.001f;
  const TriangleMesh a = importGltf(kScenes / "cornell_box/CornellBox.glb", options);
  const fs::path file = tmpDir("roundtrip_cornell") / "sub" / "cornell.glb";
  exportGlb(file, a);
  EXPECT_FALSE(fs::exists(file.string() + ".tmp." + std::to_string(::getpid())));
  const TriangleMesh b = importGltf(file);
  EXPECT_EQ(b.triangleCount(), a.triangleCount());
  expectSameMaterials(a, b);
  for (uint32_t m = 0; m < a.materials.size(); ++m)
    EXPECT_EQ(trianglesOfMaterial(a, m), trianglesOfMaterial(b, m)) << "material " << m;
  EXPECT_EQ(b.bounds().min, a.bounds().min);
  EXPECT_EQ(b.bounds().max, a.bounds().max);
}

TEST(GltfExport, ThreeMaterialRoundTripIsBitExact) {
  TriangleMesh a;
  Material wall;
  wall.name = "wall";
  wall.albedo = {0.7f, 0.31f, 0.123456789f};
  wall.roughness = 0.37f;
  wall.metallic = 0.1f;
  Material lamp;
  lamp.name = "lamp";
  lamp.albedo = glm::vec3(0.9f);
  lamp.emission = {37.3f, 12.1f, 0.5f};  // needs KHR_materials_emissive_strength
  lamp.doubleSided = true;
  Material glow;
  glow.name = "glow";
  glow.emission = {0.25f, 0.5f, 1.0f};  // fits in emissiveFactor
  glow.roughness = 0.0f;
  glow.metallic = 1.0f;
  const uint32_t m0 = a.addMaterial(wall), m1 = a.addMaterial(lamp), m2 = a.addMaterial(glow);
  a.addBox({-1.1f, 0.0f, -2.3f}, {1.7f, 2.9f, 0.3f}, m0);
  a.addQuad({0.1f, 2.8f, 0.1f}, {0.3f, 2.8f, 0.1f}, {0.3f, 2.8f, 0.3f}, {0.1f, 2.8f, 0.3f}, m1);
  a.addTriangle({1e-7f, -3.4e7f, 1.0f / 3.0f}, {2.0f, 0.5f, 0.25f}, {-0.1f, 0.2f, 0.3f}, m2);
  a.uvs.resize(a.positions.size());
  for (size_t i = 0; i < a.uvs.size(); ++i) a.uvs[i] = {float(i) / 7.0f, 1.0f - float(i) / 3.0f};
  a.materials[0].category = SurfaceCategory::kImported;
  a.validate("three materials");

  const fs::path file = tmpDir("roundtrip3") / "three.glb";
  exportGlb(file, a);
  const std::vector<char> bytes = readBytes(file);
  ASSERT_GE(bytes.size(), 20u);
  EXPECT_EQ(std::string(bytes.data(), 4), "glTF");
  EXPECT_EQ(bytes.size() % 4, 0u);
  GltfImportReport report;
  GltfImportOptions options;
  options.report = &report;
  const TriangleMesh b = importGltf(file, options);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  EXPECT_EQ(b.triangleCount(), a.triangleCount());
  EXPECT_EQ(b.positions, a.positions);  // vertices were already grouped by material
  EXPECT_EQ(b.uvs, a.uvs);
  EXPECT_EQ(b.indices, a.indices);
  EXPECT_EQ(b.triangleMaterial, a.triangleMaterial);
  expectSameMaterials(a, b);
  EXPECT_EQ(b.contentHash(), a.contentHash());
}

TEST(GltfExport, EmptyMeshAndInvalidMesh) {
  const fs::path dir = tmpDir("export_edge");
  TriangleMesh empty;
  empty.addMaterial({});
  exportGlb(dir / "empty.glb", empty);
  const TriangleMesh back = importGltf(dir / "empty.glb");
  EXPECT_EQ(back.triangleCount(), 0u);
  EXPECT_EQ(back.materials.size(), 1u);

  TriangleMesh broken;
  broken.addTriangle({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 3);  // no such material
  expectErrorNames(errorOf([&] { exportGlb(dir / "broken.glb", broken); }), dir / "broken.glb", "material");
  EXPECT_FALSE(fs::exists(dir / "broken.glb"));
}

// ---- presets ------------------------------------------------------------------------------------------

bool strictlyInside(glm::vec3 p, const Aabb& b) {
  return p.x > b.min.x && p.y > b.min.y && p.z > b.min.z && p.x < b.max.x && p.y < b.max.y && p.z < b.max.z;
}

TEST(ScenePreset, CornellGridHasEightProbesInsideTheBox) {
  const ScenePreset& preset = findScenePreset("cornell");
  EXPECT_EQ(preset.relativePath, "cornell_box/CornellBox.glb");
  EXPECT_EQ(preset.scale, 0.001f);
  const Aabb bounds = loadScenePreset(preset, kScenes).bounds();
  const ProbeGrid grid = presetProbeGrid(preset, bounds);
  EXPECT_EQ(grid.probeCount(), 8);
  for (int64_t i = 0; i < grid.probeCount(); ++i)
    EXPECT_TRUE(strictlyInside(grid.probePosition(grid.probeCoord(i)), bounds)) << "probe " << i;
  // Cell-centred: a quarter of the box from each face.
  expectNear(grid.probePosition({0, 0, 0}), bounds.min + 0.25f * bounds.size(), 1e-6f, "first probe");
  expectNear(grid.probePosition({1, 1, 1}), bounds.max - 0.25f * bounds.size(), 1e-6f, "last probe");
}

TEST(ScenePreset, SponzaGridFromReadmeBounds) {
  const ScenePreset& preset = findScenePreset("sponza");
  EXPECT_EQ(preset.probeDims, glm::ivec3(18, 7, 11));
  Aabb bounds;
  bounds.extend({-26.845f, 2.282f, -16.478f});
  bounds.extend({24.177f, 23.617f, 14.900f});
  const ProbeGrid grid = presetProbeGrid(preset, bounds);
  EXPECT_EQ(grid.probeCount(), 1386);
  for (int64_t i = 0; i < grid.probeCount(); ++i)
    ASSERT_TRUE(strictlyInside(grid.probePosition(grid.probeCoord(i)), bounds)) << "probe " << i;
  const ProbeGrid again = presetProbeGrid(preset, bounds);
  EXPECT_EQ(again.origin, grid.origin);
  EXPECT_EQ(again.spacing, grid.spacing);
  EXPECT_NEAR(grid.spacing.x, (24.177 + 26.845) / 18.0, 1e-5);
}

TEST(ScenePreset, AllPresetsAndUnknownName) {
  for (const char* name : {"cornell", "sponza", "breakfast_room", "box"}) {
    const ScenePreset& p = findScenePreset(name);
    EXPECT_EQ(p.name, name);
    EXPECT_TRUE(fs::exists(kScenes / p.relativePath)) << p.relativePath;
  }
  EXPECT_EQ(findScenePreset("box").probeDims, glm::ivec3(2));
  const std::string msg = errorOf([] { findScenePreset("nope"); });
  for (const char* name : {"nope", "cornell", "sponza", "breakfast_room", "box"})
    EXPECT_NE(msg.find(name), std::string::npos) << msg;
}

TEST(ScenePreset, FlatAxisAndEmptyBounds) {
  ScenePreset flat{"flat", "", 1.0f, {3, 1, 2}};
  Aabb plane;
  plane.extend({0, 1, 0});
  plane.extend({3, 1, 2});
  const ProbeGrid grid = presetProbeGrid(flat, plane);
  EXPECT_EQ(grid.probePosition({0, 0, 0}), glm::vec3(0.5f, 1.0f, 0.5f));
  EXPECT_EQ(grid.probePosition({2, 0, 1}), glm::vec3(2.5f, 1.0f, 1.5f));
  errorOf([&] { presetProbeGrid(flat, Aabb{}); });
}

}  // namespace
}  // namespace lfgi::worlds
