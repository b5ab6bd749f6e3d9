// Opening artifacts and light bundles, the CPU path, and the front that picks a device or
// the CPU.
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#include <functional>
#include <optional>

#include "cpvs/base/error.h"
#include "cpvs/base/file.h"
#include "cpvs/dagmh/dag_mh_words.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/io/dmh_file.h"
#include "cpvs/runtime/runtime.h"
#include "query_kernel.h"

namespace cpvs::runtime {

namespace {

// An artifact's bytes through `decode`: FileError when the file cannot be read,
// CorruptArtifact when decode refuses them.
template <class Decode>
auto openWith(const std::string& path, Decode&& decode) {
  std::vector<uint8_t> bytes;
  try {
    bytes = readFile(path);
  } catch (const InputError& e) {
    throw RuntimeError(Status::FileError, e.what());
  }
  return decode(bytes, path);
}

}  // namespace

const char* artifactKindName(ArtifactKind kind) { return kind == ArtifactKind::DagMh ? "dagmh" : "cpvs"; }

ShadowArtifact::ShadowArtifact(ShadowQuery query, std::shared_ptr<const TopTree> translucent)
    : query_(std::move(query)), translucent_(std::move(translucent)) {
  if (!translucent_) return;
  const TopTree& t = *translucent_;
  if (!t.linked() || t.transmittance().size() != t.frustumCount() || !t.light().directional ||
      length(t.light().vector - query_->grid().frame.dir) > 1e-9)
    throw RuntimeError(Status::InvalidArgument,
                       "translucent casters: a tree that is not linked, lacks a transmittance per frustum, or is not "
                       "for the artifact's sun");
}

ShadowArtifact::ShadowArtifact(DagMhQuery query) : dagMh_(std::move(query)) {
  try {
    dagMhWords_ = dagMhWords(dagMh_->dag());
  } catch (const InputError& e) {
    throw RuntimeError(Status::InvalidArgument, e.what());
  }
}

const ShadowQuery& ShadowArtifact::cpu() const {
  if (!query_) throw RuntimeError(Status::InvalidArgument, "the artifact is a DAG-MH, not a CPVS");
  return *query_;
}

const DagMhQuery& ShadowArtifact::dagMh() const {
  if (!dagMh_) throw RuntimeError(Status::InvalidArgument, "the artifact is a CPVS, not a DAG-MH");
  return *dagMh_;
}

std::shared_ptr<const ShadowArtifact> ShadowArtifact::fromBytes(const std::vector<uint8_t>& bytes, const std::string& source) {
  try {
    if (isDmh(bytes.data(), bytes.size())) {
      DmhArtifact a = decodeDmh(bytes.data(), bytes.size(), source);
      return std::make_shared<const ShadowArtifact>(DagMhQuery(a.grid, std::move(a.dag)));
    }
    CpvsArtifact a = decodeCpvs(bytes.data(), bytes.size(), source);
    return std::make_shared<const ShadowArtifact>(ShadowQuery(a.grid, std::move(a.packed)), std::move(a.translucent));
  } catch (const InputError& e) {
    throw RuntimeError(Status::CorruptArtifact, e.what());
  }
}

std::shared_ptr<const ShadowArtifact> ShadowArtifact::open(const std::string& path) { return openWith(path, fromBytes); }

std::shared_ptr<const LightArtifact> LightArtifact::fromBytes(const std::vector<uint8_t>& bytes, const std::string& source) {
  try {
    return std::make_shared<const LightArtifact>(decodeBundle(bytes.data(), bytes.size(), source));
  } catch (const InputError& e) {
    throw RuntimeError(Status::CorruptArtifact, e.what());
  }
}

std::shared_ptr<const LightArtifact> LightArtifact::open(const std::string& path) { return openWith(path, fromBytes); }

void cpuLitTexels(const ShadowArtifact& artifact, const std::vector<Vec3>& points, const std::vector<Vec3>& normals,
                  int pcf, std::vector<uint32_t>& out, const DynamicCasters* casters) {
  if (!normals.empty() && normals.size() != points.size())
    throw RuntimeError(Status::InvalidArgument, std::to_string(normals.size()) + " normals for " + std::to_string(points.size()) + " points");
  std::optional<PcfWidth> width;
  try {
    width.emplace(pcf);
  } catch (const InputError& e) {
    throw RuntimeError(Status::InvalidArgument, e.what());
  }
  out.resize(points.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, points.size(), 1024), [&](const auto& range) {
    for (size_t i = range.begin(); i != range.end(); ++i) {
      const Vec3 n = normals.empty() ? Vec3{} : normals[i];
      out[i] = casters && casters->shadowed(points[i], n) ? 0 : artifact.litTexels(points[i], n, *width);
    }
  });
}

