#include "cpvs/bake/bake_lights.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <mutex>

#include "cpvs/bake/bake.h"
#include "cpvs/light/area_light.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/light_plan.h"
#include "cpvs/base/error.h"
#include "cpvs/base/text.h"
#include "cpvs/dag/node_pool.h"
#include "cpvs/dag/packed_dag.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

std::string lightPlanJson(const LightBundle& b, const std::vector<double>& closest) {
  std::string out = "{\"grids\": [";
  for (size_t k = 0; k < b.grids.size(); ++k) {
    const BundleGrid& g = b.grids[k];
    const double c = k < closest.size() ? closest[k] : std::nan("");
    out += std::string(k ? ", " : "") + "{\"light\": " + std::to_string(g.light) + ", \"near\": " +
           jsonNumber(g.grid.near()) + ", \"far\": " + jsonNumber(g.grid.far()) + ", \"resolution\": " +
           std::to_string(g.grid.resolution()) + ", \"closest\": " + (std::isfinite(c) ? jsonNumber(c) : "null") +
           ", \"bytes\": " + std::to_string(g.bytes) + "}";
  }
  out += "]";
  bool fixtures = false;
  for (size_t i = 0; i < b.lights.size(); ++i) {
    const Light& l = b.lights[i].light;
    if (l.exclude.empty()) continue;
    out += std::string(fixtures ? ", " : ", \"fixtures\": [") + "{\"light\": " + std::to_string(i) + ", \"exclude\": [";
    for (size_t n = 0; n < l.exclude.size(); ++n) out += (n ? ", " : "") + jsonString(l.exclude[n]);
    out += "]}";
    fixtures = true;
  }
  out += fixtures ? "]}" : "}";
  // A bundle of thousands of point lights would pass the largest plan a file records.
  if (out.size() > kMaxPlanBytes)
    return "{\"grids\": " + std::to_string(b.grids.size()) + ", \"per_grid\": \"omitted: more than " +
           std::to_string(kMaxPlanBytes) + " bytes\"}";
  return out;
}

bool sceneAreaLightHasSize(const SceneLight& s) {
  return isFinite(s.edgeU) && isFinite(s.edgeV) && length(cross(s.edgeU, s.edgeV)) > 0;
}

std::vector<Light> sceneLights(const Scene& scene) {
  std::vector<Light> out;
  uint32_t areas = 0;
  for (const SceneLight& s : scene.lights) {
    if (s.type == SceneLight::Type::Area) {
      if (!sceneAreaLightHasSize(s)) continue;
      AreaLight a;
      a.name = validUtf8Prefix(s.name, kMaxLightNameBytes - 16);  // room for " vpl 1023"
      a.centre = s.position;
      a.edgeU = s.edgeU;
      a.edgeV = s.edgeV;
      a.seed = ++areas;
      a.range = s.range;
      if (isFinite(s.color) && (s.color.x > 0 || s.color.y > 0 || s.color.z > 0)) {
        const double peak = std::max({s.color.x, s.color.y, s.color.z});
        a.colour = s.color / peak;
        a.intensity = peak;
      }
      for (Light& l : vplsOf(a, areas)) out.push_back(std::move(l));
      continue;
    }
    if (s.type != SceneLight::Type::Spot && s.type != SceneLight::Type::Point) continue;
    Light l;
    // A cone wider than one grid holds (COLLADA's, as assimp reads it, often is) is
    // baked as a point light's cube; its axis and cone stay for shading.
    const bool spot = s.type == SceneLight::Type::Spot && s.outerConeDeg <= kMaxConeDeg;
    l.kind = spot ? LightKind::Spot : LightKind::Point;
    l.name = validUtf8Prefix(s.name, kMaxLightNameBytes);
    l.position = s.position;
    if (s.type == SceneLight::Type::Spot) {
      l.direction = s.direction;
      l.coneDeg = s.outerConeDeg;
    }
    l.range = s.range;
    // A name a file could not pass through the contract as it is (not UTF-8) names no fixture.
    const bool nameable = !s.name.empty() && validUtf8Prefix(s.name, kMaxExcludeNameBytes) == s.name;
    // Only where the name is the node's alone: a mesh or material of that name elsewhere
    // (an instanced lamp mesh named as its first node) would leave those out too.
    bool placesMeshes = false, alone = nameable;
    for (const SceneMesh& m : scene.meshes)
      if (meshIsNamed(m, s.name)) {
        placesMeshes |= m.node == s.name;
        alone &= m.node == s.name;
      }
    if (placesMeshes && alone) l.exclude = {s.name};
    if (isFinite(s.color) && (s.color.x > 0 || s.color.y > 0 || s.color.z > 0)) {
      // Shading takes the colour and the intensity apart: the brightest channel is the intensity.
      const double peak = std::max({s.color.x, s.color.y, s.color.z});
      l.colour = s.color / peak;
      l.intensity = peak;
    }
    out.push_back(std::move(l));
  }
  return out;
}

