// cpvs_runtime: what a game or a viewer links to use baked shadows. Open a .cpvs or a
// .dmh (or fetch a farm job's artifact into a local cache), upload its words to a Vulkan
// device as they are, and answer batches of shadow queries in a compute shader; or on
// the CPU, with the same answers, where no device exists. Links the query, dag, io and
// base layers and the farm client, never the baker. The C API (cpvs_runtime.h) wraps
// this for engines with C plugin interfaces.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "cpvs/base/vec3.h"
#include "cpvs/dag/packed_dag.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/psv/top_tree.h"
#include "cpvs/query/bundle_query.h"
#include "cpvs/query/dag_mh_query.h"
#include "cpvs/query/medium.h"
#include "cpvs/query/shadow_query.h"

// Vulkan handles as the application has them, without including vulkan.h here.
typedef struct VkInstance_T* VkInstance;
typedef struct VkPhysicalDevice_T* VkPhysicalDevice;
typedef struct VkDevice_T* VkDevice;

namespace cpvs::runtime {

/// Why a runtime call failed; the C API returns the same numbers (cpvs_runtime.h).
enum class Status : int {
  Ok = 0,
  InvalidArgument = 1,  // a null, out-of-range or inconsistent argument
  FileError = 2,        // a file cannot be read or written
  CorruptArtifact = 3,  // the bytes are not a valid .cpvs or .dmh (truncated, damaged, foreign)
  NoVulkan = 4,         // no Vulkan loader, or it has no usable driver
  NoDevice = 5,         // no device, none that matches the selection, or one without 64-bit floats
  DeviceLost = 6,       // the device stopped answering (driver reset, removal)
  OutOfMemory = 7,      // host or device memory
  FarmError = 8,        // the farm refused the request or could not be reached
  Internal = 9,
};

/// "no-device" and the like.
const char* statusName(Status s);

class RuntimeError : public std::runtime_error {
 public:
  RuntimeError(Status status, const std::string& what) : std::runtime_error(what), status_(status) {}
  Status status() const { return status_; }

 private:
  Status status_;
};

/// What a sun artifact holds: a CPVS (`.cpvs`, voxels), or a DAG-MH (`.dmh`, `cpvs bake
/// --format dagmh`: a shadow map that answers the declared receivers as the CPVS does).
enum class ArtifactKind { Cpvs, DagMh };

/// "cpvs" or "dagmh".
const char* artifactKindName(ArtifactKind kind);

/// A baked sun artifact opened for lookups, of either kind: its grid, the words a device
/// binds (as the file holds them) and the CPU reference over them. Immutable; share it
/// between devices.
class ShadowArtifact {
 public:
  /// Reads and validates a .cpvs or a .dmh file (told apart by their magic). FileError
  /// when it cannot be read, CorruptArtifact when it is not a valid artifact.
  static std::shared_ptr<const ShadowArtifact> open(const std::string& path);
  static std::shared_ptr<const ShadowArtifact> fromBytes(const std::vector<uint8_t>& bytes, const std::string& source);

  ArtifactKind kind() const { return dagMh_ ? ArtifactKind::DagMh : ArtifactKind::Cpvs; }
  const OrthoGrid& grid() const { return dagMh_ ? dagMh_->grid() : query_->grid(); }
  /// The words cpvs_shadow.glsl reads (CpvsWords): a CPVS's packed words, or a DAG-MH's
  /// (dag_mh_words.h; the shader then needs CPVS_DAG_MH).
  const std::vector<uint32_t>& words() const { return dagMh_ ? dagMhWords_ : query_->dag().words(); }
  /// Bytes of the shadows as stored: the CPVS's packed DAG, or the DAG-MH's structure,
  /// values and skip list.
  uint64_t bytes() const { return dagMh_ ? dagMh_->dag().bytes() : query_->dag().bytes(); }
  /// A CPVS's DAG and CPU reference; InvalidArgument for a DAG-MH.
  const PackedDag& packed() const { return cpu().dag(); }
  const ShadowQuery& cpu() const;
  /// A DAG-MH's CPU reference; InvalidArgument for a CPVS.
  const DagMhQuery& dagMh() const;
  /// Lit texels of the pcf x pcf footprint at (p, n) on the CPU, either kind.
  uint32_t litTexels(const Vec3& p, const Vec3& n, PcfWidth pcf) const {
    return dagMh_ ? dagMh_->litTexels(p, n, pcf) : query_->litTexels(p, n, pcf);
  }
  /// The TOP tree of the scene's translucent casters the file carries (glass, water,
  /// leaves on cards: left out of the CPVS), or null. The light reaching a receiver is
  /// the CPVS's visibility times their transmittance (cpuTransmittance,
  /// GpuShadows::transmittance).
  const TopTree* translucent() const { return translucent_.get(); }
  /// What cpvs_shadow.glsl's CpvsTranslucent binds (CPVS_TRANSLUCENT): a 64-byte header as
  /// DynamicCasters::gpuBytes' (its normal offset one texel of the grid) and the tree's
  /// nodes; and CpvsTransmittances, 3 floats a frustum. A tree of no frustum without one.
  std::vector<uint8_t> translucentGpuBytes() const;
  std::vector<uint8_t> transmittanceGpuBytes() const;

