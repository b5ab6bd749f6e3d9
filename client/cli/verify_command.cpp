// `cpvs verify`: CPVS lookups against exact shadow rays (Embree) and exact shadow volumes (a
// TOP tree) on the scene's surfaces.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>

#include "bake_flags.h"
#include "cpvs/bake/camera_views.h"
#include "cli_util.h"
#include "commands.h"
#include "cpvs/base/error.h"
#include "cpvs/eval/verify.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/io/dmh_file.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/psv/translucent_tree.h"
#include "cpvs/query/bundle_query.h"
#include "cpvs/raytrace/ray_scene.h"

namespace cpvs::cli {

namespace {

struct VerifyArgs {
  std::string file, scene;
  uint64_t samples = 100000, seed = 1;
  bool json = false;
  std::string reference = "both";  // embree, psv or both
  OptionFlags receivers;  // --receivers volume:FILE and --receiver-box, for a volume bake
};

// The declaration an artifact or bundle was baked for: its kind and PCF from the header,
// a volume from the flags, which must hash to what the header recorded.
ReceiverDeclaration bakedReceivers(const VerifyArgs& a, const BakeOptions& options, const Hash128& bakedHash) {
  ReceiverDeclaration d;
  d.kind = options.receivers;
  d.maxPcf = options.receiverPcf;
  const OptionFlags& f = a.receivers;
  const bool given = f.receivers != optionName(ReceiverKind::Everywhere) || !f.receiverBoxes.empty() ||
                     cameraFlagsGiven(f) || !f.groundLayer.empty();
  const std::string baked = optionName(d.kind);
  if (d.kind == ReceiverKind::Volume || d.kind == ReceiverKind::Cameras) {
    if (!given)
      throw InputError(a.file + " was baked for '" + baked + "' receivers: give them again (--receivers " + baked +
                       "[:FILE], --receiver-box, --ground-layer, --camera-region, --view-distance, --camera-visibility)");
    OptionFlags copy = f;
    copy.receiverPcf = d.maxPcf;
    d = receiversOf(copy);
    if (d.kind != options.receivers) throw InputError("--receivers: " + a.file + " was baked for '" + baked + "'");
  } else if (given && f.receivers != baked) {
    throw InputError("--receivers: " + a.file + " was baked for '" + baked + "', not '" + f.receivers + "'");
  }
  if (receiverHash(d) != bakedHash)
    throw InputError("the receivers given are not the ones " + a.file + " was baked for (declaration " +
                     receiverHash(d).hex() + ", the file's " + bakedHash.hex() + ")");
  return d;
}

/// The oracles --reference names, with the tree for the light (kept in `tree`).
ExactOracles oraclesFor(const VerifyArgs& a, const Scene& scene, const PsvLight& light, std::optional<TopTree>& tree) {
  tree.reset();
  if (a.reference == "embree") return {};
  tree = verificationTree(scene, light);
  return {&*tree, a.reference == "psv"};
}

/// What the text report says of the second oracle.
void printOracles(const VerifyArgs& a, const VerifyResult& r) {
  if (a.reference != "both") return;
  std::printf("  second oracle (TOP tree, seed 003): %llu points, differs from Embree at %llu near a boundary and "
              "%llu elsewhere\n",
              static_cast<unsigned long long>(r.oraclesCompared),
              static_cast<unsigned long long>(r.oraclesDisagreeNearBoundary),
              static_cast<unsigned long long>(r.oraclesDisagreeElsewhere));
  for (const auto& e : r.disagreementExamples)
    std::printf("    the oracles differ at (%.9g, %.9g, %.9g) normal (%.4f, %.4f, %.4f)\n", e.point.x, e.point.y,
                e.point.z, e.normal.x, e.normal.y, e.normal.z);
}

// A light bundle: each light against exact segment rays at surface points in its cone
// (a point light's: in each face; for declared receivers, on their sides), --samples
// shared out among the lights.
int verifyBundle(const VerifyArgs& a, const std::vector<uint8_t>& bytes) {
  const LightBundle bundle = decodeBundle(bytes.data(), bytes.size(), a.file);
  const ReceiverDeclaration receivers = bakedReceivers(a, bundle.options, bundle.receiverHash);
  const Scene scene = openMatchingScene(a.scene, bundle.sceneHash);
  const std::vector<uint8_t> sides = receivingSides(scene, receivers);
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  const RayScene rays(scene, (lo + hi) * 0.5);
  const BundleQuery q(bundle);
  const uint64_t perLight = std::max<uint64_t>(1, a.samples / q.lightCount());
  std::vector<VerifyResult> results;
  uint64_t elsewhere = 0, disagree = 0;
  std::optional<TopTree> tree;
  for (size_t i = 0; i < q.lightCount(); ++i) {
    const BundleLight& l = q.light(i);
    const ExactOracles oracles = oraclesFor(a, scene, PsvLight::point(l.light.position), tree);
    VerifyResult total;
    for (uint32_t k = l.firstGrid; k < l.firstGrid + l.gridCount; ++k) {
      total += verifyBundleGrid(q, k, bundle.options.closed, scene, rays, std::max<uint64_t>(1, perLight / l.gridCount),
                                a.seed + k, &sides, oracles);
    }
    elsewhere += total.mismatchElsewhere;
    disagree += total.oraclesDisagreeElsewhere;
    results.push_back(std::move(total));
  }
  if (a.json) {
    std::cout << "{\n  \"file\": " << jsonString(a.file) << ",\n  \"scene\": " << jsonString(a.scene) << ",\n  \"lights\": [";
    for (size_t i = 0; i < results.size(); ++i) {
      const VerifyResult& r = results[i];
      std::cout << (i ? ",\n    " : "\n    ") << "{\"index\": " << i << ", \"name\": " << jsonString(q.light(i).light.name)
                << ", \"samples\": " << r.samples << ", \"lit\": " << r.exactlyLit << ", \"near_boundary\": " << r.nearBoundary
                << ", \"mismatch_near_boundary_count\": " << r.mismatchNearBoundary
                << ", \"mismatch_elsewhere_count\": " << r.mismatchElsewhere
                << ", \"oracles_disagree_elsewhere_count\": " << r.oraclesDisagreeElsewhere << "}";
    }
    std::cout << "\n  ],\n  \"reference\": " << jsonString(a.reference) << ",\n  \"mismatch_elsewhere_count\": "
              << elsewhere << ",\n  \"oracles_disagree_elsewhere_count\": " << disagree << "\n}\n";
  } else {
    std::printf("%s against %s: each light's lookups against exact segment rays to it, at surface points in its cone\n",
                a.file.c_str(), a.scene.c_str());
    std::printf("\n  %-5s %-18s %-5s %9s %9s %14s %12s %10s\n", "light", "name", "kind", "points", "lit", "near boundary",
                "mismatches", "elsewhere");
    for (size_t i = 0; i < results.size(); ++i) {
      const VerifyResult& r = results[i];
      std::printf("  %-5zu %-18s %-5s %9llu %9llu %14llu %12llu %10llu\n", i, loggable(q.light(i).light.name, 18).c_str(),
                  lightKindName(q.light(i).light.kind), static_cast<unsigned long long>(r.samples),
                  static_cast<unsigned long long>(r.exactlyLit), static_cast<unsigned long long>(r.nearBoundary),
                  static_cast<unsigned long long>(r.mismatchNearBoundary), static_cast<unsigned long long>(r.mismatchElsewhere));
      for (const auto& e : r.elsewhereExamples)
        std::printf("    mismatch at (%.9g, %.9g, %.9g) normal (%.4f, %.4f, %.4f)\n", e.point.x, e.point.y, e.point.z,
                    e.normal.x, e.normal.y, e.normal.z);
    }
    VerifyResult all;
    for (const VerifyResult& r : results) all += r;
    std::printf("  %-5s %-18s %-5s %9llu %9s %14llu %12llu %10llu\n", "all", "", "", static_cast<unsigned long long>(all.samples),
                "", static_cast<unsigned long long>(all.nearBoundary),
                static_cast<unsigned long long>(all.mismatchNearBoundary), static_cast<unsigned long long>(elsewhere));
    printOracles(a, all);
    std::printf("\n  (near boundary: the exact answer changes within one voxel of the point; mismatches there are "
                "the grid's quantization, elsewhere they are wrong answers)\n");
  }
  return elsewhere == 0 && disagree == 0 ? 0 : 1;
}

// The translucent casters' tree of a sun artifact against the scene's: the same nodes and
// transmittance as translucentTree builds, and its walk equal to the product over every
// frustum holding the point (TopTree's brute force) at each sampled point.
struct TranslucentCheck {
  bool expected = false, stored = false, same = true;
  size_t frusta = 0;
  uint64_t points = 0, darkened = 0, differ = 0;
};

TranslucentCheck checkTranslucent(const CpvsArtifact& art, const Scene& scene, const std::vector<SurfaceSample>& samples) {
  TranslucentCheck c;
  c.expected = hasTranslucentMeshes(scene);
  c.stored = art.translucent != nullptr;
  if (!c.stored) return c;
  const TopTree& t = *art.translucent;
  c.frusta = t.frustumCount();
  c.same = c.expected;  // a tree where the scene has no glass is not the scene's
  if (c.expected) {
    const TopTree want = translucentTree(scene, PsvLight::sun(art.grid.frame.dir));
    c.same = want.nodes().size() == t.nodes().size() &&
             std::memcmp(want.nodes().data(), t.nodes().data(), t.bytes()) == 0 && want.transmittance() == t.transmittance() &&
             want.origin() == t.origin();
  }
  for (const SurfaceSample& s : samples) {
    const Vec3 p = s.point + s.normal * art.grid.texelSize();
    std::array<float, 3> want{1, 1, 1};
    for (uint32_t k : t.frustaHolding(p))
      for (int ch = 0; ch < 3; ++ch) want[ch] *= t.transmittance()[k][ch];
    const std::array<float, 3> got = t.transmittanceAt(p);
    ++c.points;
    c.darkened += got != std::array<float, 3>{1, 1, 1};
    // The walk multiplies in its own order: equal up to float rounding.
    bool close = true;
    for (int ch = 0; ch < 3; ++ch) close &= std::fabs(got[ch] - want[ch]) <= 1e-6f;
    c.differ += !close;
  }
  return c;
}

// A DAG-MH: its lookups at the receivers it serves, against the exact shadows.
int verifyDagMh(const VerifyArgs& a, const std::vector<uint8_t>& bytes) {
  DmhArtifact art = decodeDmh(bytes.data(), bytes.size(), a.file);
  const Scene scene = openMatchingScene(a.scene, art.sceneHash);
  const ReceiverDeclaration receivers = bakedReceivers(a, art.options, art.receiverHash);
  std::optional<Scene> opaque;
  const Scene& casters = sunCasters(scene, opaque);
  const RayScene rays(casters, art.grid.origin);
  const DagMhQuery q(art.grid, std::move(art.dag));
  const auto samples = sampleReceivers(scene, rays, art.options.closed, art.grid.frame.dir, receivers, a.samples, a.seed);
  std::optional<TopTree> tree;
  const VerifyResult r =
      verifyDagMhSamples(q, art.options.closed, rays, samples, oraclesFor(a, casters, PsvLight::sun(art.grid.frame.dir), tree));
  if (a.json) {
    std::cout << "{\n  \"file\": " << jsonString(a.file) << ",\n  \"format\": \"dagmh\",\n  \"scene\": "
              << jsonString(a.scene) << ",\n  \"receivers\": " << jsonString(optionName(receivers.kind))
              << ",\n  \"samples\": " << r.samples << ",\n  \"skipped_inside_closed\": " << r.insideClosed
              << ",\n  \"near_boundary\": " << r.nearBoundary
              << ",\n  \"mismatch_near_boundary\": " << jsonNumber(r.fractionNearBoundary())
              << ",\n  \"mismatch_elsewhere\": " << jsonNumber(r.fractionElsewhere())
              << ",\n  \"mismatch_near_boundary_count\": " << r.mismatchNearBoundary
              << ",\n  \"mismatch_elsewhere_count\": " << r.mismatchElsewhere << ",\n  \"reference\": "
              << jsonString(a.reference) << "\n}\n";
  } else {
    std::printf("%s (a DAG-MH) against %s: %llu receiver points compared (%llu skipped: offset point inside closed "
                "geometry)\n  receivers: %s\n",
                a.file.c_str(), a.scene.c_str(), static_cast<unsigned long long>(r.samples),
                static_cast<unsigned long long>(r.insideClosed), receiversText(art.options, art.receiverHash).c_str());
    std::printf("  near a shadow boundary (within one voxel): %llu points, %llu mismatches = %.4f%% of all\n",
                static_cast<unsigned long long>(r.nearBoundary), static_cast<unsigned long long>(r.mismatchNearBoundary),
                100.0 * r.fractionNearBoundary());
    std::printf("  elsewhere: %llu mismatches = %.4f%%\n", static_cast<unsigned long long>(r.mismatchElsewhere),
                100.0 * r.fractionElsewhere());
    for (const auto& e : r.elsewhereExamples)
      std::printf("    mismatch at (%.9g, %.9g, %.9g) normal (%.4f, %.4f, %.4f)\n", e.point.x, e.point.y, e.point.z,
                  e.normal.x, e.normal.y, e.normal.z);
    printOracles(a, r);
  }
  return r.mismatchElsewhere == 0 && r.oraclesDisagreeElsewhere == 0 ? 0 : 1;
}

int runVerify(const VerifyArgs& a) {
  if (a.samples == 0) throw InputError("--samples must be at least 1");
  const std::vector<uint8_t> bytes = readFile(a.file);
  if (isDmh(bytes.data(), bytes.size())) return verifyDagMh(a, bytes);
  if (cpvsFormatVersion(bytes.data(), bytes.size(), a.file) == kBundleFormatVersion) return verifyBundle(a, bytes);
  CpvsArtifact art = decodeCpvs(bytes.data(), bytes.size(), a.file);
  Scene scene = openMatchingScene(a.scene, art);
  const ReceiverDeclaration receivers = bakedReceivers(a, art.options, art.receiverHash);
  // Translucent meshes are not in the CPVS: its answers are held against the exact shadows
  // of the opaque part, and the file's tree of them against the scene's.
  const bool translucent = hasTranslucentMeshes(scene);
  const Scene opaque = translucent ? opaquePart(scene) : Scene{};
  const Scene& casters = translucent ? opaque : scene;
  // The receivers are sampled on the whole scene (glass receives too), by its own rays.
  std::optional<RayScene> sceneRays;
  if (translucent) sceneRays.emplace(scene, art.grid.origin);
  RayScene rays(casters, art.grid.origin);
  ShadowQuery q(art.grid, std::move(art.packed));
  const auto samples = sampleReceivers(scene, translucent ? *sceneRays : rays, art.options.closed, art.grid.frame.dir,
                                       receivers, a.samples, a.seed);
  std::optional<TopTree> tree;
  const ExactOracles oracles = oraclesFor(a, casters, PsvLight::sun(art.grid.frame.dir), tree);
  VerifyResult r = verifySamples(q, art.options.closed, rays, samples, oracles);
  const TranslucentCheck glass = checkTranslucent(art, scene, samples);
  // Sampled cameras: how much of what an independent sample sees the bake left free.
  const bool sampledCameras =
      receivers.kind == ReceiverKind::Cameras && receivers.cameraVisibility == CameraVisibility::Sampled;
  CameraViews independent;
  if (sampledCameras) {
    const std::vector<uint8_t> declared = receivingSides(scene, receivers);
    independent = sampleCameraViews(scene, receivers, a.seed ? a.seed : 1, &declared);
  }
  const double outsideShare = independent.hits ? double(independent.hitsOutside) / double(independent.hits) : 0;
  const double areaShare = independent.areaDeclared > 0 ? independent.areaOutside / independent.areaDeclared : 0;
  if (a.json) {
    std::ostringstream s;
    s << "{\n  \"file\": " << jsonString(a.file) << ",\n  \"scene\": " << jsonString(a.scene)
      << ",\n  \"receivers\": " << jsonString(optionName(receivers.kind))
      << ",\n  \"samples\": " << r.samples << ",\n  \"skipped_inside_closed\": " << r.insideClosed
      << ",\n  \"near_boundary\": " << r.nearBoundary
      << ",\n  \"mismatch_near_boundary\": " << jsonNumber(r.fractionNearBoundary())
      << ",\n  \"mismatch_elsewhere\": " << jsonNumber(r.fractionElsewhere())
      << ",\n  \"mismatch_near_boundary_count\": " << r.mismatchNearBoundary
      << ",\n  \"mismatch_elsewhere_count\": " << r.mismatchElsewhere << ",\n  \"reference\": " << jsonString(a.reference);
    if (a.reference == "both")
      s << ",\n  \"oracles_compared\": " << r.oraclesCompared
        << ",\n  \"oracles_disagree_near_boundary_count\": " << r.oraclesDisagreeNearBoundary
        << ",\n  \"oracles_disagree_elsewhere_count\": " << r.oraclesDisagreeElsewhere;
    if (glass.expected || glass.stored)
      s << ",\n  \"translucent\": {\"frusta\": " << glass.frusta << ", \"tree_is_the_scenes\": " << (glass.same ? "true" : "false")
        << ", \"points\": " << glass.points << ", \"points_under_glass\": " << glass.darkened
        << ", \"walk_differs_from_brute_force\": " << glass.differ << "}";
    if (sampledCameras)
      s << ",\n  \"independent_camera_sample\": {\"positions\": " << independent.positions
        << ", \"rays\": " << independent.rays << ", \"hits\": " << independent.hits
        << ", \"hits_outside\": " << independent.hitsOutside << ", \"hits_outside_share\": " << jsonNumber(outsideShare)
        << ", \"area_outside_share\": " << jsonNumber(areaShare) << "}";
    s << "\n}\n";
    std::cout << s.str();
  } else {
    std::printf("%s against %s: %llu receiver points compared (%llu skipped: offset point inside closed geometry)\n",
                a.file.c_str(), a.scene.c_str(), static_cast<unsigned long long>(r.samples),
                static_cast<unsigned long long>(r.insideClosed));
    std::printf("  receivers: %s\n",
                receiversText(art.options, art.receiverHash).c_str());
    std::printf("  near a shadow boundary (within one voxel): %llu points, %llu mismatches = %.4f%% of all\n",
                static_cast<unsigned long long>(r.nearBoundary), static_cast<unsigned long long>(r.mismatchNearBoundary),
                100.0 * r.fractionNearBoundary());
    std::printf("  elsewhere: %llu mismatches = %.4f%%\n", static_cast<unsigned long long>(r.mismatchElsewhere),
                100.0 * r.fractionElsewhere());
    if (sampledCameras)
      std::printf("  sampled cameras: an independent sample (%llu positions, %llu rays) hit %llu times, %llu (%.4f%%) "
                  "on sides the bake left free (%.4f%% of the declared area); lookups there may be wrong\n",
                  static_cast<unsigned long long>(independent.positions), static_cast<unsigned long long>(independent.rays),
                  static_cast<unsigned long long>(independent.hits), static_cast<unsigned long long>(independent.hitsOutside),
                  100.0 * outsideShare, 100.0 * areaShare);
    for (const auto& e : r.elsewhereExamples)
      std::printf("    mismatch at (%.9g, %.9g, %.9g) normal (%.4f, %.4f, %.4f)\n", e.point.x, e.point.y, e.point.z,
                  e.normal.x, e.normal.y, e.normal.z);
    printOracles(a, r);
    if (glass.expected || glass.stored)
      std::printf("  translucent casters: %s; at the %llu points (%llu under glass) the tree's walk %s the brute force "
                  "over its %zu frusta\n",
                  !glass.stored ? "the scene has some, the file carries no tree of them"
                  : !glass.expected ? "the file carries a tree, the scene has none"
                  : glass.same      ? "the file's tree is the scene's, node for node"
                                    : "the file's tree is NOT the scene's",
                  static_cast<unsigned long long>(glass.points), static_cast<unsigned long long>(glass.darkened),
                  glass.differ ? ("differs from (" + std::to_string(glass.differ) + " points)").c_str() : "equals",
                  glass.frusta);
  }
  // A mismatch away from every boundary is a wrong answer, not quantization; two exact
  // oracles that differ there have a bug between them: fail. So does a translucent tree
  // other than the scene's.
  const bool glassOk = glass.expected == glass.stored && glass.same && glass.differ == 0;
  return r.mismatchElsewhere == 0 && r.oraclesDisagreeElsewhere == 0 && glassOk ? 0 : 1;
}

}  // namespace

void addVerifyCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<VerifyArgs>();
  CLI::App* c = app.add_subcommand(
      "verify", "Compare CPVS lookups with exact shadow rays at points sampled on the scene (exit 1 if any mismatch "
                "lies away from a shadow boundary)");
  c->add_option("file", a->file, ".cpvs or .dmh file")->required();
  c->add_option("scene", a->scene, "The scene it was baked from (file, city[:BLOCKS[:SEED]] or landscape[:SIZE[:SEED]])")->required();
  c->add_option("--samples,-n", a->samples, "Surface points to compare")->capture_default_str();
  c->add_option("--seed", a->seed, "Sampling seed")->capture_default_str();
  c->add_flag("--json", a->json, "Print the result as JSON");
  c->add_option("--reference", a->reference,
                "The exact visibility compared with: embree (shadow rays), psv (partitioned shadow volumes, a TOP "
                "tree of the scene) or both (Embree, and the TOP tree as a second oracle: exit 1 also if the two "
                "differ away from a shadow boundary)")
      ->check(CLI::IsMember({"embree", "psv", "both"}))
      ->capture_default_str();
  // The file records which receivers it was baked for and verify samples those; a volume
  // or camera regions are given again, as baked (--receiver-pcf is the file's).
  addReceiverFlags(c, a->receivers);
  c->callback([a, &status] { status = runVerify(*a); });
}

}  // namespace cpvs::cli