std::vector<Light> withSceneLights(const Scene& scene, std::vector<Light> given, const std::string& what) {
  std::vector<Light> lights = sceneLights(scene);
  if (lights.empty()) throw InputError(what + " holds no point, spot or area light");
  // The given area lights are numbered after the scene's.
  uint32_t sceneAreas = 0;
  for (const Light& l : lights) sceneAreas = std::max(sceneAreas, l.area);
  for (Light& l : given)
    if (l.area != 0) l.area += sceneAreas;
  lights.insert(lights.end(), std::make_move_iterator(given.begin()), std::make_move_iterator(given.end()));
  return lights;
}

LightBundle planLights(const Scene& scene, const std::vector<Light>& lights, double footprint, const BakeOptions& options,
                       std::vector<double>& closest, const ReceiverDeclaration& receivers) {
  if (options.receivers != receivers.kind ||
      (receivers.kind != ReceiverKind::Everywhere && options.receiverPcf != receivers.maxPcf))
    throw InputError(std::string("baking lights: the options name receivers '") + optionName(options.receivers) +
                     "' (pcf " + std::to_string(options.receiverPcf) + "), the declaration '" +
                     optionName(receivers.kind) + "' (pcf " + std::to_string(receivers.maxPcf) + ")");
  checkReceiverDeclaration(receivers);
  checkLightCount(lights.size());
  if (scene.triangleCount() == 0) throw InputError("baking lights: the scene is empty");
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  for (size_t i = 0; i < lights.size(); ++i) {
    checkLight(lights[i], lo, hi, lightLabel(lights[i], i));
    if (lights[i].name.size() > kMaxLightNameBytes)
      throw InputError(lightLabel(lights[i], i) + ": the name is longer than " + std::to_string(kMaxLightNameBytes) + " bytes");
  }
  LightBundle b;
  b.options = options;
  closest.clear();
  for (size_t i = 0; i < lights.size(); ++i) {
    BundleLight bl{lights[i], uint32_t(b.grids.size()), 0};
    Scene storage;
    for (LightGridPlan& p : planLightGrids(castersOf(scene, lights[i].exclude, lightLabel(lights[i], i), storage), lights[i], footprint)) {
      b.grids.push_back({std::move(p.grid), p.tanCone, uint32_t(i), 0});
      closest.push_back(p.closest);
    }
    bl.gridCount = uint32_t(b.grids.size()) - bl.firstGrid;
    b.lights.push_back(std::move(bl));
  }
  uint64_t slices = 0;
  for (const BundleGrid& g : b.grids) slices += g.grid.resolution() + 1;
  if (slices > kMaxBundleSlices)
    throw InputError(std::to_string(b.grids.size()) + " grids of these resolutions hold " + std::to_string(slices) +
                     " slice boundaries; a bundle holds at most " + std::to_string(kMaxBundleSlices) +
                     " (lower --footprint's resolutions or bake fewer lights)");
  return b;
}