  /// InvalidArgument for a translucent casters' tree that is not linked, has no
  /// transmittance for each frustum, or is not for the grid's sun.
  explicit ShadowArtifact(ShadowQuery query, std::shared_ptr<const TopTree> translucent = nullptr);
  /// A DAG-MH; InvalidArgument when its words would not fit 32-bit indices.
  explicit ShadowArtifact(DagMhQuery query);

 private:
  std::optional<ShadowQuery> query_;
  std::optional<DagMhQuery> dagMh_;
  std::vector<uint32_t> dagMhWords_;
  std::shared_ptr<const TopTree> translucent_;
};

/// The sun's light reaching each (point, normal) through the artifact's translucent
/// casters, per channel (1, 1, 1 where none is in the way, and everywhere for an artifact
/// without them), on the CPU over all cores: TopTree::transmittanceAt at the point moved
/// one texel of the grid along its normal (normals empty: not moved), as the shader moves it.
void cpuTransmittance(const ShadowArtifact& artifact, const std::vector<Vec3>& points, const std::vector<Vec3>& normals,
                      std::vector<std::array<float, 3>>& out);

/// A light bundle opened for lookups: its lights, their grids, the one pool of words they
/// share (as the file holds it) and the CPU reference over them. Immutable.
class LightArtifact {
 public:
  /// Reads and validates a light bundle (.cpvs format 4). FileError when it cannot be
  /// read, CorruptArtifact when it is not a valid bundle (a single-light artifact is not).
  static std::shared_ptr<const LightArtifact> open(const std::string& path);
  static std::shared_ptr<const LightArtifact> fromBytes(const std::vector<uint8_t>& bytes, const std::string& source);

  const LightBundle& bundle() const { return bundle_; }
  size_t lightCount() const { return bundle_.lights.size(); }
  const BundleQuery& cpu() const { return query_; }

  explicit LightArtifact(LightBundle bundle) : bundle_(std::move(bundle)), query_(bundle_) {}

 private:
  LightBundle bundle_;
  BundleQuery query_;
};

/// A mesh that moves (a character, a vehicle, a door), placed for one frame.
struct CasterMesh {
  std::vector<Vec3> positions;    // in its own space
  std::vector<uint32_t> indices;  // 3 a triangle
  /// Empty, or one flag a triangle: part of a closed, outward-facing mesh, whose faces
  /// towards the light cast nothing that its far side does not (front-face culling).
  std::vector<uint8_t> closed;
  /// Where it is: world = [M | t] (p, 1), a row-major 3x4 affine transform.
  std::array<double, 12> transform{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};

  /// A point of its own space in the world.
  Vec3 place(const Vec3& p) const {
    const auto& m = transform;
    return {m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3], m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
            m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11]};
  }
};

/// What moves in one frame, casting exact hard shadows from an artifact's sun onto the
/// baked world and onto itself: the TOP tree of every placed mesh's shadow frusta
/// (partitioned shadow volumes, seed 003), built on the CPU, and how far off its surface
/// a receiver is asked (along its normal, against self-shadowing). Lookups with casters
/// answer V = V_cpvs * V_casters: a point in a caster's shadow has no lit texel.
class DynamicCasters {
 public:
  /// Where the tree is built: on the CPU here, or (Device) only its frusta here and their
  /// insertion by GpuShadows on its device (cpvs_caster_build.comp); the CPU then builds
  /// its own the first time it answers (the same frusta, so the same answers).
  enum class Build { Cpu, Device };
  /// InvalidArgument for an index out of range, a closed flag count that is not the
  /// triangles', a non-finite transform or offset. normalOffset < 0: one texel of the
  /// artifact's grid.
  DynamicCasters(const ShadowArtifact& artifact, const std::vector<CasterMesh>& meshes, double normalOffset = -1,
                 Build build = Build::Cpu);

