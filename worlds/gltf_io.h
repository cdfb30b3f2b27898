// glTF 2.0 import (.gltf / .glb → TriangleMesh), binary glTF export, and the test scenes' presets
// (file, unit scale, light-field probe grid size as in the paper's experiments).
//
// Import contract (importGltf):
//   - Reads the default scene (`scene`, else scene 0; a file with no scenes uses every root node).
//     Every mesh instance in the node tree is flattened into world space (node matrix, or T * R * S),
//     then multiplied by options.scale. Triangles are counter-clockwise from the front as in glTF; a
//     node with a negative-determinant world transform has its triangles' winding flipped so they keep
//     facing outward. Skins, morph targets, cameras and lights are ignored (rest pose).
//   - Primitive modes: TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN (strips and fans are converted to
//     triangles); POINTS and LINES* primitives are skipped and counted in GltfImportReport. Indexed and
//     non-indexed primitives; indices of any component type (ubyte, ushort, uint); sparse accessors.
//     Attributes read: POSITION (float VEC3), TEXCOORD_0 (float, or normalized ubyte / ushort VEC2).
//     Vertices are shared between primitives of one mesh instance that use the same POSITION and
//     TEXCOORD_0 accessors, and are not shared between instances.
//   - Materials: every glTF material becomes a Material at the same index, name kept, category
//     kImported: albedo = baseColorFactor.rgb (alpha and alphaMode are dropped: MASK/BLEND surfaces
//     import as opaque, with one warning listing them); albedoTexture = baseColorTexture decoded to
//     RGBA8 (an image that is missing or cannot be decoded, or a texture on TEXCOORD_n with n > 0, gives
//     a flat-colour material and a warning); emission = emissiveFactor *
//     KHR_materials_emissive_strength.emissiveStrength (emissive textures are ignored); roughness and
//     metallic factors (their textures are ignored); doubleSided. Primitives without a material use one
//     extra material "default" with glTF's default values (base colour 1, metallic 1, roughness 1),
//     appended after the file's materials.
//   - Only base-colour images are decoded (PNG, JPEG and the other stb_image formats, at most 16384 px
//     per side); 16-bit images are reduced to 8 bits; every texture is RGBA8.
//   - The result passes TriangleMesh::validate(). Cost: linear in the instanced vertex and index count
//     plus decoding the base-colour images (Sponza, 262k triangles, ~0.5 s on this machine).
//   - Errors: throws lfgi::Error whose message starts with the file path and names the problem: missing
//     or unreadable file, not glTF (tinygltf's parse errors and warnings are included), missing buffer
//     file, an accessor or bufferView out of range of its bufferView/buffer, an index referencing a
//     vertex out of range, attribute counts that differ from POSITION's, a non-finite position, a node
//     cycle, a required geometry extension (KHR_draco_mesh_compression, EXT_meshopt_compression,
//     KHR_mesh_quantization), an invalid options.scale. Malformed input never crashes the importer
//     (tested on truncated and corrupted files under ASan + UBSan).
//   Threading: importGltf and exportGlb share no state and may run concurrently on different files.
//
// Export contract (exportGlb): see below; textures are NOT exported.
#pragma once

#include <cstddef>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "core/probe_grid.h"
#include "worlds/mesh.h"