LightBundle bakeLights(const Scene& scene, const std::vector<Light>& lights, double footprint,
                       const BakeOptions& options, const Hash128& sceneHash, StageTimes* times,
                       const ProgressFn& progress, std::vector<double>* gridSeconds, const ReceiverDeclaration& receivers) {
  std::vector<double> closest;
  LightBundle b = planLights(scene, lights, footprint, options, closest, receivers);
  b.sceneHash = sceneHash;
  b.receiverHash = receiverHash(receivers);
  if (receivers.kind == ReceiverKind::Cameras && receivers.cameraVisibility == CameraVisibility::Sampled)
    (void)receivingSides(scene, receivers);  // cast once, before the grids share it
  StageTimes local;
  StageTimes& st = times ? *times : local;
  const size_t n = b.grids.size();
  std::vector<Dag> dags(n);
  std::vector<StageTimes> gridTimes(n);
  if (gridSeconds) gridSeconds->assign(n, 0);
  if (progress && !progress({"lights", 0, n})) throw Cancelled();
  // Grids bake side by side, each parallel inside too: one grid alone leaves cores idle
  // between its stages. Isolated, so that a thread waiting inside one grid's bake does
  // not start another (at most one grid per thread in memory). Each grid's DAG depends
  // on it alone, and they are shared in grid order: the bytes do not depend on the order.
  std::mutex reporting;
  size_t done = 0;
  bool cancelled = false;
  // A light with a fixture bakes its grids (a point light's six) with one copy of the
  // scene without it, made by the first of them and freed after the last.
  struct Casters {
    std::mutex made;
    std::unique_ptr<Scene> scene;
    size_t gridsLeft = 0;
  };
  std::vector<Casters> casters(b.lights.size());
  for (const BundleGrid& g : b.grids) ++casters[g.light].gridsLeft;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1), [&](const tbb::blocked_range<size_t>& range) {
    for (size_t k = range.begin(); k != range.end(); ++k) {
      {
        std::lock_guard<std::mutex> lock(reporting);
        if (cancelled) return;
      }
      const auto start = std::chrono::steady_clock::now();
      tbb::this_task_arena::isolate([&] {
        const uint32_t i = b.grids[k].light;
        const Light& light = b.lights[i].light;
        Casters& c = casters[i];
        const Scene* cast = &scene;
        if (!light.exclude.empty()) {
          std::lock_guard<std::mutex> lock(c.made);
          if (!c.scene) {
            auto made = std::make_unique<Scene>();
            castersOf(scene, light.exclude, lightLabel(light, i), *made);
            c.scene = std::move(made);
          }
          cast = c.scene.get();
        }
        {
          const BakeScene prepared(*cast, b.grids[k].grid, b.grids[k].tanCone, options.renderer, 0, receivers, &scene);
          dags[k] = bakeGrid(prepared, options, &gridTimes[k]);
        }
        if (!light.exclude.empty()) {
          std::lock_guard<std::mutex> lock(c.made);
          if (--c.gridsLeft == 0) c.scene.reset();
        }
      });
      std::lock_guard<std::mutex> lock(reporting);
      if (gridSeconds) (*gridSeconds)[k] = secondsSince(start);
      ++done;
      if (progress && !cancelled && !progress({"lights", done, n})) cancelled = true;
    }
  });
  if (cancelled) throw Cancelled();
  for (const StageTimes& t : gridTimes) st.add(t);
  auto start = std::chrono::steady_clock::now();
  finishLightBundle(b, std::move(dags), closest);
  st.add("merge", secondsSince(start));
  return b;
}

void finishLightBundle(LightBundle& b, std::vector<Dag>&& dags, const std::vector<double>& closest) {
  CPVS_CHECK(dags.size() == b.grids.size());
  NodePool pool;
  {
    std::vector<const Dag*> all;
    for (const Dag& d : dags) all.push_back(&d);
    pool = shareNodes(all);
    std::vector<Dag>().swap(dags);  // the pool holds every node now
  }
  for (size_t k = 0; k < b.grids.size(); ++k) b.grids[k].bytes = reachableBytes(pool, k);
  b.poolBytes = pool.bytes();
  b.pool = std::make_shared<const std::vector<uint32_t>>(packPool(pool.leaves, pool.levels, pool.roots));
  b.plan = lightPlanJson(b, closest);
}

const Scene& castersOf(const Scene& scene, const std::vector<std::string>& exclude, const std::string& source,
                       Scene& storage) {
  if (exclude.empty()) return scene;
  storage = withoutMeshes(scene, exclude, source);
  return storage;
}

double defaultFootprint(const Scene& scene) {
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  return length(hi - lo) / 4096;
}

}  // namespace cpvs