  /// As built: linked (Build::Cpu) or its frusta alone (Build::Device).
  const TopTree& tree() const { return tree_; }
  double normalOffset() const { return normalOffset_; }
  size_t triangleCount() const { return triangles_; }
  /// Whether the point, moved normalOffset along n, is in a caster's shadow.
  bool shadowed(const Vec3& p, const Vec3& n) const;
  /// The bytes cpvs_shadow.glsl's CpvsCasters binds (CPVS_CASTERS): a 64-byte header
  /// (the origin and normal offset in doubles, the light, the query margins, the root)
  /// and the tree's 32-byte nodes (for Build::Device, the frusta to insert).
  std::vector<uint8_t> gpuBytes() const { return bytesOf(tree_); }
  /// The same of a linked tree, what an engine's shader walks (for Build::Device, the
  /// CPU's own, built now if it was not).
  std::vector<uint8_t> linkedGpuBytes() const { return bytesOf(linked()); }
  /// For Build::Device: what cpvs_caster_build.comp classifies with (the build's
  /// tolerance, a reserved double, then TopTree::corners()).
  std::vector<uint8_t> cornerBytes() const;

 private:
  const TopTree& linked() const;
  std::vector<uint8_t> bytesOf(const TopTree& tree) const;

  TopTree tree_;
  double normalOffset_ = 0;
  size_t triangles_ = 0;
  mutable std::once_flag linkOnce_;
  mutable std::unique_ptr<TopTree> cpuTree_;  // Build::Device: the CPU's own, made when first asked
};

/// What moves, casting exact hard shadows from a light bundle's lights: a TOP tree of
/// point-light frusta for each spot or point light whose reach (its grids' far) the
/// casters enter, built on the CPU; none for the others. An area light's VPLs get none:
/// soft lookups do not see dynamic casters.
class LightCasters {
 public:
  /// As DynamicCasters'; normalOffset < 0: for each light one texel of its first grid at
  /// its far plane.
  LightCasters(const LightArtifact& artifact, const std::vector<CasterMesh>& meshes, double normalOffset = -1);

  /// Light i's tree, or null.
  const TopTree* tree(size_t light) const { return trees_[light].get(); }
  double normalOffset(size_t light) const { return offsets_[light]; }
  size_t triangleCount() const { return triangles_; }
  /// Whether the point, moved light's normal offset along n, is in a caster's shadow.
  bool shadowed(size_t light, const Vec3& p, const Vec3& n) const;
  /// cpvs_shadow.glsl's CpvsLightCasters (CPVS_LIGHT_CASTERS): a 64-byte header a light,
  /// as CpvsCasters' with where its tree starts among the nodes (root 0: no tree), and
  /// CpvsLightCasterNodes, every tree's nodes one after another.
  std::vector<uint8_t> headerBytes() const;
  std::vector<uint8_t> nodeBytes() const;

 private:
  std::vector<std::unique_ptr<TopTree>> trees_;
  std::vector<double> offsets_;
  size_t triangles_ = 0;
};

/// Lit texel counts, on the CPU, of light lights[i] at each (point, normal), as
/// BundleQuery answers them, over all cores. One light per point (or one for all);
/// InvalidArgument for a light index out of range.
void cpuLightLitTexels(const LightArtifact& artifact, const std::vector<uint32_t>& lights,
                       const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
                       std::vector<uint32_t>& out, const LightCasters* casters = nullptr);

/// Soft visibility, on the CPU, of area light areas[i] (0-based; one per point, or one
/// for all) at each (point, normal), as BundleQuery::softVisibility answers it, over all
/// cores. InvalidArgument for an area index out of range.
void cpuSoftVisibility(const LightArtifact& artifact, const std::vector<uint32_t>& areas,
                       const std::vector<Vec3>& points, const std::vector<Vec3>& normals, std::vector<float>& out);

