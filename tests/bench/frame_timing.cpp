#include "frame_timing.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>

#include "cpvs/base/error.h"

namespace cpvs::bench {

namespace {

constexpr char kMagic[8] = {'C', 'P', 'V', 'S', 'F', 'R', 'M', '1'};
constexpr char kPixelsMagic[8] = {'C', 'P', 'V', 'S', 'F', 'P', 'X', '1'};
constexpr char kCastersMagic[8] = {'C', 'P', 'V', 'S', 'C', 'S', 'T', '1'};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

double millisecondsSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

std::string fixed(const char* fmt, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

int8_t quantize(double v) { return int8_t(std::lround(std::clamp(v, -1.0, 1.0) * 127)); }

}  // namespace

void writeFrame(const std::string& path, const Frame& f) {
  std::ofstream out(path, std::ios::binary);
  const uint64_t n = f.points.size();
  out.write(kMagic, 8);
  out.write(reinterpret_cast<const char*>(&n), 8);
  for (uint64_t i = 0; i < n; ++i) {
    const float p[3] = {float(f.points[i].x), float(f.points[i].y), float(f.points[i].z)};
    const Vec3 nn = f.normals.empty() ? Vec3{} : f.normals[i];
    const int8_t q[3] = {quantize(nn.x), quantize(nn.y), quantize(nn.z)};
    out.write(reinterpret_cast<const char*>(p), sizeof p);
    out.write(reinterpret_cast<const char*>(q), sizeof q);
  }
  if (!out) throw InputError("cannot write " + path);
}

Frame readFrame(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[8];
  uint64_t n = 0;
  if (!in.read(magic, 8) || std::memcmp(magic, kMagic, 8) != 0 || !in.read(reinterpret_cast<char*>(&n), 8))
    throw InputError(path + ": not a frame file");
  if (n > (uint64_t(1) << 28)) throw InputError(path + ": " + std::to_string(n) + " points is too many");
  Frame f;
  f.points.resize(n);
  f.normals.resize(n);
  for (uint64_t i = 0; i < n; ++i) {
    float p[3];
    int8_t q[3];
    if (!in.read(reinterpret_cast<char*>(p), sizeof p) || !in.read(reinterpret_cast<char*>(q), sizeof q))
      throw InputError(path + ": truncated at point " + std::to_string(i));
    f.points[i] = {p[0], p[1], p[2]};
    f.normals[i] = {q[0] / 127.0, q[1] / 127.0, q[2] / 127.0};
  }
  return f;
}

void writeManyLightFrame(const std::string& path, const ManyLightFrame& f) {
  writeFrame(path, f.seen);
  std::ofstream out(path, std::ios::binary | std::ios::app);
  const uint32_t size[2] = {uint32_t(f.width), uint32_t(f.height)};
  out.write(kPixelsMagic, 8);
  out.write(reinterpret_cast<const char*>(size), 8);
  out.write(reinterpret_cast<const char*>(f.pixels.data()), std::streamsize(f.pixels.size() * 4));
  if (!out) throw InputError("cannot write " + path);
}

ManyLightFrame readManyLightFrame(const std::string& path) {
  ManyLightFrame f;
  f.seen = readFrame(path);
  std::ifstream in(path, std::ios::binary);
  in.seekg(std::streamoff(16 + 15 * f.seen.points.size()));
  char magic[8];
  uint32_t size[2] = {0, 0};
  if (!in.read(magic, 8) || std::memcmp(magic, kPixelsMagic, 8) != 0 || !in.read(reinterpret_cast<char*>(size), 8) ||
      size[0] == 0 || size[1] == 0 || size[0] > 16384 || size[1] > 16384)
    throw InputError(path + ": not a many-light frame (no image size)");
  f.width = int(size[0]), f.height = int(size[1]);
  f.pixels.resize(f.seen.points.size());
  if (!in.read(reinterpret_cast<char*>(f.pixels.data()), std::streamsize(f.pixels.size() * 4)))
    throw InputError(path + ": truncated pixel indices");
  for (uint32_t i : f.pixels)
    if (uint64_t(i) >= uint64_t(f.width) * uint64_t(f.height)) throw InputError(path + ": a pixel index outside the image");
  return f;
}

ManyLightQueries manyLightQueries(const BundleQuery& query, const ManyLightFrame& f) {
  const size_t n = size_t(f.width) * size_t(f.height);
  std::vector<Vec3> points(n), normals(n);
  std::vector<uint8_t> hit(n, 0);
  for (size_t k = 0; k < f.pixels.size(); ++k) {
    points[f.pixels[k]] = f.seen.points[k], normals[f.pixels[k]] = f.seen.normals[k];
    hit[f.pixels[k]] = 1;
  }
  ManyLightQueries q;
  q.tiles = cullLights(query, points, hit, f.width, f.height, 16, 64);
  const LightTiles& tiles = q.tiles;
  for (size_t i = 0; i < n; ++i) {
    if (!hit[i]) continue;
    const size_t tile = tiles.tile(int(i % size_t(f.width)), int(i / size_t(f.width)));
    for (uint32_t k = tiles.begin[tile]; k < tiles.begin[tile + 1]; ++k) {
      q.lights.push_back(tiles.lights[k]);
      q.frame.points.push_back(points[i]);
      q.frame.normals.push_back(normals[i]);
    }
  }
  return q;
}

std::unique_ptr<runtime::GpuDevice> openTimingDevice(const runtime::DeviceOptions& options) {
  try {
    auto device = runtime::GpuDevice::create(options);
    std::printf("Device: %s (%s), maxStorageBufferRange %llu bytes\n", device->name().c_str(), device->type().c_str(),
                static_cast<unsigned long long>(device->maxStorageBufferRange()));
    return device;
  } catch (const runtime::RuntimeError& e) {
    std::printf("Device: none (%s); CPU figures only\n", e.what());
    return nullptr;
  }
}

void printTimingHeader() {
  std::printf("| scene | R | DAG | array | queries | lookup | device ms/frame | ns/query | Mq/s | wall ms | CPU ms/frame | CPU ns/query | device/CPU | answers |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
}

void printTimingRows(const std::string& scene, const std::string& resolution, uint64_t dagBytes,
                     const std::shared_ptr<const runtime::ShadowArtifact>& artifact, const Frame& frame,
                     runtime::GpuDevice* device, int repeat) {
  std::unique_ptr<runtime::GpuShadows> gpu;
  if (device) gpu = std::make_unique<runtime::GpuShadows>(*device, artifact);
  const double n = double(frame.points.size());
  for (int pcf : {1, 9}) {
    std::vector<uint32_t> onCpu, onGpu;
    runtime::cpuLitTexels(*artifact, frame.points, frame.normals, pcf, onCpu);  // warm-up, and the reference
    std::vector<double> cpuMs, devMs, wallMs;
    for (int r = 0; r < repeat; ++r) {
      const auto t = std::chrono::steady_clock::now();
      runtime::cpuLitTexels(*artifact, frame.points, frame.normals, pcf, onCpu);
      cpuMs.push_back(millisecondsSince(t));
    }
    std::string answers = "CPU only";
    if (gpu) {
      gpu->litTexels(frame.points, frame.normals, pcf, onGpu);  // warm-up
      uint64_t differ = 0;
      for (size_t i = 0; i < onCpu.size(); ++i) differ += onGpu[i] != onCpu[i];
      answers = differ == 0 ? "identical" : std::to_string(differ) + " differ";
      for (int r = 0; r < repeat; ++r) {
        const auto t = std::chrono::steady_clock::now();
        gpu->litTexels(frame.points, frame.normals, pcf, onGpu);
        wallMs.push_back(millisecondsSince(t));
        devMs.push_back(gpu->lastDeviceNanoseconds() * 1e-6);
      }
    }
    const double cpu = median(cpuMs), dev = median(devMs);
    auto mib = [](uint64_t b) { return fixed("%.2f MiB", double(b) / (1 << 20)); };
    std::printf("| %s | %s | %s | %s | %.0f | %s | %s | %s | %s | %s | %s | %s | %s | %s |\n", scene.c_str(),
                resolution.c_str(), mib(dagBytes).c_str(), mib(artifact->words().size() * 4).c_str(), n,
                pcf == 1 ? "binary" : "9x9 PCF", gpu ? fixed("%.3f", dev).c_str() : "-",
                gpu ? fixed("%.2f", dev * 1e6 / n).c_str() : "-", gpu ? fixed("%.0f", n / (dev * 1e3)).c_str() : "-",
                gpu ? fixed("%.1f", median(wallMs)).c_str() : "-", fixed("%.1f", cpu).c_str(),
                fixed("%.1f", cpu * 1e6 / n).c_str(), gpu ? fixed("%.2fx", cpu / dev).c_str() : "-", answers.c_str());
    std::fflush(stdout);
  }
}

void writeCasters(const std::string& path, const runtime::CasterMesh& m) {
  std::ofstream out(path, std::ios::binary);
  const uint64_t counts[2] = {m.positions.size(), m.indices.size() / 3};
  out.write(kCastersMagic, 8);
  out.write(reinterpret_cast<const char*>(counts), sizeof counts);
  out.write(reinterpret_cast<const char*>(m.positions.data()), std::streamsize(m.positions.size() * sizeof(Vec3)));
  out.write(reinterpret_cast<const char*>(m.indices.data()), std::streamsize(m.indices.size() * 4));
  std::vector<uint8_t> closed = m.closed;
  closed.resize(counts[1], 0);
  out.write(reinterpret_cast<const char*>(closed.data()), std::streamsize(closed.size()));
  out.write(reinterpret_cast<const char*>(m.transform.data()), sizeof(double) * 12);
  if (!out) throw InputError(path + ": cannot be written");
}

runtime::CasterMesh readCasters(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[8];
  uint64_t counts[2] = {0, 0};
  if (!in.read(magic, 8) || std::memcmp(magic, kCastersMagic, 8) != 0 || !in.read(reinterpret_cast<char*>(counts), 16))
    throw InputError(path + ": not a casters file");
  if (counts[0] > (uint64_t(1) << 26) || counts[1] > (uint64_t(1) << 26)) throw InputError(path + ": too many vertices or triangles");
  runtime::CasterMesh m;
  m.positions.resize(counts[0]);
  m.indices.resize(3 * counts[1]);
  m.closed.resize(counts[1]);
  in.read(reinterpret_cast<char*>(m.positions.data()), std::streamsize(m.positions.size() * sizeof(Vec3)));
  in.read(reinterpret_cast<char*>(m.indices.data()), std::streamsize(m.indices.size() * 4));
  in.read(reinterpret_cast<char*>(m.closed.data()), std::streamsize(m.closed.size()));
  if (!in.read(reinterpret_cast<char*>(m.transform.data()), sizeof(double) * 12)) throw InputError(path + ": truncated");
  return m;
}

void printCasterTimingHeader() {
  std::printf("| frame | caster triangles | frusta | filter | CPU build ms | device build ms | device lookups ms | "
              "device build + lookups ms | CPU lookups ms | CPU overflow answers | answers |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
}

void printCasterTimingRows(const std::string& name, const std::shared_ptr<const runtime::ShadowArtifact>& artifact,
                           const runtime::CasterMesh& mesh, const Frame& frame, runtime::GpuDevice* device, int repeat) {
  using runtime::DynamicCasters;
  std::unique_ptr<runtime::GpuShadows> gpu;
  if (device) gpu = std::make_unique<runtime::GpuShadows>(*device, artifact);
  const std::vector<runtime::CasterMesh> meshes{mesh};
  std::vector<double> buildMs;
  std::shared_ptr<const DynamicCasters> onCpu;
  for (int r = 0; r < repeat; ++r) {
    const auto t = std::chrono::steady_clock::now();
    onCpu = std::make_shared<const DynamicCasters>(*artifact, meshes);
    buildMs.push_back(millisecondsSince(t));
  }
  for (int pcf : {1, 9}) {
    std::vector<uint32_t> want, got;
    std::vector<double> cpuMs, devBuildMs, devMs;
    for (int r = 0; r < repeat; ++r) {
      const auto t = std::chrono::steady_clock::now();
      runtime::cpuLitTexels(*artifact, frame.points, frame.normals, pcf, want, onCpu.get());
      cpuMs.push_back(millisecondsSince(t));
    }
    std::string answers = "CPU only";
    size_t overflows = 0;
    if (gpu) {
      for (int r = 0; r < repeat; ++r) {
        auto frusta = std::make_shared<const DynamicCasters>(*artifact, meshes, -1, DynamicCasters::Build::Device);
        gpu->setDynamicCasters(frusta);
        gpu->litTexels(frame.points, frame.normals, pcf, got);
        devBuildMs.push_back(gpu->lastCasterBuildNanoseconds() * 1e-6);
        devMs.push_back(gpu->lastDeviceNanoseconds() * 1e-6);
        overflows = gpu->lastCasterOverflows();
      }
      uint64_t differ = 0;
      for (size_t i = 0; i < want.size(); ++i) differ += got[i] != want[i];
      answers = differ == 0 ? "identical" : std::to_string(differ) + " differ";
    }
    const double build = median(devBuildMs), lookups = median(devMs);
    std::printf("| %s | %zu | %zu | %s | %.1f | %s | %s | %s | %.1f | %s | %s |\n", name.c_str(), mesh.indices.size() / 3,
                onCpu->tree().frustumCount(), pcf == 1 ? "binary" : "9x9 PCF", median(buildMs),
                gpu ? fixed("%.3f", build).c_str() : "-", gpu ? fixed("%.3f", lookups).c_str() : "-",
                gpu ? fixed("%.3f", build + lookups).c_str() : "-", median(cpuMs),
                gpu ? std::to_string(overflows).c_str() : "-", answers.c_str());
    std::fflush(stdout);
  }
}

void printTimingFooter() {
  std::printf("\ndevice/CPU: CPU time over device time (above 1: the device is faster). Device ms: GPU timestamps around\n"
              "the dispatches; wall ms adds the copies of queries and answers and the submission. The CPU runs the\n"
              "same lookups (ShadowQuery::litTexels) on every core; `answers` compares the two, point by point.\n");
}

void printLightTimingHeader() {
  std::printf("| bundle | lights | grids | pool | device array | lookups | filter | device ms/frame | wall ms | CPU ms/frame | device/CPU | answers |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
}

void printLightTimingRows(const std::string& name, const std::shared_ptr<const runtime::LightArtifact>& artifact,
                          const ManyLightQueries& f, runtime::GpuDevice* device, int repeat) {
  std::unique_ptr<runtime::GpuLights> gpu;
  if (device) gpu = std::make_unique<runtime::GpuLights>(*device, artifact);
  const runtime::LightArtifact& a = *artifact;
  auto mib = [](uint64_t b) { return fixed("%.2f MiB", double(b) / (1 << 20)); };
  for (int pcf : {1, 9}) {
    std::vector<uint32_t> onCpu, onGpu;
    runtime::cpuLightLitTexels(a, f.lights, f.frame.points, f.frame.normals, pcf, onCpu);  // warm-up, and the reference
    std::vector<double> cpuMs, devMs, wallMs;
    for (int r = 0; r < repeat; ++r) {
      const auto t = std::chrono::steady_clock::now();
      runtime::cpuLightLitTexels(a, f.lights, f.frame.points, f.frame.normals, pcf, onCpu);
      cpuMs.push_back(millisecondsSince(t));
    }
    std::string answers = "CPU only";
    if (gpu) {
      gpu->litTexels(f.lights, f.frame.points, f.frame.normals, pcf, onGpu);  // warm-up
      uint64_t differ = 0;
      for (size_t i = 0; i < onCpu.size(); ++i) differ += onGpu[i] != onCpu[i];
      answers = differ == 0 ? "identical" : std::to_string(differ) + " differ";
      for (int r = 0; r < repeat; ++r) {
        const auto t = std::chrono::steady_clock::now();
        gpu->litTexels(f.lights, f.frame.points, f.frame.normals, pcf, onGpu);
        wallMs.push_back(millisecondsSince(t));
        devMs.push_back(gpu->lastDeviceNanoseconds() * 1e-6);
      }
    }
    const double cpu = median(cpuMs), dev = median(devMs);
    std::printf("| %s | %zu | %zu | %s | %s | %zu | %s | %s | %s | %s | %s | %s |\n", name.c_str(), a.lightCount(),
                a.bundle().grids.size(), mib(a.bundle().poolBytes).c_str(), mib(a.bundle().pool->size() * 4).c_str(),
                f.lights.size(), pcf == 1 ? "binary" : "9x9 PCF", gpu ? fixed("%.3f", dev).c_str() : "-",
                gpu ? fixed("%.1f", median(wallMs)).c_str() : "-", fixed("%.1f", cpu).c_str(),
                gpu ? fixed("%.2fx", cpu / dev).c_str() : "-", answers.c_str());
    std::fflush(stdout);
  }
}

}  // namespace cpvs::bench
