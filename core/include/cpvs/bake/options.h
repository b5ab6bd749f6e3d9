// Every option of a bake: its enums with their explicit values (the same in the .cpvs
// header and in the farm's proto, checked by static_asserts in proto/farm_convert.cpp),
// their names on the command line and in JSON, and their bounds. A leaf header: it
// includes nothing of the pipeline, so the file format and the farm's contract can name
// the options without the bake.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>

#include "cpvs/base/limits.h"

namespace cpvs {

/// How closed geometry is recognised: per part from the mesh topology (auto), every
/// triangle (on: open meshes forced closed degrade gracefully, see texel_slices.h), none (off).
enum class ClosedMode : uint8_t { Auto = 0, On = 1, Off = 2 };

/// How the exit depth of closed geometry is found (§3.3).
enum class ExitMode : uint8_t {
  Exact = 0,   // count front (+1) and back (-1) faces from the enter hit until zero
  Approx = 1,  // first back face behind the enter hit (exact unless closed parts intersect)
};

/// How voxels in undefined regions get a value.
enum class UndefinedRule : uint8_t {
  New = 0,  // §3.4: per 8x8 column, the fewest masks that describe the transitions
  Old = 1,  // Sintorn et al.: lit or shadowed where homogeneous, else shadowed
  Aligned = 2,  // the new rule, each column wholly lit or shadowed in every 8-slice slab its texels allow
};

/// How the depth maps are rendered. Both follow the same classification and tie rules;
/// they differ only on texels whose ray grazes an edge or a slice boundary.
enum class Renderer : uint8_t {
  Embree = 0,  // a ray per texel through Embree's BVH (robust mode, float rays)
  Raster = 1,  // exact rasterization: snapped vertices, integer edge functions, top-left rule
};

enum class CompressMode : uint8_t {
  TopDown = 0,   // §4.2: dedupe from the roots down, never visiting subtrees of duplicates
  BottomUp = 1,  // §4.1: sort and dedupe every level from the leaves up
  None = 2,      // keep the DAG as inserted (duplicates remain; not canonical)
};

/// Which points may be queried (seed 004): every voxel no query can read is left to the
/// undefined rule. A receiver's normal is its surface's geometric normal (the side it is
/// seen from); a volume's dynamic receivers may have any normal.
enum class ReceiverKind : uint8_t {
  Everywhere = 0,        // any point outside closed solids (with any normal)
  Surfaces = 1,          // the front side of the scene's static surfaces (back faces culled)
  SurfacesTwoSided = 2,  // both sides of every open surface, the outside of closed parts
  Volume = 3,            // the front sides plus any point of a declared closed volume
  Cameras = 4,           // the sides cameras can see within a view distance (plus a volume)
};

/// How the sides that cameras see are found (ReceiverKind::Cameras).
enum class CameraVisibility : uint8_t {
  Faced = 0,    // every side a camera place faces within the view distance, occluders ignored: conservative
  Sampled = 1,  // the sides that rays from sampled camera positions hit first: smaller, not conservative between samples
};
/// Sampled camera visibility: rays per side of each cube face a camera position casts.
constexpr uint32_t kDefaultCameraRays = 128;
constexpr uint32_t kMaxCameraRays = 2048;

/// Hash functions for node content. Weak exists so tests can force collisions: every
/// algorithm must stay correct when different nodes share a hash.
enum class HashKind : uint8_t { Xxh3 = 0, WeakForTests = 1 };

/// Tile sizes, in texels a side: powers of two from 8 (one leaf) to the largest grid.
constexpr int kMinLog2TileSize = kLog2LeafSide;
constexpr int kMaxLog2TileSize = kMaxLog2Resolution;
constexpr int kDefaultLog2TileSize = 12;  // 4096 texels

/// The widest PCF filter of any lookup (normal_offset.h's kMaxPcfWidth, repeated for this
/// leaf header).
constexpr int kMaxPcfWidthOption = 9;

/// Everything that decides the bytes of a bake besides the scene, light and resolution.
struct BakeOptions {
  ClosedMode closed = ClosedMode::Auto;
  ExitMode exit = ExitMode::Exact;
  bool cull = true;
  CompressMode compress = CompressMode::TopDown;
  UndefinedRule undefinedRule = UndefinedRule::Aligned;
  int log2TileSize = kDefaultLog2TileSize;
  HashKind hash = HashKind::Xxh3;
  Renderer renderer = Renderer::Raster;
  ReceiverKind receivers = ReceiverKind::Everywhere;
  uint8_t receiverPcf = kMaxPcfWidthOption;  // the widest PCF filter receivers' lookups use
  constexpr bool operator==(const BakeOptions&) const = default;
};

/// The names of an option's values, indexed by value: the one table the command line,
/// JSON, the summary and the readers' bounds use.
template <class Option>
struct OptionNames;
template <>
struct OptionNames<ClosedMode> {
  static constexpr const char* kFlag = "closed";
  static constexpr std::array<const char*, 3> kNames{"auto", "on", "off"};
};
template <>
struct OptionNames<ExitMode> {
  static constexpr const char* kFlag = "exit";
  static constexpr std::array<const char*, 2> kNames{"exact", "approx"};
};
template <>
struct OptionNames<UndefinedRule> {
  static constexpr const char* kFlag = "undefined";
  static constexpr std::array<const char*, 3> kNames{"new", "old", "aligned"};
};
template <>
struct OptionNames<CompressMode> {
  static constexpr const char* kFlag = "compress";
  static constexpr std::array<const char*, 3> kNames{"topdown", "bottomup", "none"};
};
template <>
struct OptionNames<Renderer> {
  static constexpr const char* kFlag = "renderer";
  static constexpr std::array<const char*, 2> kNames{"embree", "raster"};
};
template <>
struct OptionNames<ReceiverKind> {
  static constexpr const char* kFlag = "receivers";
  static constexpr std::array<const char*, 5> kNames{"everywhere", "surfaces", "surfaces-two-sided", "volume",
                                                     "cameras"};
};
template <>
struct OptionNames<CameraVisibility> {
  static constexpr const char* kFlag = "camera-visibility";
  static constexpr std::array<const char*, 2> kNames{"faced", "sampled"};
};
template <>
struct OptionNames<HashKind> {
  static constexpr const char* kFlag = "hash";
  static constexpr std::array<const char*, 2> kNames{"xxh3", "weak-for-tests"};
};

/// The name of a value ("topdown").
template <class Option>
constexpr const char* optionName(Option value) {
  return OptionNames<Option>::kNames[size_t(value)];
}

/// True when `raw` is a value of the option (for readers of bytes and messages).
template <class Option>
constexpr bool isOptionValue(int64_t raw) {
  return raw >= 0 && raw < int64_t(OptionNames<Option>::kNames.size());
}

/// Throws the InputError of parseOption.
[[noreturn]] void throwUnknownOption(const std::string& what, std::string_view name, const std::string& accepted);

/// The value of a name; InputError naming `what` and the accepted names otherwise.
template <class Option>
Option parseOption(std::string_view name, const std::string& what) {
  const auto& names = OptionNames<Option>::kNames;
  for (size_t i = 0; i < names.size(); ++i)
    if (name == names[i]) return Option(i);
  std::string accepted;
  for (const char* n : names) accepted += (accepted.empty() ? "" : ", ") + std::string(n);
  throwUnknownOption(what, name, accepted);
}

/// log2 of a tile size in texels; InputError naming `what` unless a power of two in
/// [2^kMinLog2TileSize, 2^kMaxLog2TileSize].
int log2TileSizeOf(uint64_t texels, const std::string& what);

/// What the options say, one line: "closed auto, exit exact, cull on, ...".
std::string describe(const BakeOptions& options);

}  // namespace cpvs