/// Fetches the artifact of a finished farm job into `cacheDir`, where it is kept under
/// its content hash (XXH3-128, 32 hex digits, ".cpvs", or ".dmh" for a DAG-MH), and
/// returns its path. A job
/// fetched before is answered from the cache, after checking the file against its hash,
/// without a call to the farm. An interrupted download resumes where it stopped.
/// FarmError when the farm refuses or cannot be reached (or the job is not done),
/// CorruptArtifact when what arrived does not match its checksum, FileError for the cache.
struct FarmAddress {
  std::string address;  // HOST:PORT of the coordinator
  std::string token;    // bearer token; empty = none
  std::string caFile;   // PEM roots to trust: TLS when set, plaintext otherwise
};
std::string fetchArtifact(const FarmAddress& farm, const std::string& jobId, const std::string& cacheDir,
                          bool* fromCache = nullptr);

/// Lit texel counts, on the CPU, for each (point, normal): ShadowQuery::litTexels over all
/// cores. normals empty (no offset) or one per point. With casters, 0 where they shadow
/// the point.
void cpuLitTexels(const ShadowArtifact& artifact, const std::vector<Vec3>& points, const std::vector<Vec3>& normals,
                  int pcf, std::vector<uint32_t>& out, const DynamicCasters* casters = nullptr);

/// How a device is picked and set up.
struct DeviceOptions {
  /// A device whose name contains this text; empty: the CPVS_DEVICE environment variable,
  /// else the first discrete GPU, then integrated, then virtual, then a CPU device.
  std::string select;
  /// Khronos validation layer on, its reports collected (also: CPVS_VALIDATION=1).
  bool validation = false;
  /// Split the words across storage bindings of at most this many bytes (0: the device's
  /// maxStorageBufferRange). For tests of the split on devices whose limit is large.
  uint64_t maxBindingBytes = 0;
  /// The Vulkan loader library (empty: CPVS_VULKAN_LOADER, else libvulkan.so.1).
  std::string loader;
};

/// A Vulkan device and queue for lookups: created headless by the library, or the
/// application's own (which must have been created with shaderFloat64 enabled and a
/// queue family with compute).
class GpuDevice {
 public:
  static std::unique_ptr<GpuDevice> create(const DeviceOptions& options = {});
  struct External {
    VkInstance instance = nullptr;
    VkPhysicalDevice physicalDevice = nullptr;
    VkDevice device = nullptr;
    uint32_t queueFamily = 0;
    void* getInstanceProcAddr = nullptr;  // PFN_vkGetInstanceProcAddr; null: the loader's
  };
  static std::unique_ptr<GpuDevice> adopt(const External& external, const DeviceOptions& options = {});
  ~GpuDevice();
  GpuDevice(const GpuDevice&) = delete;
  GpuDevice& operator=(const GpuDevice&) = delete;

  std::string name() const;
  /// "discrete GPU", "integrated GPU", "virtual GPU", "CPU" or "other".
  std::string type() const;
  uint64_t maxStorageBufferRange() const;
  /// Everything the validation layer reported (errors and warnings), when it is on.
  std::vector<std::string> validationMessages() const;
  /// Makes every later submission fail as a lost device does (VK_ERROR_DEVICE_LOST).
  void simulateDeviceLossForTests();

  struct Impl;
  Impl& impl() const { return *impl_; }

