#include "worlds/gltf_io.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <map>
#include <new>
#include <optional>
#include <unordered_map>
#include <utility>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <nlohmann/json.hpp>

// tinygltf 2.7.0 is compiled into this file under a private namespace name. Debian ships it as
// libtinygltf.so, but libdraco.so.7 (linked into lfgi_worlds for surfels) embeds and exports its own,
// different tinygltf:: build; with both on the link line the dynamic linker binds tinygltf:: calls to
// whichever comes first, and the class layouts differ (the FS callbacks read as null). Renaming the
// namespace here makes every call bind to this copy. stb_image is compiled static (private to this
// file, so no clash with the stb_image_write in core/image.cpp); image writing is disabled because
// the exporter writes no textures and builds its GLB itself. Both headers live in /usr/include, so
// their warnings are suppressed as system headers.
#define tinygltf lfgi_tinygltf
#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_INCLUDE_STB_IMAGE
#define STB_IMAGE_STATIC
#define STBI_MAX_DIMENSIONS (1 << 14)  // larger images count as undecodable (flat colour + warning)
#define STB_IMAGE_IMPLEMENTATION
#include <stb/stb_image.h>
#include <tiny_gltf.h>

#include "core/error.h"
#include "core/file_util.h"

namespace lfgi::worlds {

namespace {

namespace fs = std::filesystem;

// An accessor with no bufferView is all zeros (plus sparse substitutions); cap its size so a few bytes
// of JSON cannot ask for gigabytes.
constexpr size_t kMaxZeroAccessorCount = size_t(1) << 24;

// Geometry-compression extensions: without them the file's geometry cannot be read at all.
constexpr std::array<std::string_view, 3> kUnsupportedGeometryExtensions = {
    "KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_mesh_quantization"};

std::string trimmed(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r' || s.back() == ' ')) s.pop_back();
  return s;
}

void appendLines(std::vector<std::string>& out, const std::string& text) {
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string line = trimmed(text.substr(start, end - start));
    if (!line.empty()) out.push_back(std::move(line));
    start = end + 1;
  }
}

std::string joinLines(const std::vector<std::string>& lines) {
  std::string s;
  for (const std::string& l : lines) {
    if (!s.empty()) s += "; ";
    s += l;
  }
  return s;
}

// Image loader for tinygltf: keeps the encoded bytes of URI images (decoding happens later, only for
// base-colour images). For bufferView images tinygltf passes a pointer computed from the bufferView
// without checking that it lies inside the buffer, so those bytes are ignored here and read later
// through the same range checks as accessors.
bool keepEncodedImage(tinygltf::Image* image, const int /*imageIndex*/, std::string* /*err*/,
                      std::string* /*warn*/, int /*reqWidth*/, int /*reqHeight*/, const unsigned char* bytes,
                      int size, void* /*user*/) {
  image->width = 0;
  image->height = 0;
  image->component = 0;
  image->bits = 0;
  if (image->bufferView < 0 && bytes != nullptr && size > 0) image->image.assign(bytes, bytes + size);
  return true;
}

size_t componentSize(int componentType) {
  switch (componentType) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return 4;
    default:
      return 0;
  }
}

std::string_view componentTypeName(int componentType) {
  switch (componentType) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
      return "byte";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return "unsigned byte";
    case TINYGLTF_COMPONENT_TYPE_SHORT:
      return "short";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return "unsigned short";
    case TINYGLTF_COMPONENT_TYPE_INT:
      return "int";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
      return "unsigned int";
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return "float";
    default:
      return "invalid";
  }
}

int typeComponents(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return 1;
    case TINYGLTF_TYPE_VEC2:
      return 2;
    case TINYGLTF_TYPE_VEC3:
      return 3;
    case TINYGLTF_TYPE_VEC4:
      return 4;
    case TINYGLTF_TYPE_MAT2:
      return 4;
    case TINYGLTF_TYPE_MAT3:
      return 9;
    case TINYGLTF_TYPE_MAT4:
      return 16;
    default:
      return 0;
  }
}

template <typename T>
T loadUnaligned(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

// One component of an attribute as float: float as is, normalized integers per glTF 2.0 §3.11.
float decodeFloatComponent(const uint8_t* p, int componentType) {
  switch (componentType) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return loadUnaligned<float>(p);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return float(*p) / 255.0f;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return float(loadUnaligned<uint16_t>(p)) / 65535.0f;
    case TINYGLTF_COMPONENT_TYPE_BYTE:
      return std::max(float(int8_t(*p)) / 127.0f, -1.0f);
    case TINYGLTF_COMPONENT_TYPE_SHORT:
      return std::max(float(loadUnaligned<int16_t>(p)) / 32767.0f, -1.0f);
    default:
      return 0.0f;
  }
}

uint32_t decodeIndex(const uint8_t* p, int componentType) {
  switch (componentType) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return *p;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return loadUnaligned<uint16_t>(p);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
      return loadUnaligned<uint32_t>(p);
    default:
      return 0;
  }
}

