// `cpvs query`: sun visibility at world points, one from the command line or many from CSV.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <memory>
#include <sstream>

#include "cli_util.h"
#include "commands.h"
#include "cpvs/base/error.h"
#include "cpvs/bake/bake_plan.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/io/dmh_file.h"
#include "cpvs/query/dag_mh_query.h"
#include "cpvs/query/bundle_query.h"
#include "cpvs/query/shadow_query.h"
#include "cpvs/runtime/runtime.h"

namespace cpvs::cli {

namespace {

struct QueryArgs {
  std::string file, point, normal, pointsCsv, segment, medium, light = "all";
  int pcf = 1;
  bool gpu = false, soft = false;
};

/// Reads "x,y,z" or "x,y,z,nx,ny,nz" per line; blank lines and lines starting with '#'
/// are skipped, and a first line that is not numeric is taken as a header.
void readPointsCsv(const std::string& path, std::vector<Vec3>& points, std::vector<Vec3>& normals) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open");
  std::string line;
  size_t lineNo = 0;
  bool anyNormal = false, anyWithout = false;
  while (std::getline(in, line)) {
    ++lineNo;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") == std::string::npos || line[line.find_first_not_of(" \t")] == '#') continue;
    std::vector<double> v;
    try {
      v = parseNumbers(line, path + " line " + std::to_string(lineNo));
    } catch (const InputError&) {
      if (points.empty() && lineNo == 1) continue;  // a header
      throw;
    }
    if (v.size() != 3 && v.size() != 6)
      throw InputError(path + " line " + std::to_string(lineNo) + ": expected x,y,z or x,y,z,nx,ny,nz, got " +
                       std::to_string(v.size()) + " numbers");
    points.push_back({v[0], v[1], v[2]});
    normals.push_back(v.size() == 6 ? Vec3{v[3], v[4], v[5]} : Vec3{});
    (v.size() == 6 ? anyNormal : anyWithout) = true;
  }
  if (points.empty()) throw InputError(path + ": no points");
  if (!anyNormal) normals.clear();
}

// What a file was baked for, to say when a lookup is not one it promises to answer.
class ReceiverNotice {
 public:
  ReceiverNotice(const CpvsArtifact& art, const std::string& file, int pcf)
      : kind_(art.options.receivers), resolution_(art.grid.resolution()) {
    if (kind_ == ReceiverKind::Everywhere) return;
    const int baked = art.options.receiverPcf;
    std::fprintf(stderr, "note: %s was baked for '%s' receivers (lookups up to PCF %d); a lookup elsewhere may be wrong\n",
                 file.c_str(), optionName(kind_), baked);
    if (pcf > baked)
      std::fprintf(stderr, "warning: --pcf %d is wider than the %d %s was baked for: filtered answers may be wrong\n", pcf,
                   baked, file.c_str());
    if (!planCoverage(art.plan, resolution_, cells_, coverage_))
      std::fprintf(stderr, "note: %s records no receiver coverage: lookups outside it cannot be told\n", file.c_str());
  }

  // A surface receiver is looked up with its normal; any other kind also without one.
  bool needsNormal() const { return kind_ == ReceiverKind::Surfaces || kind_ == ReceiverKind::SurfacesTwoSided; }

  // True when the lookup reads the grid only where no declared receiver reads.
  bool outside(const ShadowQuery& q, const Vec3& p, const Vec3& n, int pcf) const {
    if (cells_ == 0) return false;
    const VoxelCoord v = q.voxelOf(p, n, pcf);
    if (v.z < 0) return false;  // in front of the grid: lit, read nowhere
    const int64_t R = int64_t(resolution_), side = R / int64_t(cells_), r = pcf / 2;
    bool read = false;
    for (int64_t y = v.y - r; y <= v.y + r; ++y)
      for (int64_t x = v.x - r; x <= v.x + r; ++x) {
        if (x < 0 || y < 0 || x >= R || y >= R) continue;
        read = true;
        if (coverage_[size_t(y / side) * cells_ + size_t(x / side)]) return false;
      }
    return read;
  }