 private:
  explicit GpuDevice(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// An artifact uploaded to a device: the packed words in one device buffer (one copy,
/// no repacking), bound as one storage buffer, or as up to 8 where the array exceeds the
/// binding limit; the mapping in a uniform buffer.
class GpuShadows {
 public:
  GpuShadows(GpuDevice& device, std::shared_ptr<const ShadowArtifact> artifact);
  ~GpuShadows();
  GpuShadows(const GpuShadows&) = delete;
  GpuShadows& operator=(const GpuShadows&) = delete;

  /// Lit texel counts of the pcf x pcf footprint, as cpuLitTexels answers them (with the
  /// dynamic casters set, if any). DeviceLost (and nothing in `out`) when the device stops
  /// answering.
  void litTexels(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
                 std::vector<uint32_t>& out);
  /// This frame's dynamic casters (null: none), uploaded for the following litTexels calls,
  /// which then walk their tree on the device too (cpvs_shadow.glsl's cpvsCasterShadow, a
  /// stack of 32); the points whose walk needs a deeper stack are answered on the CPU.
  void setDynamicCasters(std::shared_ptr<const DynamicCasters> casters);
  /// How many points of the last litTexels call the CPU answered for the casters.
  size_t lastCasterOverflows() const;
  /// The light let through the artifact's translucent casters, as cpuTransmittance answers
  /// it to the bit (cpvs_shadow.glsl's cpvsTranslucentTransmittance, a stack of 64; the
  /// points whose walk needs more are answered on the CPU). DeviceLost when the device
  /// stops answering.
  void transmittance(const std::vector<Vec3>& points, const std::vector<Vec3>& normals,
                     std::vector<std::array<float, 3>>& out);
  /// How many points of the last transmittance call the CPU answered.
  size_t lastTranslucentOverflows() const;
  /// Device time of the last tree inserted on the device (DynamicCasters::Build::Device),
  /// ns, and the planes its invocations were classified against.
  double lastCasterBuildNanoseconds() const;
  uint64_t lastCasterBuildSteps() const;
  /// Device time of the lookups of the last litTexels call (GPU timestamps), ns.
  double lastDeviceNanoseconds() const;
  /// Segments from[i] -> to[i] walked through the sun's grid on the device
  /// (cpvs_shadow.glsl's cpvsSunSegment): each one's lit fraction, ShadowQuery::litFraction's
  /// to the bit, and the sun light the medium scatters towards from[i] per unit of sun
  /// irradiance (cpvsSunInScattering: ShadowQuery::inScattering in float). InvalidArgument
  /// for unequal counts or a bad medium; DeviceLost when the device stops answering.
  void segments(const std::vector<Vec3>& from, const std::vector<Vec3>& to, const Medium& medium,
                std::vector<double>& litFraction, std::vector<float>& inScattering);
  /// Device time of the walks of the last segments call (GPU timestamps), ns.
  double lastSegmentNanoseconds() const;
  int wordBindings() const;
  const ShadowArtifact& artifact() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

/// A light bundle uploaded to a device: the shared pool in one device buffer as the
/// file holds it (bound whole or split across up to 8 bindings), the light table, the
/// grid table and every grid's slice boundaries in three more (cpvs_shadow.glsl with
/// CPVS_LIGHTS reads exactly these; lightTable() and friends give an engine the bytes).
class GpuLights {
 public:
  GpuLights(GpuDevice& device, std::shared_ptr<const LightArtifact> artifact);
  ~GpuLights();
  GpuLights(const GpuLights&) = delete;
  GpuLights& operator=(const GpuLights&) = delete;

  /// Lit texel counts of light lights[i]'s pcf x pcf footprint at each (point, normal),
  /// as cpuLightLitTexels answers them. DeviceLost when the device stops answering.
  void litTexels(const std::vector<uint32_t>& lights, const std::vector<Vec3>& points,
                 const std::vector<Vec3>& normals, int pcf, std::vector<uint32_t>& out);
  /// This frame's dynamic casters (null: none), in every later litTexels: 0 where they
  /// shadow the point from that light (the points whose walk overflows the shader's stack
  /// are answered on the CPU).
  void setDynamicCasters(std::shared_ptr<const LightCasters> casters);
  size_t lastCasterOverflows() const;
  /// Soft visibility of area light areas[i] at each (point, normal) on the device
  /// (cpvs_shadow.glsl's cpvsSoftVisibility), as cpuSoftVisibility answers it to the bit.
  void softVisibility(const std::vector<uint32_t>& areas, const std::vector<Vec3>& points,
                      const std::vector<Vec3>& normals, std::vector<float>& out);
  double lastDeviceNanoseconds() const;
  int wordBindings() const;
  const LightArtifact& artifact() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

/// The uniform block CpvsSun that cpvs_shadow.glsl reads the sun's grid from, as bytes
/// (224: the 208-byte GpuGrid of gpu_grid.h, then log2BufferWords, the log2 of the words
/// per word buffer where the words are split, 0 where they are not).
std::vector<uint8_t> sunBlockBytes(const ShadowArtifact& artifact, uint32_t log2BufferWords);

/// The buffers cpvs_shadow.glsl's CPVS_LIGHTS section binds besides the pool, as bytes:
/// CpvsLights (64 bytes a light), CpvsGrids (8 bytes of header: log2BufferWords, the
/// log2 of the words per pool buffer where the pool is split, and the grid count; then
/// a 208-byte GpuGrid a grid, the record the sun's grid has too) and
/// CpvsSliceBoundaries (doubles).
std::vector<uint8_t> lightTableBytes(const LightBundle& bundle);
std::vector<uint8_t> gridTableBytes(const LightBundle& bundle, uint32_t log2BufferWords);
std::vector<uint8_t> sliceBoundaryBytes(const LightBundle& bundle);

/// Where lookups run.
enum class Backend { Auto, Gpu, Cpu };

/// The front most callers use: an artifact answered on a device when `backend` allows one
/// and one can be had, else on the CPU (Auto); Gpu fails instead of falling back.
class ShadowLookups {
 public:
  ShadowLookups(std::shared_ptr<const ShadowArtifact> artifact, Backend backend = Backend::Auto,
                const DeviceOptions& options = {});
  /// On the caller's device, which must outlive this (Cpu: the device is not used).
  ShadowLookups(std::shared_ptr<const ShadowArtifact> artifact, GpuDevice& device, Backend backend = Backend::Auto);
  ~ShadowLookups();

  bool onGpu() const { return gpu_ != nullptr; }
  /// The device's name, or "CPU (N threads)".
  std::string deviceName() const;
  /// Why the GPU is not used (empty when it is, or when the CPU was asked for).
  const std::string& fallbackReason() const { return fallbackReason_; }
  void litTexels(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf, std::vector<uint32_t>& out);
  /// This frame's dynamic casters (null: none), in every later lookup.
  void setDynamicCasters(std::shared_ptr<const DynamicCasters> casters);
  /// lit / pcf^2 (1 lit, 0 shadowed for pcf 1), as ShadowQuery::filtered.
  void visibility(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf, std::vector<float>& out);
  /// The light let through the artifact's translucent casters (GpuShadows::transmittance,
  /// cpuTransmittance): multiply visibility by it.
  void transmittance(const std::vector<Vec3>& points, const std::vector<Vec3>& normals,
                     std::vector<std::array<float, 3>>& out);
  /// Segments through the sun's grid (GpuShadows::segments), on the device or on the CPU
  /// (ShadowQuery::litFraction and inScattering, the latter rounded to float).
  void segments(const std::vector<Vec3>& from, const std::vector<Vec3>& to, const Medium& medium,
                std::vector<double>& litFraction, std::vector<float>& inScattering);
  const ShadowArtifact& artifact() const { return *artifact_; }
  GpuDevice* device() const { return device_; }

 private:
  /// Uploads to device_; on failure falls back to the CPU (Auto) or throws (Gpu).
  void upload();
  /// Runs `work` on the device, if there is one: false when there is none, or when it was
  /// lost now (Auto: the CPU answers from then on; Gpu: the error is thrown).
  bool onDevice(const std::function<void()>& work);

  std::shared_ptr<const ShadowArtifact> artifact_;
  std::unique_ptr<GpuDevice> ownDevice_;  // the one made here, when none was given
  GpuDevice* device_ = nullptr;
  std::unique_ptr<GpuShadows> gpu_;
  std::shared_ptr<const DynamicCasters> casters_;
  Backend backend_;
  std::string fallbackReason_;
};

/// Follows a farm's sun track: a background subscription (resumed after a lost
/// connection from the last version held) uploads each new version as it arrives, and
/// lookups for an instant answer the crossfade of the two versions around it:
/// (1 - w) * before + w * after, w = how far the instant is between their instants (for
/// a track of directions, instants are the versions' sequence numbers, in ms). A new
/// version is made ready beside the old ones and swapped in under a lock held only for
/// the swap: lookups never wait for an upload. Holds the newest three versions.
class TrackFollower {
 public:
  TrackFollower(FarmAddress farm, std::string trackId, Backend backend = Backend::Auto, const DeviceOptions& options = {});
  ~TrackFollower();
  TrackFollower(const TrackFollower&) = delete;
  TrackFollower& operator=(const TrackFollower&) = delete;

  /// Waits until at least `count` versions arrived or the timeout passed; returns how
  /// many arrived so far.
  uint64_t waitForVersions(uint64_t count, double timeoutSeconds);
  /// The last sequence received (the resume token).
  uint64_t lastSequence() const;
  /// Why the subscription last failed (empty while it is fine); it retries on its own.
  std::string lastError() const;
  /// Instants (Unix ms) of the versions held, oldest first.
  std::vector<int64_t> heldInstants() const;

  /// Visibility (lit fraction of the pcf x pcf footprint) at `instantMs`: the crossfade
  /// of the held versions around it, the nearest alone outside them. InvalidArgument when
  /// no version has arrived yet.
  void visibility(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf, int64_t instantMs,
                  std::vector<float>& out);

  struct Impl;

 private:
  std::shared_ptr<Impl> impl_;
};

}  // namespace cpvs::runtime