bool isFinite(glm::vec3 v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Reads one glTF file into a TriangleMesh. One instance per import; all errors go through fail().
class GltfImporter {
 public:
  GltfImporter(const fs::path& file, const GltfImportOptions& options, GltfImportReport& report)
      : file_(file), path_(file.string()), options_(options), report_(report) {}

  TriangleMesh run() {
    if (!std::isfinite(options_.scale) || options_.scale <= 0.0f)
      error(fmt::format("import scale {} must be finite and > 0", options_.scale));
    loadModel();
    checkExtensions();
    convertMaterials();
    traverseScene();
    if (!missingImageNames_.empty()) {
      report_.warnings.push_back(
          fmt::format("{} base-colour image(s) missing or undecodable, flat colour used: {}",
                      missingImageNames_.size(), joinLines(missingImageNames_)));
    }
    if (!alphaMaterials_.empty())
      report_.warnings.push_back(fmt::format("{} alpha-masked or blended material(s) imported as opaque: {}",
                                             alphaMaterials_.size(), joinLines(alphaMaterials_)));
    if (report_.primitivesSkipped > 0)
      report_.warnings.push_back(fmt::format(
          "{} primitive instance(s) skipped (points, lines, or no POSITION)", report_.primitivesSkipped));
    mesh_.validate(path_);
    return std::move(mesh_);
  }

 private:
  [[noreturn]] void error(const std::string& what) const { fail("{}: {}", path_, what); }

  void loadModel() {
    std::error_code ec;
    const fs::file_status status = fs::status(file_, ec);
    if (!fs::exists(status)) error("file not found");
    if (!fs::is_regular_file(status)) error("not a regular file");
    const std::vector<std::byte> bytes = readFileBytes(file_);
    if (bytes.size() >= std::numeric_limits<uint32_t>::max()) error("file is larger than 4 GiB");

    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(&keepEncodedImage, nullptr);
    const bool binary = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
    if (binary &&
        bytes.size() >= 8) {  // GLB header: magic, u32 container version (2 for glTF 2.0), u32 length
      uint32_t container = 0;
      std::memcpy(&container, bytes.data() + 4, 4);
      if (container != 2)
        error(fmt::format("binary glTF container version {} (this importer reads 2)", container));
    }
    std::string baseDir = file_.parent_path().string();
    if (baseDir.empty()) baseDir = ".";
    std::string err, warn;
    bool ok = false;
    try {
      if (binary) {
        ok = loader.LoadBinaryFromMemory(&model_, &err, &warn,
                                         reinterpret_cast<const unsigned char*>(bytes.data()),
                                         unsigned(bytes.size()), baseDir);
      } else {
        ok = loader.LoadASCIIFromString(&model_, &err, &warn, reinterpret_cast<const char*>(bytes.data()),
                                        unsigned(bytes.size()), baseDir);
      }
    } catch (const std::exception& e) {
      err += std::string("exception: ") + e.what();
      ok = false;
    }
    std::vector<std::string> tinyWarnings;
    appendLines(tinyWarnings, warn);
    if (!ok) {
      std::vector<std::string> errors;
      appendLines(errors, err);
      if (errors.empty()) errors.emplace_back("unknown tinygltf error");
      error(fmt::format("cannot load {} glTF: {}{}", binary ? "binary (.glb)" : "JSON (.gltf)",
                        joinLines(errors),
                        tinyWarnings.empty() ? "" : " (warnings: " + joinLines(tinyWarnings) + ")"));
    }
    report_.warnings = std::move(tinyWarnings);
    if (!err.empty()) appendLines(report_.warnings, err);  // non-fatal tinygltf complaints
    // glTF 2.0 spec, asset: a loader must refuse a major version it does not know, or a minVersion newer
    // than what it implements (tinygltf parses glTF 1.0 or 3.x JSON as if it were 2.0).
    const std::string& version = model_.asset.version;
    if (version.rfind("2.", 0) != 0)
      error(fmt::format("glTF asset.version '{}' (this importer reads 2.x)", version));
    const std::string& minVersion = model_.asset.minVersion;
    if (!minVersion.empty() && minVersion != "2.0")
      error(fmt::format("glTF asset.minVersion '{}' (this importer implements 2.0)", minVersion));
  }

  void checkExtensions() {
    for (const std::string& ext : model_.extensionsRequired) {
      for (std::string_view bad : kUnsupportedGeometryExtensions)
        if (ext == bad) error(fmt::format("requires extension {}, which is not supported", ext));
      if (ext != "KHR_materials_emissive_strength")
        report_.warnings.push_back(fmt::format("required extension {} is ignored", ext));
    }
  }

  // ---- buffers and accessors ----------------------------------------------------------------------

  // The bytes of count elements of elementSize bytes, stride apart, starting at byteOffset inside
  // bufferView viewIndex; every range is checked against its bufferView and buffer.
  const uint8_t* viewElements(int viewIndex, size_t byteOffset, size_t count, size_t elementSize,
                              size_t* stride, const std::string& what) const {
    if (viewIndex < 0 || size_t(viewIndex) >= model_.bufferViews.size())
      error(fmt::format("{}: bufferView {} does not exist ({} bufferViews)", what, viewIndex,
                        model_.bufferViews.size()));
    const tinygltf::BufferView& view = model_.bufferViews[size_t(viewIndex)];
    if (view.buffer < 0 || size_t(view.buffer) >= model_.buffers.size())
      error(fmt::format("{}: bufferView {} refers to buffer {} of {}", what, viewIndex, view.buffer,
                        model_.buffers.size()));
    const std::vector<unsigned char>& data = model_.buffers[size_t(view.buffer)].data;
    size_t viewEnd = 0;
    if (__builtin_add_overflow(view.byteOffset, view.byteLength, &viewEnd) || viewEnd > data.size())
      error(fmt::format("{}: bufferView {} (offset {}, length {}) is out of range of buffer {} ({} bytes)",
                        what, viewIndex, view.byteOffset, view.byteLength, view.buffer, data.size()));
    size_t step = view.byteStride != 0 ? view.byteStride : elementSize;
    if (step < elementSize)
      error(fmt::format("{}: bufferView {} byteStride {} is smaller than the element size {}", what,
                        viewIndex, view.byteStride, elementSize));
    if (stride) *stride = step;
    if (count == 0) return data.data() + view.byteOffset;
    size_t span = 0, end = 0;
    if (__builtin_mul_overflow(count - 1, step, &span) || __builtin_add_overflow(span, elementSize, &span) ||
        __builtin_add_overflow(span, byteOffset, &end) || end > view.byteLength)
      error(fmt::format(
          "{}: {} elements of {} bytes, stride {}, at offset {} are out of range of bufferView {} "
          "({} bytes)",
          what, count, elementSize, step, byteOffset, viewIndex, view.byteLength));
    return data.data() + view.byteOffset + byteOffset;
  }

  const tinygltf::Accessor& accessor(int index, const std::string& what) const {
    if (index < 0 || size_t(index) >= model_.accessors.size())
      error(
          fmt::format("{}: accessor {} does not exist ({} accessors)", what, index, model_.accessors.size()));
    return model_.accessors[size_t(index)];
  }

  // Reads count * components values of an accessor (with sparse substitution), decoding each
  // component with decode(bytes, componentType).
  template <typename T, typename Decode>
  std::vector<T> readAccessor(int index, const std::string& what, Decode decode) const {
    const tinygltf::Accessor& acc = accessor(index, what);
    const int components = typeComponents(acc.type);
    const size_t csize = componentSize(acc.componentType);
    if (components == 0 || csize == 0)
      error(fmt::format("{}: accessor {} has invalid type {} / component type {}", what, index, acc.type,
                        acc.componentType));
    const size_t elementSize = size_t(components) * csize;
    std::vector<T> out;
    if (acc.bufferView >= 0) {
      size_t stride = 0;
      const uint8_t* p = viewElements(acc.bufferView, acc.byteOffset, acc.count, elementSize, &stride,
                                      fmt::format("{} (accessor {})", what, index));
      out.resize(acc.count * size_t(components));
      T* dst = out.data();
      for (size_t i = 0; i < acc.count; ++i, p += stride)
        for (int c = 0; c < components; ++c) *dst++ = decode(p + size_t(c) * csize, acc.componentType);
    } else {
      if (acc.count > kMaxZeroAccessorCount)
        error(fmt::format("{}: accessor {} without bufferView has count {} (limit {})", what, index,
                          acc.count, kMaxZeroAccessorCount));
      out.assign(acc.count * size_t(components), T(0));
    }
    if (acc.sparse.isSparse) applySparse(acc, index, components, csize, what, decode, out);
    return out;
  }

  template <typename T, typename Decode>
  void applySparse(const tinygltf::Accessor& acc, int index, int components, size_t csize,
                   const std::string& what, Decode decode, std::vector<T>& out) const {
    const std::string sw = fmt::format("{} (sparse accessor {})", what, index);
    if (acc.sparse.count < 0 || size_t(acc.sparse.count) > acc.count)
      error(fmt::format("{}: sparse count {} exceeds accessor count {}", sw, acc.sparse.count, acc.count));
    if (acc.sparse.indices.byteOffset < 0 || acc.sparse.values.byteOffset < 0)
      error(fmt::format("{}: negative sparse byteOffset", sw));
    const size_t n = size_t(acc.sparse.count);
    const int ict = acc.sparse.indices.componentType;
    if (ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
      error(fmt::format("{}: sparse indices have component type {}", sw, ict));
    const size_t isize = componentSize(ict);
    const uint8_t* ip = viewElements(acc.sparse.indices.bufferView, size_t(acc.sparse.indices.byteOffset), n,
                                     isize, nullptr, sw);
    const size_t elementSize = size_t(components) * csize;
    const uint8_t* vp = viewElements(acc.sparse.values.bufferView, size_t(acc.sparse.values.byteOffset), n,
                                     elementSize, nullptr, sw);
    for (size_t k = 0; k < n; ++k) {
      const uint32_t target = decodeIndex(ip + k * isize, ict);
      if (target >= acc.count)
        error(fmt::format("{}: sparse index {} is out of range ({} elements)", sw, target, acc.count));
      for (int c = 0; c < components; ++c)
        out[size_t(target) * size_t(components) + size_t(c)] =
            decode(vp + k * elementSize + size_t(c) * csize, acc.componentType);
    }
  }

  const std::vector<glm::vec3>& positions(int index, const std::string& what) {
    auto it = positionCache_.find(index);
    if (it != positionCache_.end()) return it->second;
    const tinygltf::Accessor& acc = accessor(index, what);
    if (acc.type != TINYGLTF_TYPE_VEC3 || acc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
      error(
          fmt::format("{}: accessor {} must be float VEC3, is {} with type {} (KHR_mesh_quantization is not "
                      "supported)",
                      what, index, componentTypeName(acc.componentType), acc.type));
    std::vector<float> raw = readAccessor<float>(index, what, decodeFloatComponent);
    std::vector<glm::vec3> v(acc.count);
    for (size_t i = 0; i < acc.count; ++i) {
      v[i] = glm::vec3(raw[3 * i], raw[3 * i + 1], raw[3 * i + 2]);
      if (!isFinite(v[i])) error(fmt::format("{}: position {} is not finite", what, i));
    }
    return positionCache_.emplace(index, std::move(v)).first->second;
  }

  const std::vector<glm::vec2>& texcoords(int index, const std::string& what) {
    auto it = uvCache_.find(index);
    if (it != uvCache_.end()) return it->second;
    const tinygltf::Accessor& acc = accessor(index, what);
    const bool ok = acc.type == TINYGLTF_TYPE_VEC2 &&
                    (acc.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT ||
                     (acc.normalized && (acc.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
                                         acc.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT)));
    if (!ok)
      error(fmt::format(
          "{}: accessor {} must be VEC2 of float or normalized unsigned byte/short, is {}{} with "
          "type {}",
          what, index, acc.normalized ? "normalized " : "", componentTypeName(acc.componentType), acc.type));
    std::vector<float> raw = readAccessor<float>(index, what, decodeFloatComponent);
    std::vector<glm::vec2> v(acc.count);
    for (size_t i = 0; i < acc.count; ++i) {
      v[i] = glm::vec2(raw[2 * i], raw[2 * i + 1]);
      if (!std::isfinite(v[i].x) || !std::isfinite(v[i].y))
        error(fmt::format("{}: uv {} is not finite", what, i));
    }
    return uvCache_.emplace(index, std::move(v)).first->second;
  }

  std::vector<uint32_t> indexList(int index, const std::string& what) {
    const tinygltf::Accessor& acc = accessor(index, what);
    const int ct = acc.componentType;
    if (acc.type != TINYGLTF_TYPE_SCALAR ||
        (ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
         ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT))
      error(fmt::format("{}: accessor {} must be SCALAR unsigned byte/short/int, is {} with type {}", what,
                        index, componentTypeName(ct), acc.type));
    return readAccessor<uint32_t>(index, what, decodeIndex);
  }

  // ---- materials and textures ---------------------------------------------------------------------

  void convertMaterials() {
    for (size_t i = 0; i < model_.materials.size(); ++i) {
      const tinygltf::Material& src = model_.materials[i];
      const std::string what = fmt::format("material {} '{}'", i, src.name);
      Material m;
      m.name = src.name;
      if (src.alphaMode == "MASK" || src.alphaMode == "BLEND") alphaMaterials_.push_back(what);
      m.category = SurfaceCategory::kImported;
      const tinygltf::PbrMetallicRoughness& pbr = src.pbrMetallicRoughness;
      if (pbr.baseColorFactor.size() != 4)
        error(fmt::format("{}: baseColorFactor must have 4 numbers", what));
      m.albedo = glm::vec3(float(pbr.baseColorFactor[0]), float(pbr.baseColorFactor[1]),
                           float(pbr.baseColorFactor[2]));
      m.metallic = float(pbr.metallicFactor);
      m.roughness = float(pbr.roughnessFactor);
      m.doubleSided = src.doubleSided;
      double strength = 1.0;
      auto ext = src.extensions.find("KHR_materials_emissive_strength");
      if (ext != src.extensions.end() && ext->second.IsObject() && ext->second.Has("emissiveStrength")) {
        const tinygltf::Value& s = ext->second.Get("emissiveStrength");
        if (s.IsNumber() && std::isfinite(s.GetNumberAsDouble()) && s.GetNumberAsDouble() >= 0.0) {
          strength = s.GetNumberAsDouble();
        } else {
          report_.warnings.push_back(fmt::format("{}: invalid emissiveStrength ignored", what));
        }
      }
      if (src.emissiveFactor.size() != 3) error(fmt::format("{}: emissiveFactor must have 3 numbers", what));
      // In double, so that an exported factor * strength rounds back to the exact float emission.
      m.emission = glm::vec3(float(src.emissiveFactor[0] * strength), float(src.emissiveFactor[1] * strength),
                             float(src.emissiveFactor[2] * strength));
      const glm::vec4 params(m.albedo.x + m.albedo.y + m.albedo.z, m.emission.x + m.emission.y + m.emission.z,
                             m.metallic, m.roughness);
      if (!std::isfinite(params.x) || !std::isfinite(params.y) || !std::isfinite(params.z) ||
          !std::isfinite(params.w))
        error(fmt::format("{}: a material factor is not finite", what));
      if (options_.loadTextures && pbr.baseColorTexture.index >= 0)
        m.albedoTexture = baseColorTexture(pbr.baseColorTexture, what);
      mesh_.addMaterial(std::move(m));
    }
  }

  // Index into mesh_.textures, or -1 (flat colour) with a warning.
  int baseColorTexture(const tinygltf::TextureInfo& info, const std::string& what) {
    if (size_t(info.index) >= model_.textures.size())
      error(fmt::format("{}: baseColorTexture {} does not exist ({} textures)", what, info.index,
                        model_.textures.size()));
    if (info.texCoord != 0) {
      report_.warnings.push_back(
          fmt::format("{}: baseColorTexture uses TEXCOORD_{} (only TEXCOORD_0 is read); flat colour used",
                      what, info.texCoord));
      return -1;
    }
    const int source = model_.textures[size_t(info.index)].source;
    if (source < 0) {
      report_.warnings.push_back(
          fmt::format("{}: texture {} has no image source; flat colour used", what, info.index));
      return -1;
    }
    if (size_t(source) >= model_.images.size())
      error(fmt::format("{}: texture {} refers to image {} of {}", what, info.index, source,
                        model_.images.size()));
    auto cached = imageTexture_.find(source);
    if (cached != imageTexture_.end()) return cached->second;
    const int result = decodeImage(source);
    imageTexture_.emplace(source, result);
    return result;
  }

  int decodeImage(int imageIndex) {
    tinygltf::Image& img = model_.images[size_t(imageIndex)];
    const bool dataUri = img.uri.rfind("data:", 0) == 0;
    const std::string label =
        fmt::format("image {} '{}'", imageIndex, img.uri.empty() || dataUri ? img.name : img.uri);
    const unsigned char* bytes = img.image.data();
    size_t size = img.image.size();
    if (img.bufferView >= 0) {
      if (size_t(img.bufferView) >= model_.bufferViews.size())
        error(fmt::format("{}: bufferView {} does not exist", label, img.bufferView));
      const size_t length = model_.bufferViews[size_t(img.bufferView)].byteLength;
      bytes = viewElements(img.bufferView, 0, length == 0 ? 0 : 1, length, nullptr, label);
      size = length;
    }
    if (size == 0 || size > size_t(std::numeric_limits<int>::max())) {
      ++report_.missingImages;
      missingImageNames_.push_back(label);
      return -1;
    }
    tinygltf::Image decoded;
    std::string err, warn;
    bool ok = false;
    try {
      ok = tinygltf::LoadImageData(&decoded, imageIndex, &err, &warn, 0, 0, bytes, int(size), nullptr);
    } catch (const std::exception& e) {
      err += e.what();
    }
    const size_t pixels = size_t(std::max(decoded.width, 0)) * size_t(std::max(decoded.height, 0));
    const size_t bytesPerChannel = decoded.bits == 16 ? 2 : 1;
    if (!ok || decoded.component != 4 || (decoded.bits != 8 && decoded.bits != 16) || pixels == 0 ||
        decoded.image.size() != pixels * 4 * bytesPerChannel) {
      ++report_.missingImages;
      missingImageNames_.push_back(label + (err.empty() ? "" : " (" + trimmed(err) + ")"));
      return -1;
    }
    Texture tex;
    tex.width = decoded.width;
    tex.height = decoded.height;
    if (bytesPerChannel == 1) {
      tex.rgba = std::move(decoded.image);
    } else {
      tex.rgba.resize(pixels * 4);
      for (size_t i = 0; i < pixels * 4; ++i)
        tex.rgba[i] = uint8_t(loadUnaligned<uint16_t>(&decoded.image[2 * i]) >> 8);
    }
    img.image.clear();
    img.image.shrink_to_fit();
    ++report_.imagesDecoded;
    mesh_.textures.push_back(std::move(tex));
    return int(mesh_.textures.size() - 1);
  }

  uint32_t defaultMaterial() {
    if (!defaultMaterial_) {
      Material m;
      m.name = "default";
      m.albedo = glm::vec3(1.0f);
      m.metallic = 1.0f;
      m.roughness = 1.0f;
      defaultMaterial_ = mesh_.addMaterial(std::move(m));
    }
    return *defaultMaterial_;
  }

  // ---- node tree ----------------------------------------------------------------------------------

  glm::dmat4 localTransform(const tinygltf::Node& node, size_t nodeIndex) const {
    if (!node.matrix.empty()) {
      if (node.matrix.size() != 16) error(fmt::format("node {}: matrix must have 16 numbers", nodeIndex));
      return glm::make_mat4(node.matrix.data());  // glTF and glm are both column-major
    }
    glm::dmat4 m(1.0);
    if (!node.translation.empty()) {
      if (node.translation.size() != 3)
        error(fmt::format("node {}: translation must have 3 numbers", nodeIndex));
      m[3] = glm::dvec4(node.translation[0], node.translation[1], node.translation[2], 1.0);
    }
    if (!node.rotation.empty()) {
      if (node.rotation.size() != 4) error(fmt::format("node {}: rotation must have 4 numbers", nodeIndex));
      glm::dquat q(node.rotation[3], node.rotation[0], node.rotation[1],
                   node.rotation[2]);  // glTF: x, y, z, w
      const double len = glm::length(q);
      if (len > 0.0 && std::isfinite(len)) q /= len;
      m = m * glm::mat4_cast(q);
    }
    if (!node.scale.empty()) {
      if (node.scale.size() != 3) error(fmt::format("node {}: scale must have 3 numbers", nodeIndex));
      m = glm::scale(m, glm::dvec3(node.scale[0], node.scale[1], node.scale[2]));
    }
    return m;
  }

  void traverseScene() {
    std::vector<int> roots;
    if (!model_.scenes.empty()) {
      int scene = model_.defaultScene >= 0 ? model_.defaultScene : 0;
      if (size_t(scene) >= model_.scenes.size())
        error(fmt::format("default scene {} does not exist ({} scenes)", scene, model_.scenes.size()));
      roots = model_.scenes[size_t(scene)].nodes;
    } else {
      std::vector<bool> isChild(model_.nodes.size(), false);
      for (const tinygltf::Node& n : model_.nodes)
        for (int c : n.children)
          if (c >= 0 && size_t(c) < isChild.size()) isChild[size_t(c)] = true;
      for (size_t i = 0; i < model_.nodes.size(); ++i)
        if (!isChild[i]) roots.push_back(int(i));
    }
    // Depth-first with an explicit stack (deep chains must not overflow the call stack). Each node may
    // be reached once: a second visit means a node with two parents or a cycle, both invalid glTF.
    std::vector<bool> visited(model_.nodes.size(), false);
    std::vector<std::pair<int, glm::dmat4>> stack;
    for (auto it = roots.rbegin(); it != roots.rend(); ++it) stack.emplace_back(*it, glm::dmat4(1.0));
    while (!stack.empty()) {
      auto [index, parent] = stack.back();
      stack.pop_back();
      if (index < 0 || size_t(index) >= model_.nodes.size())
        error(fmt::format("node {} does not exist ({} nodes)", index, model_.nodes.size()));
      if (visited[size_t(index)])
        error(fmt::format("node {} is reached twice (cycle, or a node with two parents)", index));
      visited[size_t(index)] = true;
      const tinygltf::Node& node = model_.nodes[size_t(index)];
      const glm::dmat4 world = parent * localTransform(node, size_t(index));
      if (node.mesh >= 0) addMeshInstance(node.mesh, world);
      for (auto c = node.children.rbegin(); c != node.children.rend(); ++c) stack.emplace_back(*c, world);
    }
  }

  void addMeshInstance(int meshIndex, const glm::dmat4& world) {
    if (size_t(meshIndex) >= model_.meshes.size())
      error(fmt::format("mesh {} does not exist ({} meshes)", meshIndex, model_.meshes.size()));
    ++report_.meshInstances;
    const tinygltf::Mesh& gm = model_.meshes[size_t(meshIndex)];
    const bool flip = glm::determinant(world) < 0.0;
    const glm::dmat4 m = glm::scale(glm::dmat4(1.0), glm::dvec3(double(options_.scale))) * world;
    // Vertices shared between primitives of this instance that use the same accessors.
    std::map<std::pair<int, int>, uint32_t> vertexBase;
    for (size_t p = 0; p < gm.primitives.size(); ++p) {
      const tinygltf::Primitive& prim = gm.primitives[p];
      const std::string what = fmt::format("mesh {} '{}' primitive {}", meshIndex, gm.name, p);
      const bool triangles = prim.mode == TINYGLTF_MODE_TRIANGLES ||
                             prim.mode == TINYGLTF_MODE_TRIANGLE_STRIP ||
                             prim.mode == TINYGLTF_MODE_TRIANGLE_FAN;
      auto posIt = prim.attributes.find("POSITION");
      if (!triangles || posIt == prim.attributes.end()) {
        ++report_.primitivesSkipped;
        continue;
      }
      const std::vector<glm::vec3>& pos = positions(posIt->second, what + " POSITION");
      const size_t vertexCount = pos.size();
      for (const auto& [name, accIndex] : prim.attributes) {
        const tinygltf::Accessor& acc = accessor(accIndex, what + " " + name);
        if (acc.count != vertexCount)
          error(fmt::format("{}: attribute {} has count {}, but POSITION has {}", what, name, acc.count,
                            vertexCount));
      }
      auto uvIt = prim.attributes.find("TEXCOORD_0");
      const int uvAccessor = uvIt == prim.attributes.end() ? -1 : uvIt->second;
      const std::vector<glm::vec2>* uv =
          uvAccessor >= 0 ? &texcoords(uvAccessor, what + " TEXCOORD_0") : nullptr;

      std::vector<uint32_t> idx;
      if (prim.indices >= 0) {
        idx = indexList(prim.indices, what + " indices");
        for (size_t i = 0; i < idx.size(); ++i)
          if (idx[i] >= vertexCount)
            error(fmt::format("{}: index {} (entry {}) is out of range ({} vertices)", what, idx[i], i,
                              vertexCount));
      } else {
        idx.resize(vertexCount);
        for (size_t i = 0; i < vertexCount; ++i) idx[i] = uint32_t(i);
      }
      const std::vector<uint32_t> tris = assembleTriangles(idx, prim.mode, what);

      uint32_t material = 0;
      if (prim.material < 0) {
        material = defaultMaterial();
      } else if (size_t(prim.material) < model_.materials.size()) {
        material = uint32_t(prim.material);
      } else {
        error(fmt::format("{}: material {} does not exist ({} materials)", what, prim.material,
                          model_.materials.size()));
      }

      auto [baseIt, inserted] =
          vertexBase.try_emplace({posIt->second, uvAccessor}, uint32_t(mesh_.positions.size()));
      if (inserted) {
        if (mesh_.positions.size() + vertexCount > std::numeric_limits<uint32_t>::max())
          error("more than 2^32 vertices after instancing");
        if (uv && mesh_.uvs.empty()) mesh_.uvs.assign(mesh_.positions.size(), glm::vec2(0.0f));
        mesh_.positions.reserve(mesh_.positions.size() + vertexCount);
        for (const glm::vec3& v : pos) {
          const glm::vec3 w(m * glm::dvec4(glm::dvec3(v), 1.0));
          if (!isFinite(w)) error(fmt::format("{}: transformed position is not finite", what));
          mesh_.positions.push_back(w);
        }
        if (uv) {
          mesh_.uvs.insert(mesh_.uvs.end(), uv->begin(), uv->end());
        } else if (!mesh_.uvs.empty()) {
          mesh_.uvs.resize(mesh_.positions.size(), glm::vec2(0.0f));
        }
      }
      const uint32_t base = baseIt->second;
      mesh_.indices.reserve(mesh_.indices.size() + tris.size());
      for (size_t t = 0; t + 2 < tris.size(); t += 3) {
        // A mirroring transform turns counter-clockwise into clockwise: swap two corners to keep the front.
        mesh_.indices.push_back(base + tris[t]);
        mesh_.indices.push_back(base + tris[t + (flip ? 2 : 1)]);
        mesh_.indices.push_back(base + tris[t + (flip ? 1 : 2)]);
        mesh_.triangleMaterial.push_back(material);
      }
      ++report_.primitivesImported;
    }
  }

  // Triangle list (3 local indices per triangle) for a TRIANGLES / STRIP / FAN primitive; glTF 2.0 §3.7.2.1.
  std::vector<uint32_t> assembleTriangles(const std::vector<uint32_t>& idx, int mode,
                                          const std::string& what) {
    std::vector<uint32_t> out;
    if (mode == TINYGLTF_MODE_TRIANGLES) {
      if (idx.size() % 3 != 0)
        report_.warnings.push_back(fmt::format("{}: {} indices is not a multiple of 3; the last {} dropped",
                                               what, idx.size(), idx.size() % 3));
      out.assign(idx.begin(), idx.begin() + std::ptrdiff_t(idx.size() - idx.size() % 3));
    } else if (idx.size() >= 3) {
      out.reserve((idx.size() - 2) * 3);
      for (size_t i = 0; i + 2 < idx.size(); ++i) {
        if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
          // Odd strip triangles swap their first two corners to stay counter-clockwise.
          const bool odd = (i % 2) == 1;
          out.insert(out.end(), {idx[odd ? i + 1 : i], idx[odd ? i : i + 1], idx[i + 2]});
        } else {
          out.insert(out.end(), {idx[i + 1], idx[i + 2], idx[0]});
        }
      }
    }
    return out;
  }

  fs::path file_;
  std::string path_;
  GltfImportOptions options_;
  GltfImportReport& report_;
  tinygltf::Model model_;
  TriangleMesh mesh_;
  std::optional<uint32_t> defaultMaterial_;
  std::unordered_map<int, std::vector<glm::vec3>> positionCache_;
  std::unordered_map<int, std::vector<glm::vec2>> uvCache_;
  std::unordered_map<int, int> imageTexture_;
  std::vector<std::string> missingImageNames_;
  std::vector<std::string> alphaMaterials_;
};

// ---- GLB writer -------------------------------------------------------------------------------------

void appendU32(std::vector<std::byte>& out, uint32_t v) {
  static_assert(std::endian::native == std::endian::little, "GLB is little-endian");
  const auto* p = reinterpret_cast<const std::byte*>(&v);
  out.insert(out.end(), p, p + 4);
}

template <typename T>
size_t appendAligned(std::vector<std::byte>& bin, const std::vector<T>& values) {
  while (bin.size() % 4 != 0) bin.push_back(std::byte{0});
  const size_t offset = bin.size();
  const auto* p = reinterpret_cast<const std::byte*>(values.data());
  bin.insert(bin.end(), p, p + values.size() * sizeof(T));
  return offset;
}

nlohmann::json floats(std::initializer_list<float> values) {
  nlohmann::json a = nlohmann::json::array();
  for (float v : values) a.push_back(double(v));
  return a;
}

// The document's materials (and the emissive-strength extension where one needs it).
void addGlbMaterials(nlohmann::json& doc, const TriangleMesh& mesh, const std::string& path) {
  bool usesStrength = false;
  nlohmann::json materials = nlohmann::json::array();
  for (const Material& m : mesh.materials) {
    const float params[] = {m.albedo.x,   m.albedo.y,   m.albedo.z,  m.emission.x,
                            m.emission.y, m.emission.z, m.roughness, m.metallic};
    for (float v : params)
      if (!std::isfinite(v)) fail("{}: material '{}' has a non-finite parameter", path, m.name);
    nlohmann::json jm;
    jm["name"] = m.name;
    jm["pbrMetallicRoughness"] = {{"baseColorFactor", floats({m.albedo.x, m.albedo.y, m.albedo.z, 1.0f})},
                                  {"metallicFactor", double(m.metallic)},
                                  {"roughnessFactor", double(m.roughness)}};
    const float peak = std::max({m.emission.x, m.emission.y, m.emission.z});
    if (peak > 1.0f) {
      // glTF factors are in [0, 1]; the strength extension carries the rest. Division in double so that
      // the importer's factor * strength (also in double) rounds back to the same float.
      const double s = double(peak);
      jm["emissiveFactor"] = {double(m.emission.x) / s, double(m.emission.y) / s, double(m.emission.z) / s};
      jm["extensions"]["KHR_materials_emissive_strength"] = {{"emissiveStrength", s}};
      usesStrength = true;
    } else {
      jm["emissiveFactor"] = floats({m.emission.x, m.emission.y, m.emission.z});
    }
    jm["doubleSided"] = m.doubleSided;
    materials.push_back(std::move(jm));
  }
  if (!materials.empty()) doc["materials"] = std::move(materials);
  if (usesStrength) doc["extensionsUsed"] = {"KHR_materials_emissive_strength"};
}

// One primitive per material, its vertices renumbered in first-use order, with the buffer data in bin;
// and the scene.
void addGlbMeshes(nlohmann::json& doc, std::vector<std::byte>& bin, const TriangleMesh& mesh) {
  std::vector<std::vector<uint32_t>> trianglesOf(mesh.materials.size());
  for (size_t t = 0; t < mesh.triangleCount(); ++t)
    trianglesOf[mesh.triangleMaterial[t]].push_back(uint32_t(t));

  nlohmann::json views = nlohmann::json::array();
  nlohmann::json accessors = nlohmann::json::array();
  nlohmann::json primitives = nlohmann::json::array();
  auto addView = [&](size_t offset, size_t length, int target) {
    views.push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", length}, {"target", target}});
    return views.size() - 1;
  };
  std::vector<uint32_t> local(mesh.positions.size(), std::numeric_limits<uint32_t>::max());
  const bool withUvs = !mesh.uvs.empty();
  for (size_t mi = 0; mi < trianglesOf.size(); ++mi) {
    if (trianglesOf[mi].empty()) continue;
    std::vector<uint32_t> used;  // original vertex ids in first-use order
    std::vector<uint32_t> indices;
    indices.reserve(trianglesOf[mi].size() * 3);
    for (uint32_t t : trianglesOf[mi]) {
      for (int k = 0; k < 3; ++k) {
        const uint32_t v = mesh.indices[size_t(t) * 3 + size_t(k)];
        if (local[v] == std::numeric_limits<uint32_t>::max()) {
          local[v] = uint32_t(used.size());
          used.push_back(v);
        }
        indices.push_back(local[v]);
      }
    }
    std::vector<glm::vec3> pos(used.size());
    glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
    for (size_t i = 0; i < used.size(); ++i) {
      pos[i] = mesh.positions[used[i]];
      lo = glm::min(lo, pos[i]);
      hi = glm::max(hi, pos[i]);
    }
    nlohmann::json attributes;
    const size_t posView = addView(appendAligned(bin, pos), pos.size() * sizeof(glm::vec3), 34962);
    accessors.push_back({{"bufferView", posView},
                         {"componentType", TINYGLTF_COMPONENT_TYPE_FLOAT},
                         {"count", pos.size()},
                         {"type", "VEC3"},
                         {"min", floats({lo.x, lo.y, lo.z})},
                         {"max", floats({hi.x, hi.y, hi.z})}});
    attributes["POSITION"] = accessors.size() - 1;
    if (withUvs) {
      std::vector<glm::vec2> uv(used.size());
      for (size_t i = 0; i < used.size(); ++i) uv[i] = mesh.uvs[used[i]];
      const size_t uvView = addView(appendAligned(bin, uv), uv.size() * sizeof(glm::vec2), 34962);
      accessors.push_back({{"bufferView", uvView},
                           {"componentType", TINYGLTF_COMPONENT_TYPE_FLOAT},
                           {"count", uv.size()},
                           {"type", "VEC2"}});
      attributes["TEXCOORD_0"] = accessors.size() - 1;
    }
    const size_t idxView = addView(appendAligned(bin, indices), indices.size() * sizeof(uint32_t), 34963);
    accessors.push_back({{"bufferView", idxView},
                         {"componentType", TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT},
                         {"count", indices.size()},
                         {"type", "SCALAR"}});
    primitives.push_back(
        {{"attributes", attributes}, {"indices", accessors.size() - 1}, {"material", mi}, {"mode", 4}});
    for (uint32_t v : used) local[v] = std::numeric_limits<uint32_t>::max();
  }
  doc["scene"] = 0;
  if (primitives.empty()) {
    doc["scenes"] = nlohmann::json::array({nlohmann::json::object()});
  } else {
    doc["scenes"] = nlohmann::json::array({{{"nodes", {0}}}});
    doc["nodes"] = nlohmann::json::array({{{"mesh", 0}}});
    doc["meshes"] = nlohmann::json::array({{{"primitives", std::move(primitives)}}});
    doc["accessors"] = std::move(accessors);
    doc["bufferViews"] = std::move(views);
    doc["buffers"] = nlohmann::json::array({{{"byteLength", bin.size()}}});
  }
}

std::vector<std::byte> glbContainer(const nlohmann::json& doc, std::vector<std::byte>& bin,
                                    const std::string& path) {
  // GLB container, glTF 2.0 §4.4: 12-byte header, JSON chunk padded with spaces, BIN chunk padded with
  // zeros, every chunk 4-byte aligned.
  std::string json = doc.dump();
  while (json.size() % 4 != 0) json.push_back(' ');
  while (bin.size() % 4 != 0) bin.push_back(std::byte{0});
  const size_t total = 12 + 8 + json.size() + (bin.empty() ? 0 : 8 + bin.size());
  if (total > std::numeric_limits<uint32_t>::max()) fail("{}: mesh too large for a GLB file (> 4 GiB)", path);
  std::vector<std::byte> out;
  out.reserve(total);
  appendU32(out, 0x46546C67u);  // "glTF"
  appendU32(out, 2);
  appendU32(out, uint32_t(total));
  appendU32(out, uint32_t(json.size()));
  appendU32(out, 0x4E4F534Au);  // "JSON"
  const auto* jp = reinterpret_cast<const std::byte*>(json.data());
  out.insert(out.end(), jp, jp + json.size());
  if (!bin.empty()) {
    appendU32(out, uint32_t(bin.size()));
    appendU32(out, 0x004E4942u);  // "BIN\0"
    out.insert(out.end(), bin.begin(), bin.end());
  }
  return out;
}

}  // namespace

TriangleMesh importGltf(const std::filesystem::path& file, const GltfImportOptions& options) {
  GltfImportReport localReport;
  GltfImportReport& report = options.report ? *options.report : localReport;
  report = GltfImportReport{};
  try {
    return GltfImporter(file, options, report).run();
  } catch (const std::bad_alloc&) {
    fail("{}: out of memory while importing", file.string());
  } catch (const std::length_error& e) {
    fail("{}: data too large ({})", file.string(), e.what());
  }
}

void exportGlb(const std::filesystem::path& file, const TriangleMesh& mesh) {
  const std::string path = file.string();
  mesh.validate(path);
  if (mesh.positions.size() > std::numeric_limits<uint32_t>::max() / 4)
    fail("{}: mesh too large for glTF", path);

  nlohmann::json doc;
  doc["asset"] = {{"version", "2.0"}, {"generator", "lfgi exportGlb"}};
  addGlbMaterials(doc, mesh, path);
  std::vector<std::byte> bin;
  addGlbMeshes(doc, bin, mesh);
  writeFileAtomic(file, glbContainer(doc, bin, path));
}

// ---- scene presets ------------------------------------------------------------------------------------

std::span<const ScenePreset> scenePresets() {
  static const std::vector<ScenePreset> presets = {
      {"cornell", "cornell_box/CornellBox.glb", 0.001f, {2, 2, 2}},
      {"sponza", "sponza/Sponza.gltf", 1.0f, {18, 7, 11}},
      {"breakfast_room", "breakfast_room/BreakfastRoom.gltf", 1.0f, {8, 6, 9}},
      {"box", "box/Box.gltf", 1.0f, {2, 2, 2}},
  };
  return presets;
}

const ScenePreset& findScenePreset(std::string_view name) {
  std::string known;
  for (const ScenePreset& p : scenePresets()) {
    if (p.name == name) return p;
    known += (known.empty() ? "" : ", ") + p.name;
  }
  fail("unknown scene preset '{}' (known: {})", name, known);
}

std::filesystem::path defaultScenesDir() {
  const char* env = std::getenv("LFGI_SCENES_DIR");
  if (env != nullptr && env[0] != '\0') return env;
  return LFGI_SOURCE_SCENES_DIR;
}

TriangleMesh loadScenePreset(const ScenePreset& preset, const std::filesystem::path& scenesDir,
                             GltfImportReport* report) {
  GltfImportOptions options;
  options.scale = preset.scale;
  options.report = report;
  return importGltf(scenesDir / preset.relativePath, options);
}

ProbeGrid presetProbeGrid(const ScenePreset& preset, const Aabb& sceneBounds) {
  if (sceneBounds.empty()) fail("scene preset '{}': empty scene bounds", preset.name);
  if (!isFinite(sceneBounds.min) || !isFinite(sceneBounds.max))
    fail("scene preset '{}': scene bounds are not finite", preset.name);
  if (preset.probeDims.x < 1 || preset.probeDims.y < 1 || preset.probeDims.z < 1)
    fail("scene preset '{}': probe dims ({}, {}, {}) must be >= 1", preset.name, preset.probeDims.x,
         preset.probeDims.y, preset.probeDims.z);
  ProbeGrid grid;
  grid.dims = preset.probeDims;
  const glm::vec3 size = sceneBounds.max - sceneBounds.min;
  const glm::vec3 centre = 0.5f * (sceneBounds.min + sceneBounds.max);
  for (int a = 0; a < 3; ++a) {
    if (size[a] > 0.0f) {
      grid.spacing[a] = size[a] / float(grid.dims[a]);
      grid.origin[a] = sceneBounds.min[a] + 0.5f * grid.spacing[a];
    } else {
      grid.spacing[a] = 1.0f;
      grid.origin[a] = centre[a] - 0.5f * grid.spacing[a] * float(grid.dims[a] - 1);
    }
  }
  grid.validate();
  return grid;
}

}  // namespace lfgi::worlds