namespace lfgi::worlds {

// What importGltf skipped or degraded instead of failing. Each warning is one line of text.
struct GltfImportReport {
  size_t meshInstances = 0;       // mesh references in the flattened node tree
  size_t primitivesImported = 0;  // per instance
  size_t primitivesSkipped = 0;   // POINTS / LINES / LINE_LOOP / LINE_STRIP, or no POSITION
  size_t missingImages = 0;       // base-colour images that were absent or could not be decoded
  size_t imagesDecoded = 0;
  std::vector<std::string> warnings;  // tinygltf's warnings first, then ours
};

struct GltfImportOptions {
  // Uniform scale applied to world-space positions: the file's unit in metres (0.001 for the Cornell
  // box's millimetres). Must be finite and > 0.
  float scale = 1.0f;
  // Decode base-colour textures. When false, materials keep only their flat colours (faster).
  bool loadTextures = true;
  // If set, receives the counts and warnings of this import (overwritten).
  GltfImportReport* report = nullptr;
};

// Loads a .gltf (JSON, external or data-URI buffers and images) or .glb file; the format is chosen by
// the file's first four bytes ("glTF" magic = binary), not by its extension. See the contract above.
TriangleMesh importGltf(const std::filesystem::path& file, const GltfImportOptions& options = {});

// Writes mesh as binary glTF 2.0, atomically (temporary file + rename; parent folders are created).
// Layout: one buffer, one node, one mesh with one TRIANGLES primitive per material that has triangles
// (in material order; triangles keep their relative order within a material), each primitive with its
// own compacted vertices: POSITION (float VEC3, with min/max), TEXCOORD_0 (float VEC2, only when
// mesh.uvs is not empty) and uint32 indices. Every material is written in order (name, baseColorFactor
// = (albedo, 1), metallicFactor, roughnessFactor, doubleSided; emission as emissiveFactor when no
// component exceeds 1, else emissiveFactor = emission / max component with
// KHR_materials_emissive_strength = max component). Values are written unclamped.
// Not exported: textures (albedoTexture is dropped; re-import gives the flat albedo factor), material
// categories (re-import gives kImported). Re-importing the file gives the same triangles per material,
// bit-identical positions and uvs, and bit-identical material parameters.
// Throws lfgi::Error (naming file) if mesh fails validate(), a material parameter is not finite, or the
// file cannot be written; nothing is left under the final name then.
void exportGlb(const std::filesystem::path& file, const TriangleMesh& mesh);

// ---------------------------------------------------------------------------------------------------
// Scene presets: the test scenes shipped in the repository's assets/scenes (each folder has its SOURCE.md
// and licence; see assets/scenes/README.md) with the light-field probe grid sizes used for them:
//   cornell        cornell_box/CornellBox.glb     scale 0.001 (file in mm)  probes 2 x 2 x 2
//   sponza         sponza/Sponza.gltf             scale 1                   probes 18 x 7 x 11 (paper)
//   breakfast_room breakfast_room/BreakfastRoom.gltf scale 1                probes 8 x 6 x 9: the room is
//                  3.72 x 3.00 x 4.65 m, so cell-centred spacing is 0.46 x 0.50 x 0.52 m (~0.5 m)
//   box            box/Box.gltf                   scale 1                   probes 2 x 2 x 2
struct ScenePreset {
  std::string name;
  std::string relativePath;  // below the scenes folder
  float scale = 1.0f;        // GltfImportOptions::scale for the file
  glm::ivec3 probeDims{1};
};

// All presets, in a fixed order.
std::span<const ScenePreset> scenePresets();
// The folder the presets are read from by default: $LFGI_SCENES_DIR when set and not empty, else the
// source tree's assets/scenes (compiled in), so the CLI, benches and tests find the scenes from any
// working directory.
std::filesystem::path defaultScenesDir();
// The preset called name. Throws lfgi::Error listing the known names if there is none.
const ScenePreset& findScenePreset(std::string_view name);
// importGltf(scenesDir / preset.relativePath, {scale = preset.scale}).
TriangleMesh loadScenePreset(const ScenePreset& preset, const std::filesystem::path& scenesDir,
                             GltfImportReport* report = nullptr);

// Places preset.probeDims probes inside sceneBounds (metres, i.e. after the preset's scale), cell-centred:
// on each axis spacing = size / dims and the first probe sits at min + spacing / 2, so every probe lies
// strictly inside the bounds, half a spacing away from the faces, and the grid is symmetric about the
// bounds' centre. An axis of zero size gets spacing 1 m with the probes centred on it. Deterministic
// (pure float arithmetic on the inputs). Note that the grid's owned half-open box
// [origin, boxMax()) is the bounds shifted by spacing / 2. Throws lfgi::Error if the bounds are empty
// or not finite or a dim is < 1.
ProbeGrid presetProbeGrid(const ScenePreset& preset, const Aabb& sceneBounds);

}  // namespace lfgi::worlds