 private:
  ReceiverKind kind_;
  uint64_t resolution_;
  uint32_t cells_ = 0;
  std::vector<uint8_t> coverage_;
};

// The lights --light names in a bundle of `count`: "all", or one index.
std::vector<size_t> lightsOf(const std::string& text, size_t count) {
  if (text == "all") {
    std::vector<size_t> all(count);
    for (size_t i = 0; i < count; ++i) all[i] = i;
    return all;
  }
  const std::vector<double> v = parseNumbers(text, "--light");
  if (v.size() != 1 || v[0] < 0 || v[0] != std::floor(v[0]) || v[0] >= double(count))
    throw InputError("--light " + text + ": give all or a light index from 0 to " + std::to_string(count - 1));
  return {size_t(v[0])};
}

// Soft visibility of each area light of a bundle: a line per area light for one point, a
// column per area light for many.
int querySoft(const QueryArgs& a, const BundleQuery& q) {
  if (q.areaCount() == 0) throw InputError("--soft: " + a.file + " holds no area light (bake one with --area-light)");
  if (a.light != "all" || a.pcf != 1)
    throw InputError("--soft answers every area light, interpolated bilinearly: no --light or --pcf");
  if (!a.point.empty()) {
    const Vec3 p = parseVec3(a.point, "--point");
    const Vec3 n = a.normal.empty() ? Vec3{} : parseVec3(a.normal, "--normal");
    for (size_t k = 0; k < q.areaCount(); ++k)
      std::printf("area light %zu (%zu VPLs)  soft visibility %.4f\n", k + 1, q.vplsOf(k).size(), q.softVisibility(k, p, n));
    return 0;
  }
  std::vector<Vec3> points, normals;
  readPointsCsv(a.pointsCsv, points, normals);
  std::printf("x,y,z");
  for (size_t k = 0; k < q.areaCount(); ++k) std::printf(",area%zu", k + 1);
  std::printf("\n");
  for (size_t i = 0; i < points.size(); ++i) {
    std::printf("%.9g,%.9g,%.9g", points[i].x, points[i].y, points[i].z);
    for (size_t k = 0; k < q.areaCount(); ++k)
      std::printf(",%.6g", q.softVisibility(k, points[i], normals.empty() ? Vec3{} : normals[i]));
    std::printf("\n");
  }
  return 0;
}

// A light bundle: each light's visibility (0 outside its cone), a line per light for one
// point, a column per light for many.
int queryBundle(const QueryArgs& a, const std::vector<uint8_t>& bytes) {
  if (a.gpu) throw InputError("--gpu: a light bundle is looked up on the CPU (the GPU takes sun artifacts)");
  const BundleQuery q(decodeBundle(bytes.data(), bytes.size(), a.file));
  if (a.soft) return querySoft(a, q);
  const std::vector<size_t> lights = lightsOf(a.light, q.lightCount());
  if (!a.point.empty()) {
    const Vec3 p = parseVec3(a.point, "--point");
    const Vec3 n = a.normal.empty() ? Vec3{} : parseVec3(a.normal, "--normal");
    for (size_t i : lights) {
      const float vis = q.filtered(i, p, n, a.pcf);
      std::printf("light %zu%s  %s  visibility %.4g\n", i,
                  q.light(i).light.name.empty() ? "" : (" (" + loggable(q.light(i).light.name, 40) + ")").c_str(),
                  vis == 1.0f ? "lit" : (vis == 0.0f ? "shadowed" : "partly lit"), vis);
    }
    return 0;
  }
  std::vector<Vec3> points, normals;
  readPointsCsv(a.pointsCsv, points, normals);
  std::printf("x,y,z");
  for (size_t i : lights) std::printf(",light%zu", i);
  std::printf("\n");
  for (size_t k = 0; k < points.size(); ++k) {
    std::printf("%.9g,%.9g,%.9g", points[k].x, points[k].y, points[k].z);
    for (size_t i : lights) std::printf(",%.6g", q.filtered(i, points[k], normals.empty() ? Vec3{} : normals[k], a.pcf));
    std::printf("\n");
  }
  return 0;
}

// The sun's light along a segment: where it reaches, and with a medium what it scatters
// towards the segment's start.
int querySegment(const QueryArgs& a, const std::vector<uint8_t>& bytes) {
  if (a.gpu) throw InputError("--gpu: segments are walked on the CPU");
  if (cpvsFormatVersion(bytes.data(), bytes.size(), a.file) == kBundleFormatVersion)
    throw InputError("--segment: light along a segment is answered for the sun; " + a.file + " is a light bundle");
  const size_t colon = a.segment.find(':');
  if (colon == std::string::npos)
    throw InputError("--segment '" + a.segment + "': expected AX,AY,AZ:BX,BY,BZ (from the eye A to B)");
  const Vec3 from = parseVec3(a.segment.substr(0, colon), "--segment's start");
  const Vec3 to = parseVec3(a.segment.substr(colon + 1), "--segment's end");
  std::optional<Medium> medium;
  if (!a.medium.empty()) medium = parseMedium(a.medium, "--medium");
  CpvsArtifact art = decodeCpvs(bytes.data(), bytes.size(), a.file);
  checkGridInTheAir(art, a.file, "--segment");
  if (art.translucent)
    std::fprintf(stderr, "note: %s has translucent casters; along a segment their light counts as unblocked\n",
                 a.file.c_str());
  const ShadowQuery q(art.grid, std::move(art.packed));
  const auto lit = q.litStretches(from, to);
  const double len = length(to - from);
  double litLength = 0;
  for (const auto& [u0, u1] : lit) litLength += u1 - u0;
  std::printf("length %.9g  lit %.9g (%.4g%%) in %zu stretch%s\n", len, litLength, len > 0 ? 100 * litLength / len : 100.0,
              lit.size(), lit.size() == 1 ? "" : "es");
  for (size_t k = 0; k < std::min<size_t>(lit.size(), 20); ++k)
    std::printf("  lit from %.9g to %.9g\n", lit[k].first, lit[k].second);
  if (lit.size() > 20) std::printf("  ... %zu more\n", lit.size() - 20);
  if (medium) {
    const SegmentLight s = q.inScattering(from, to, *medium);
    std::printf("transmittance %.9g  in-scattered %.9g (radiance towards the start per unit of sun irradiance)\n",
                s.transmittance, s.inScattering);
  }
  return 0;
}

// The sun's lookups on the CPU, or (--gpu) on a Vulkan device, which stderr names.
std::unique_ptr<runtime::ShadowLookups> sunLookups(std::shared_ptr<const runtime::ShadowArtifact> artifact, bool gpu) {
  auto lookups =
      std::make_unique<runtime::ShadowLookups>(std::move(artifact), gpu ? runtime::Backend::Gpu : runtime::Backend::Cpu);
  if (gpu) std::fprintf(stderr, "Looking up on %s\n", lookups->deviceName().c_str());
  return lookups;
}

// A DAG-MH: the same lookups (point or CSV), on the CPU or (--gpu) the runtime's device.
int queryDagMh(const QueryArgs& a, const std::vector<uint8_t>& bytes) {
  if (!a.segment.empty()) throw InputError("--segment: light along a segment is walked in a .cpvs, not a DAG-MH");
  if (a.soft || a.light != "all") throw InputError("--soft and --light pick a light bundle's lights; " + a.file + " has the sun only");
  DmhArtifact art = decodeDmh(bytes.data(), bytes.size(), a.file);
  if (art.options.receivers != ReceiverKind::Everywhere) {
    std::fprintf(stderr, "note: %s was baked for '%s' receivers (lookups up to PCF %d); a lookup elsewhere may be wrong\n",
                 a.file.c_str(), optionName(art.options.receivers), int(art.options.receiverPcf));
    if (a.pcf > art.options.receiverPcf)
      std::fprintf(stderr, "warning: --pcf %d is wider than the %d %s was baked for: filtered answers may be wrong\n",
                   a.pcf, int(art.options.receiverPcf), a.file.c_str());
  }
  auto artifact = std::make_shared<const runtime::ShadowArtifact>(DagMhQuery(art.grid, std::move(art.dag)));
  const DagMhQuery& q = artifact->dagMh();
  const std::unique_ptr<runtime::ShadowLookups> lookups = sunLookups(artifact, a.gpu);
  auto lookup = [&](const std::vector<Vec3>& points, const std::vector<Vec3>& normals, std::vector<float>& out) {
    lookups->visibility(points, normals, a.pcf, out);
  };
  if (!a.point.empty()) {
    const Vec3 p = parseVec3(a.point, "--point");
    const Vec3 n = a.normal.empty() ? Vec3{} : parseVec3(a.normal, "--normal");
    std::vector<float> one;
    lookup({p}, {n}, one);
    const float vis = one.at(0);
    const Vec3 c = q.lookupVoxel(p, n, a.pcf);
    const VoxelCoord v{floorToVoxel(c.x), floorToVoxel(c.y), floorToVoxel(c.z)};
    const int64_t R = int64_t(q.grid().resolution());
    std::printf("%s  visibility %.4g  (voxel %lld, %lld, %lld", vis == 1.0f ? "lit" : (vis == 0.0f ? "shadowed" : "partly lit"),
                vis, static_cast<long long>(v.x), static_cast<long long>(v.y), static_cast<long long>(v.z));
    if (v.x >= 0 && v.y >= 0 && v.x < R && v.y < R)
      std::printf("; the texel's depth %.6g slices", q.dag().depth(uint64_t(v.x), uint64_t(v.y)));
    std::printf(")\n");
    return 0;
  }
  std::vector<Vec3> points, normals;
  readPointsCsv(a.pointsCsv, points, normals);
  std::vector<float> out;
  lookup(points, normals, out);
  std::printf("x,y,z,visibility\n");
  for (size_t i = 0; i < points.size(); ++i) std::printf("%.9g,%.9g,%.9g,%.6g\n", points[i].x, points[i].y, points[i].z, out[i]);
  return 0;
}

int runQuery(const QueryArgs& a) {
  if (!a.segment.empty()) {
    if (!a.point.empty() || !a.pointsCsv.empty()) throw InputError("give one of --point, --points and --segment");
    const std::vector<uint8_t> bytes = readFile(a.file);
    return isDmh(bytes.data(), bytes.size()) ? queryDagMh(a, bytes) : querySegment(a, bytes);
  }
  if (!a.medium.empty()) throw InputError("--medium goes with --segment");
  if (a.point.empty() == a.pointsCsv.empty())
    throw InputError("give exactly one of --point X,Y,Z, --points FILE.csv and --segment A:B");
  if (!a.pointsCsv.empty() && !a.normal.empty())
    throw InputError("--normal goes with --point; in --points files put the normal in columns 4-6");
  const std::vector<uint8_t> bytes = readFile(a.file);
  if (isDmh(bytes.data(), bytes.size())) return queryDagMh(a, bytes);
  if (cpvsFormatVersion(bytes.data(), bytes.size(), a.file) == kBundleFormatVersion) return queryBundle(a, bytes);
  if (a.soft) throw InputError("--soft answers a light bundle's area lights; " + a.file + " has the sun only");
  if (a.light != "all") throw InputError("--light picks a light of a light bundle; " + a.file + " has the sun only");
  CpvsArtifact art = decodeCpvs(bytes.data(), bytes.size(), a.file);
  const ReceiverNotice notice(art, a.file, a.pcf);
  auto artifact =
      std::make_shared<const runtime::ShadowArtifact>(ShadowQuery(art.grid, std::move(art.packed)), std::move(art.translucent));
  const bool translucent = artifact->translucent() != nullptr;
  const ShadowQuery& q = artifact->cpu();
  const std::unique_ptr<runtime::ShadowLookups> lookups = sunLookups(artifact, a.gpu);
  auto lookup = [&](const std::vector<Vec3>& points, const std::vector<Vec3>& normals, std::vector<float>& out) {
    lookups->visibility(points, normals, a.pcf, out);
  };
  // The light let through the translucent casters (white without them).
  auto transmittance = [&](const std::vector<Vec3>& points, const std::vector<Vec3>& normals) {
    std::vector<std::array<float, 3>> t;
    lookups->transmittance(points, normals, t);
    return t;
  };
  if (!a.point.empty()) {
    Vec3 p = parseVec3(a.point, "--point");
    Vec3 n = a.normal.empty() ? Vec3{} : parseVec3(a.normal, "--normal");
    std::vector<float> one;
    lookup({p}, {n}, one);
    const float vis = one.at(0);
    VoxelCoord v = q.voxelOf(p, n, a.pcf);
    std::printf("%s  visibility %.4g  (voxel %lld, %lld, %lld)\n", vis == 1.0f ? "lit" : (vis == 0.0f ? "shadowed" : "partly lit"),
                vis, static_cast<long long>(v.x), static_cast<long long>(v.y), static_cast<long long>(v.z));
    if (translucent) {
      const std::array<float, 3> t = transmittance({p}, {n}).at(0);
      std::printf("through translucent casters: transmittance %.4g %.4g %.4g  light %.4g %.4g %.4g\n", t[0], t[1], t[2],
                  vis * t[0], vis * t[1], vis * t[2]);
    }
    if (notice.needsNormal() && a.normal.empty())
      std::fprintf(stderr, "warning: a surface receiver is looked up with its --normal; this lookup has none\n");
    if (notice.outside(q, p, n, a.pcf))
      std::fprintf(stderr, "warning: undefined here: outside the declared receivers (no receiver's lookup reads this "
                           "part of the grid), so this answer may be wrong\n");
    return 0;
  }
  std::vector<Vec3> points, normals;
  readPointsCsv(a.pointsCsv, points, normals);
  std::vector<float> out;
  lookup(points, normals, out);
  if (translucent) {
    // The light through the translucent casters, per channel, besides the CPVS's visibility.
    const std::vector<std::array<float, 3>> t = transmittance(points, normals);
    std::printf("x,y,z,visibility,transmittance_r,transmittance_g,transmittance_b\n");
    for (size_t i = 0; i < points.size(); ++i)
      std::printf("%.9g,%.9g,%.9g,%.6g,%.6g,%.6g,%.6g\n", points[i].x, points[i].y, points[i].z, out[i], t[i][0], t[i][1], t[i][2]);
  } else {
    std::printf("x,y,z,visibility\n");
    for (size_t i = 0; i < points.size(); ++i)
      std::printf("%.9g,%.9g,%.9g,%.6g\n", points[i].x, points[i].y, points[i].z, out[i]);
  }
  if (notice.needsNormal()) {
    const size_t without = normals.empty() ? points.size() : size_t(std::count(normals.begin(), normals.end(), Vec3{}));
    if (without)
      std::fprintf(stderr, "warning: %zu of %zu points have no normal; surface receivers are looked up with theirs\n",
                   without, points.size());
  }
  std::vector<size_t> outside;
  for (size_t i = 0; i < points.size(); ++i)
    if (notice.outside(q, points[i], normals.empty() ? Vec3{} : normals[i], a.pcf)) outside.push_back(i);
  if (!outside.empty()) {
    std::string which;
    for (size_t k = 0; k < std::min<size_t>(outside.size(), 10); ++k) which += (k ? ", " : "") + std::to_string(outside[k] + 1);
    std::fprintf(stderr, "warning: %zu of %zu points are outside the declared receivers (point%s %s%s): their answers may be wrong\n",
                 outside.size(), points.size(), outside.size() == 1 ? "" : "s", which.c_str(), outside.size() > 10 ? ", ..." : "");
  }
  return 0;
}

}  // namespace

void addQueryCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<QueryArgs>();
  CLI::App* c = app.add_subcommand(
      "query", "Visibility of the sun (or of each light of a light bundle) at world points: 1 lit, 0 shadowed, a "
               "fraction with --pcf (CSV out for --points)");
  c->add_option("file", a->file, ".cpvs, light bundle or .dmh file")->required();
  c->add_option("--point,-p", a->point, "World point X,Y,Z");
  c->add_option("--normal,-n", a->normal, "Surface normal at the point (applies the normal offset)");
  c->add_option("--points", a->pointsCsv, "CSV file of x,y,z or x,y,z,nx,ny,nz rows");
  c->add_option("--segment", a->segment,
                 "AX,AY,AZ:BX,BY,BZ: where the sun reaches along the segment from A to B (the voxels as they are "
                 "baked: needs a bake for receivers everywhere)");
  c->add_option("--medium", a->medium,
                "SIGMA_S,SIGMA_A[,G] with --segment: a homogeneous medium (scattering and absorption per world unit, "
                "Henyey-Greenstein g): prints the transmittance and the sun light scattered towards A");
  c->add_flag("--soft", a->soft,
              "A light bundle's area lights (bake --area-light): each one's soft visibility, the fraction of its light "
              "that reaches the point (its VPLs averaged, each interpolated across its grid)");
  c->add_option("--light", a->light, "A light bundle's light: its index, or all (a line or a column each)")
      ->capture_default_str();
  c->add_option("--pcf", a->pcf, "Filter width in texels: 1, 3, 5, 7 or 9")
      ->check(CLI::IsMember({1, 3, 5, 7, 9}))->capture_default_str();
  c->add_flag("--gpu", a->gpu,
              "Look up on a Vulkan device (headless; CPVS_DEVICE picks one by name): the same answers as the "
              "CPU's. Exit status 5 when there is none");
  c->callback([a, &status] { status = runQuery(*a); });
}

}  // namespace cpvs::cli
