// Timing one frame's lookups on a Vulkan device and on the CPU, and the frame files that
// carry a frame to a machine with a GPU (tests/gpu/device-check.sh): what bench_gpu_query
// and gpu_frame_timing share. Links the runtime only, so the program that runs on that
// machine carries no baker.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "cpvs/base/vec3.h"
#include "cpvs/query/light_tiles.h"
#include "cpvs/runtime/runtime.h"

namespace cpvs::bench {

/// The points of one frame and their normals.
struct Frame {
  std::vector<Vec3> points, normals;
};

/// A frame file: "CPVSFRM1", the point count (uint64), then per point its position as
/// three floats and its normal as three int8 (times 127). Positions and normals are
/// what the lookups of both paths read, so rounding them changes no comparison.
void writeFrame(const std::string& path, const Frame& frame);
Frame readFrame(const std::string& path);

/// A frame of many-light lookups as a camera sees it: the image size, and for each pixel
/// that sees the scene its index (row-major) and its point and normal (a Frame). Written
/// as the Frame file plus "CPVSFPX1", width and height (uint32) and a uint32 per point.
struct ManyLightFrame {
  int width = 0, height = 0;
  std::vector<uint32_t> pixels;
  Frame seen;
};
void writeManyLightFrame(const std::string& path, const ManyLightFrame& frame);
ManyLightFrame readManyLightFrame(const std::string& path);
/// Its lookups: tiled light culling over 16 x 16 tiles (cullLights), then one query per
/// pixel and light of its tile's list, in pixel order.
struct ManyLightQueries {
  std::vector<uint32_t> lights;
  Frame frame;
  LightTiles tiles;
};
ManyLightQueries manyLightQueries(const BundleQuery& query, const ManyLightFrame& frame);

/// A frame's dynamic casters, one mesh placed in the world: "CPVSCST1", the vertex and
/// triangle counts (uint64), the positions (3 doubles each), the indices (uint32), the
/// closed flags (a byte a triangle) and the transform (12 doubles).
void writeCasters(const std::string& path, const runtime::CasterMesh& mesh);
runtime::CasterMesh readCasters(const std::string& path);

/// A device for the timing, with a line saying which (or why none: CPU figures only).
std::unique_ptr<runtime::GpuDevice> openTimingDevice(const runtime::DeviceOptions& options);

/// The Markdown table's header and one pair of rows (binary, 9x9 PCF) for an artifact:
/// device time from GPU timestamps and wall time, CPU time, their ratio, and whether the
/// answers are identical. `device` may be null (CPU only).
void printTimingHeader();
void printTimingRows(const std::string& scene, const std::string& resolution, uint64_t dagBytes,
                     const std::shared_ptr<const runtime::ShadowArtifact>& artifact, const Frame& frame,
                     runtime::GpuDevice* device, int repeat);
void printTimingFooter();

/// The same for an artifact's frame with dynamic casters: their tree built on the CPU
/// (every core) and inserted on the device, then binary and 9x9 lookups times their
/// shadow on the device and on the CPU; medians over `repeat` frames, each building the
/// tree anew.
void printCasterTimingHeader();
void printCasterTimingRows(const std::string& name, const std::shared_ptr<const runtime::ShadowArtifact>& artifact,
                           const runtime::CasterMesh& casters, const Frame& frame, runtime::GpuDevice* device, int repeat);

/// The same for a light bundle's frame (one lookup per pixel and culled light): a table
/// of its own, binary and 9x9 PCF rows, device and CPU medians over `repeat` frames.
void printLightTimingHeader();
void printLightTimingRows(const std::string& name, const std::shared_ptr<const runtime::LightArtifact>& artifact,
                          const ManyLightQueries& queries, runtime::GpuDevice* device, int repeat);

}  // namespace cpvs::bench
