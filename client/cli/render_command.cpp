// `cpvs render`: a picture of the scene in the sun with the baked shadows, optionally next
// to exact ray-traced shadows and their difference.
#include <spdlog/spdlog.h>

#include <cstdio>
#include <filesystem>
#include <memory>

#include "cli_util.h"
#include "commands.h"
#include "cpvs/base/error.h"
#include "cpvs/eval/render.h"

namespace cpvs::cli {

namespace {

struct RenderArgs {
  std::string file, scene, camera, out, size = "960x600";
  int pcf = 3;
  bool reference = false;
};

void parseSize(const std::string& text, int& w, int& h) {
  size_t x = text.find('x');
  auto bad = [&] { return InputError("--size '" + text + "': expected WIDTHxHEIGHT, e.g. 960x600"); };
  if (x == std::string::npos) throw bad();
  try {
    size_t used = 0;
    w = std::stoi(text.substr(0, x), &used);
    if (used != x) throw bad();
    h = std::stoi(text.substr(x + 1), &used);
    if (used != text.size() - x - 1) throw bad();
  } catch (const std::logic_error&) {
    throw bad();
  }
  if (w < 1 || h < 1 || w > 16384 || h > 16384) throw InputError("--size '" + text + "': each side must be 1..16384");
}

/// Writes `base`.exr and `base`.png.
void writeBoth(const std::string& base, const Image& img) {
  writeExr(base + ".exr", img);
  writePng(base + ".png", img);
}

int runRender(const RenderArgs& a) {
  int w = 0, h = 0;
  parseSize(a.size, w, h);
  namespace fs = std::filesystem;
  fs::path out(a.out);
  std::string ext = out.extension().string();
  if (ext != ".png" && ext != ".exr" && !ext.empty())
    throw InputError("--out '" + a.out + "': name an image .png or .exr (both are written)");
  std::string base = (out.parent_path() / out.stem()).string();

  CpvsArtifact art = readCpvs(a.file);
  Scene scene = openMatchingScene(a.scene, art);
  RayScene rays(scene, art.grid.origin);
  ShadowQuery q(art.grid, std::move(art.packed));
  const Vec3 L = art.grid.frame.dir;
  Camera cam = a.camera.empty() ? defaultCamera(scene, L, double(w) / h) : Camera::parse(a.camera);
  CameraHits hits = traceCamera(scene, rays, cam, w, h);
  std::vector<float> vis = cpvsVisibility(hits, q, a.pcf);
  writeBoth(base, shadeHits(hits, vis, L));
  std::printf("Wrote %s.png and %s.exr (CPVS shadows, PCF %d)\n", base.c_str(), base.c_str(), a.pcf);
  if (a.reference) {
    std::vector<float> exact = exactVisibility(hits, rays, art.grid);
    writeBoth(base + "-reference", shadeHits(hits, exact, L));
    // The difference compares binary lookups so that a filtered edge is not counted.
    std::vector<float> binary = a.pcf == 1 ? vis : cpvsVisibility(hits, q, 1);
    uint64_t compared = 0, differing = 0;
    writeBoth(base + "-diff", differenceImage(hits, binary, exact, L, &compared, &differing));
    std::printf("Wrote %s-reference.png/.exr (exact ray-traced shadows) and %s-diff.png/.exr\n", base.c_str(),
                base.c_str());
    std::printf("  %llu of %llu sunward pixels differ (%.3f%%): red = CPVS darker, blue = CPVS brighter\n",
                static_cast<unsigned long long>(differing), static_cast<unsigned long long>(compared),
                compared ? 100.0 * double(differing) / double(compared) : 0.0);
  }
  std::printf("Camera: %.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n", cam.eye.x, cam.eye.y, cam.eye.z, cam.target.x,
              cam.target.y, cam.target.z, cam.fovDeg);
  return 0;
}

}  // namespace

void addRenderCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<RenderArgs>();
  CLI::App* c = app.add_subcommand("render", "Render the scene lit by the sun with the baked shadows (PNG and EXR)");
  c->add_option("file", a->file, ".cpvs file")->required();
  c->add_option("scene", a->scene, "The scene it was baked from (file, or city[:BLOCKS[:SEED]])")->required();
  c->add_option("--out,-o", a->out, "Output image; NAME.png and NAME.exr are both written")->required();
  c->add_option("--camera", a->camera,
                "EX,EY,EZ,TX,TY,TZ[,FOV]: eye, target and vertical field of view in degrees "
                "(default: a three-quarter view from the sunny side)");
  c->add_option("--size", a->size, "Image size WIDTHxHEIGHT")->capture_default_str();
  c->add_option("--pcf", a->pcf, "Filter width in texels: 1, 3, 5, 7 or 9")
      ->check(CLI::IsMember({1, 3, 5, 7, 9}))->capture_default_str();
  c->add_flag("--reference", a->reference,
              "Also render exact ray-traced shadows (NAME-reference) and the difference (NAME-diff)");
  c->callback([a, &status] { status = runRender(*a); });
}

}  // namespace cpvs::cli
