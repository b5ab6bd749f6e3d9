// `cpvs verify`: CPVS lookups against exact Embree shadow rays on the scene's surfaces.
#include <spdlog/spdlog.h>

#include <cstdio>
#include <iostream>
#include <memory>
#include <sstream>

#include "cli_util.h"
#include "commands.h"
#include "cpvs/base/error.h"
#include "cpvs/eval/verify.h"

namespace cpvs::cli {

namespace {

struct VerifyArgs {
  std::string file, scene;
  uint64_t samples = 100000, seed = 1;
  bool json = false;
};

int runVerify(const VerifyArgs& a) {
  if (a.samples == 0) throw InputError("--samples must be at least 1");
  CpvsArtifact art = readCpvs(a.file);
  Scene scene = openMatchingScene(a.scene, art);
  RayScene rays(scene, art.grid.origin);
  ShadowQuery q(art.grid, std::move(art.packed));
  VerifyResult r = verifyArtifact(q, art.options.closed, scene, rays, a.samples, a.seed);
  if (a.json) {
    std::ostringstream s;
    s << "{\n  \"file\": " << jsonString(a.file) << ",\n  \"scene\": " << jsonString(a.scene)
      << ",\n  \"samples\": " << r.samples << ",\n  \"skipped_inside_closed\": " << r.insideClosed
      << ",\n  \"near_boundary\": " << r.nearBoundary
      << ",\n  \"mismatch_near_boundary\": " << jsonNumber(r.fractionNearBoundary())
      << ",\n  \"mismatch_elsewhere\": " << jsonNumber(r.fractionElsewhere())
      << ",\n  \"mismatch_near_boundary_count\": " << r.mismatchNearBoundary
      << ",\n  \"mismatch_elsewhere_count\": " << r.mismatchElsewhere << "\n}\n";
    std::cout << s.str();
  } else {
    std::printf("%s against %s: %llu surface points compared (%llu skipped: offset point inside closed geometry)\n",
                a.file.c_str(), a.scene.c_str(), static_cast<unsigned long long>(r.samples),
                static_cast<unsigned long long>(r.insideClosed));
    std::printf("  near a shadow boundary (within one voxel): %llu points, %llu mismatches = %.4f%% of all\n",
                static_cast<unsigned long long>(r.nearBoundary), static_cast<unsigned long long>(r.mismatchNearBoundary),
                100.0 * r.fractionNearBoundary());
    std::printf("  elsewhere: %llu mismatches = %.4f%%\n", static_cast<unsigned long long>(r.mismatchElsewhere),
                100.0 * r.fractionElsewhere());
    for (const auto& e : r.elsewhereExamples)
      std::printf("    mismatch at (%.9g, %.9g, %.9g) normal (%.4f, %.4f, %.4f)\n", e.point.x, e.point.y, e.point.z,
                  e.normal.x, e.normal.y, e.normal.z);
  }
  // A mismatch away from every boundary is a wrong answer, not quantization: fail.
  return r.mismatchElsewhere == 0 ? 0 : 1;
}

}  // namespace

void addVerifyCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<VerifyArgs>();
  CLI::App* c = app.add_subcommand(
      "verify", "Compare CPVS lookups with exact shadow rays at points sampled on the scene (exit 1 if any mismatch "
                "lies away from a shadow boundary)");
  c->add_option("file", a->file, ".cpvs file")->required();
  c->add_option("scene", a->scene, "The scene it was baked from (file, city[:BLOCKS[:SEED]] or landscape[:SIZE[:SEED]])")->required();
  c->add_option("--samples,-n", a->samples, "Surface points to compare")->capture_default_str();
  c->add_option("--seed", a->seed, "Sampling seed")->capture_default_str();
  c->add_flag("--json", a->json, "Print the result as JSON");
  c->callback([a, &status] { status = runVerify(*a); });
}

}  // namespace cpvs::cli