ShadowLookups::ShadowLookups(std::shared_ptr<const ShadowArtifact> artifact, Backend backend, const DeviceOptions& options)
    : artifact_(std::move(artifact)), backend_(backend) {
  if (!artifact_) throw RuntimeError(Status::InvalidArgument, "no artifact");
  if (backend == Backend::Cpu) return;
  try {
    ownDevice_ = GpuDevice::create(options);
  } catch (const RuntimeError& e) {
    if (backend == Backend::Gpu) throw;
    fallbackReason_ = e.what();
    return;
  }
  device_ = ownDevice_.get();
  upload();
}

ShadowLookups::ShadowLookups(std::shared_ptr<const ShadowArtifact> artifact, GpuDevice& device, Backend backend)
    : artifact_(std::move(artifact)), backend_(backend) {
  if (!artifact_) throw RuntimeError(Status::InvalidArgument, "no artifact");
  if (backend == Backend::Cpu) return;
  device_ = &device;
  upload();
}

void ShadowLookups::upload() {
  try {
    gpu_ = std::make_unique<GpuShadows>(*device_, artifact_);
  } catch (const RuntimeError& e) {
    if (backend_ == Backend::Gpu) throw;
    gpu_.reset();
    device_ = nullptr;
    ownDevice_.reset();
    fallbackReason_ = e.what();
  }
}

ShadowLookups::~ShadowLookups() = default;

std::string ShadowLookups::deviceName() const {
  if (gpu_) return device_->name() + " (" + device_->type() + ", Vulkan)";
  return "CPU (" + std::to_string(tbb::info::default_concurrency()) + " threads)";
}

bool ShadowLookups::onDevice(const std::function<void()>& work) {
  if (!gpu_) return false;
  try {
    work();
    return true;
  } catch (const RuntimeError& e) {
    // A device that is lost stays lost: from here on the CPU answers, as Auto promised.
    if (e.status() != Status::DeviceLost || backend_ != Backend::Auto) throw;
    fallbackReason_ = e.what();
    gpu_.reset();
    device_ = nullptr;
    ownDevice_.reset();
    return false;
  }
}

void ShadowLookups::litTexels(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
                              std::vector<uint32_t>& out) {
  if (onDevice([&] { gpu_->litTexels(points, normals, pcf, out); })) return;
  cpuLitTexels(*artifact_, points, normals, pcf, out, casters_.get());
}

void ShadowLookups::transmittance(const std::vector<Vec3>& points, const std::vector<Vec3>& normals,
                                  std::vector<std::array<float, 3>>& out) {
  if (onDevice([&] { gpu_->transmittance(points, normals, out); })) return;
  cpuTransmittance(*artifact_, points, normals, out);
}

void ShadowLookups::setDynamicCasters(std::shared_ptr<const DynamicCasters> casters) {
  casters_ = std::move(casters);
  onDevice([&] { gpu_->setDynamicCasters(casters_); });
}

void ShadowLookups::visibility(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
                               std::vector<float>& out) {
  std::vector<uint32_t> lit;
  litTexels(points, normals, pcf, lit);
  out.resize(lit.size());
  const float texels = float(pcf * pcf);
  for (size_t i = 0; i < lit.size(); ++i) out[i] = float(lit[i]) / texels;
}

void checkSegmentKind(const ShadowArtifact& artifact) {
  if (artifact.kind() != ArtifactKind::Cpvs)
    throw RuntimeError(Status::InvalidArgument,
                       "segments (sun shafts) walk a CPVS's voxels; a DAG-MH stores one depth a texel: bake a .cpvs");
}

void ShadowLookups::segments(const std::vector<Vec3>& from, const std::vector<Vec3>& to, const Medium& medium,
                             std::vector<double>& litFraction, std::vector<float>& inScattering) {
  if (gpu_) {
    gpu_->segments(from, to, medium, litFraction, inScattering);
    return;
  }
  checkSegmentShape(from.size(), to.size(), medium);
  checkSegmentKind(*artifact_);
  litFraction.resize(from.size());
  inScattering.resize(from.size());
  const ShadowQuery& q = artifact_->cpu();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, from.size(), 256), [&](const auto& range) {
    for (size_t i = range.begin(); i != range.end(); ++i) {
      litFraction[i] = q.litFraction(from[i], to[i]);
      inScattering[i] = float(q.inScattering(from[i], to[i], medium).inScattering);
    }
  });
}

}  // namespace cpvs::runtime
