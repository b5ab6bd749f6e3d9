#include "coordinator/job_service.h"

#include <spdlog/spdlog.h>

#include <bit>
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>

#include "coordinator/bundle_job.h"
#include "coordinator/clock.h"
#include "coordinator/dag_mh_job.h"
#include "coordinator/stored_spec.h"
#include "cpvs/bake/bake.h"
#include "cpvs/bake/bake_lights.h"
#include "cpvs/bake/bake_plan.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/raster_scene.h"
#include "cpvs/bake/tile_plan.h"
#include "cpvs/base/error.h"
#include "cpvs/base/parse.h"
#include "cpvs/base/text.h"
#include "cpvs/dag/packed_layout.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/net/convert.h"
#include "cpvs/net/model_convert.h"
#include "cpvs/net/receiver_declaration.h"
#include "cpvs/net/error_kind.h"
#include "cpvs/query/medium.h"

namespace cpvs::server {

namespace {

// The job's declared media, checked, as the plan takes them. InputError for a bad one.
std::vector<BakePlan::Medium> mediaOf(const pb::BakeSpec& spec) {
  std::vector<BakePlan::Medium> out;
  for (int k = 0; k < spec.media_size(); ++k) {
    const pb::Medium& m = spec.media(k);
    const std::string label = "media[" + std::to_string(k) + "]";
    if (m.name().size() > 256) throw InputError(label + ": the name is longer than 256 bytes");
    try {
      checkMedium({m.scattering(), m.absorption(), m.g()});
    } catch (const InputError& e) {
      throw InputError(label + ": " + e.what());
    }
    out.push_back({m.name(), "declared", m.scattering(), m.absorption(), m.g(), false, ""});
  }
  return out;
}

}  // namespace

using net::ErrorKind;
using net::FarmError;

JobService::JobService(FarmStore& store, SceneStore& scenes, ArtifactStore& artifacts, MergeScheduler& merges,
                       ChangeFeed& feed, JobLimits limits)
    : store_(store), scenes_(scenes), artifacts_(artifacts), merges_(merges), feed_(feed), limits_(limits) {}

std::optional<pb::JobStatus> JobService::knownRequest(const pb::SubmitBakeRequest& request, const Access& access) {
  auto existing = store_.jobByRequest(request.request_id());
  if (!existing) return std::nullopt;
  // Request ids are one namespace: another client's says nothing about its job.
  if (!access.sees(existing->owner))
    throw FarmError(ErrorKind::AlreadyExists, "request_id " + request.request_id() + " is taken; use another");
  // Compared as the model writes specs (defaults dropped, lights' colours filled in): a
  // job stored as its client sent it, before specs crossed the model, is the same job.
  pb::BakeSpec stored = bakeSpecOf(*existing);
  try {
    stored = net::toProto(net::modelOf(stored));
  } catch (const InputError&) {  // not a spec the model reads: compared as it is
  }
  if (!sameMessage(stored, request.spec()))
    throw FarmError(ErrorKind::AlreadyExists,
                    "request_id " + request.request_id() + " was used for a different job (" + existing->id + ")");
  return toStatus(*existing);
}

void JobService::checkRoom(const Access& access) {
  if (store_.activeJobCount() >= limits_.maxActiveJobs)
    throw FarmError(ErrorKind::ResourceExhausted,
                    "the farm already holds " + std::to_string(limits_.maxActiveJobs) + " unfinished jobs");
  // One client cannot take every place (R15): an administrator, or a farm without
  // tokens, is not counted per client.
  if (!access.everything && store_.activeJobCount(access.owner) >= limits_.maxActiveJobsPerClient)
    throw FarmError(ErrorKind::ResourceExhausted, "this client already has " +
                                                      std::to_string(limits_.maxActiveJobsPerClient) +
                                                      " unfinished jobs, the most one client may have");
}

TileCosts JobService::costsOf(const std::string& jobId) const {
  const auto now = std::chrono::steady_clock::now();
  {
    std::lock_guard lock(costsMutex_);
    const auto it = costs_.find(jobId);
    if (it != costs_.end() && now - it->second.first < std::chrono::seconds(5)) return it->second.second;
  }
  TileCosts costs = store_.tileCosts(jobId);
  std::lock_guard lock(costsMutex_);
  if (costs_.size() >= 1024) costs_.clear();  // running jobs are far fewer; finished ones drop out
  costs_[jobId] = {now, costs};
  return costs;
}

pb::JobStatus JobService::toStatus(const JobRecord& j) const {
  pb::JobStatus s;
  s.set_job_id(j.id);
  s.set_request_id(j.requestId);
  s.set_state(pb::JobState(int(j.state)));
  try {
    *s.mutable_spec() = bakeSpecOf(j);
  } catch (const FormatError& e) {
    spdlog::error("{}", e.what());  // the status still tells the job's state
  }
  s.set_tiles_total(j.tilesTotal);
  s.set_tiles_done(j.tilesDone);
  s.set_tiles_untouched(j.tilesUntouched);
  s.set_tiles_unread(j.tilesUnread);
  s.set_tiles_reused(j.tilesReused);
  for (const auto& [stage, seconds] : j.stages) {
    auto* st = s.add_stages();
    st->set_stage(stage);
    st->set_seconds(seconds);
  }
  int64_t end = isFinal(j.state) && j.finishedMs ? j.finishedMs : nowMs();
  double elapsed = double(end - j.createdMs) / 1000.0;
  s.set_seconds_elapsed(elapsed);
  double eta = -1;
  const uint64_t baked = j.tilesDone - j.tilesUntouched - j.tilesUnread;  // those took no time
  if (j.state == JobState::Running && baked > 0 && j.startedMs > 0) {
    const double running = double(nowMs() - j.startedMs) / 1000.0;
    eta = running * double(j.tilesTotal - j.tilesDone) / double(baked);
    // Better, where the tiles' triangles are known: the worker seconds the tiles left
    // should take by the law fitted to those done (TileEta's), turned into wall seconds
    // at the rate the farm has turned worker seconds into wall seconds so far.
    const TileCosts costs = costsOf(j.id);
    if (const auto law = TileCostLaw::fit(costs.done); law && costs.done.t > 0)
      eta = law->seconds(double(costs.leftTiles), costs.leftWork) * running / costs.done.t;
  }
  s.set_eta_seconds(isFinal(j.state) ? 0 : eta);
  s.set_error(j.error);
  s.set_bytes(j.bytes);
  s.set_file_bytes(j.fileBytes);
  s.set_resolution(resolutionOf(j));
  if (j.isBundle()) {
    // Grids are in light order and every light has at least one.
    s.set_lights(j.grids.back().light + 1);
    s.set_grids(uint32_t(j.grids.size()));
  }
  s.set_peak_merge_bytes(j.peakMergeBytes);
  s.set_created_unix_ms(j.createdMs);
  return s;
}

pb::JobStatus JobService::submit(const std::string& requestId, const net::BakeSpec& bake, const Access& access) {
  // Stored, compared and planned as the contract's message (stored_spec.h).
  pb::SubmitBakeRequest request;
  request.set_request_id(requestId);
  *request.mutable_spec() = net::toProto(bake);
  const pb::BakeSpec& spec = request.spec();
  if (request.request_id().empty() || request.request_id().size() > 128)
    throw FarmError(ErrorKind::InvalidArgument, "request_id must be 1..128 characters");
  if (auto existing = knownRequest(request, access)) return *existing;
  if (spec.name().size() > 256) throw FarmError(ErrorKind::InvalidArgument, "name is longer than 256 characters");
  if (std::abs(spec.priority()) > 1000) throw FarmError(ErrorKind::InvalidArgument, "priority must be in -1000..1000");
  if (net::isLightBundle(spec)) {
    if (spec.format() != pb::ARTIFACT_FORMAT_CPVS)
      throw FarmError(ErrorKind::InvalidArgument, "format: a DAG-MH is the sun's; a light bundle is a CPVS");
    if (spec.media_size() > 0)
      throw FarmError(ErrorKind::InvalidArgument, "media are read through a sun's grid: a light bundle takes none");
    return submitBundle(request, access);
  }
  if (spec.has_pointer_grid() || spec.footprint() != 0)
    throw FarmError(ErrorKind::InvalidArgument, "pointer_grid and footprint are for light bundles (lights, scene_lights)");
  JobRecord j;
  LightFrame frame;
  BakeOptions options;
  int log2R = 0;
  std::vector<BakePlan::Medium> media;
  try {
    media = mediaOf(spec);
    frame = net::lightOf(spec);
    options = net::fromProto(spec.options());
    log2R = parseResolution(spec.resolution());
  } catch (const InputError& e) {
    throw FarmError(ErrorKind::InvalidArgument, e.what());
  }
  if (spec.format() == pb::ARTIFACT_FORMAT_DAG_MH) {
    try {
      checkDagMhSpec(spec, options, log2R);
    } catch (const InputError& e) {
      throw FarmError(ErrorKind::InvalidArgument, e.what());
    }
  }
  if (log2R < limits_.minLog2Resolution || log2R > limits_.maxLog2Resolution)
    throw FarmError(ErrorKind::InvalidArgument, "resolution " + spec.resolution() + " is outside this farm's limits (" +
                                                    std::to_string(1ull << limits_.minLog2Resolution) + " .. " +
                                                    std::to_string(1ull << limits_.maxLog2Resolution) + ")");
  const TilePlan plan(log2R, options.log2TileSize);  // the local bake's tiles, in its order
  if (plan.count() > limits_.maxTilesPerJob) {
    uint64_t smallest = uint64_t(1) << plan.log2TileSize();
    while (TilePlan(log2R, std::countr_zero(smallest)).count() > limits_.maxTilesPerJob) smallest *= 2;
    throw FarmError(ErrorKind::InvalidArgument,
                    "tile_size " + std::to_string(uint64_t(1) << plan.log2TileSize()) + " at resolution " +
                        spec.resolution() + " makes " + std::to_string(plan.count()) + " tiles; this farm takes at most " +
                        std::to_string(limits_.maxTilesPerJob) + " per job (tiles of at least " +
                        std::to_string(smallest) + " texels at this resolution)");
  }
  try {
    checkDepthSlices(spec.options().depth_slices(), log2R, "options.depth_slices");
  } catch (const InputError& e) {
    throw FarmError(ErrorKind::InvalidArgument, e.what());
  }
  checkRoom(access);  // before loading the scene, which may take long
  SceneStats stats;
  Scene scene = scenes_.load(spec.scene_hash(), &stats);
  OrthoGrid grid;
  ReceiverDeclaration receivers;
  try {
    grid = makeGrid(scene, frame, log2R, spec.options().depth_slices());
    receivers = net::declarationOf(net::modelOf(spec.options().receivers()), [&](const std::string& hash) { return scenes_.load(hash); });
  } catch (const InputError& e) {
    throw FarmError(ErrorKind::InvalidArgument, e.what());
  }
  j.grids = {JobGrid{gridSpecOf(grid)}};
  j.options = options;
  j.receiverHash = receiverHash(receivers);
  j.tilesTotal = plan.count();
  // Tiles no triangle can touch, or no declared receiver reads, are all lit: done now,
  // merged without a worker. The plan classified every tile (BakePlan::tileClasses, the
  // local bake's test, without building a renderer).
  BakePlan bakePlan;
  std::vector<uint32_t> work;  // per tile, the triangles that reach it: what the ETA weighs
  {
    std::optional<Scene> opaque;
    const RasterScene projected(sunCasters(scene, opaque), grid);
    const ReceiverSet reads(scene, grid, receivers);
    bakePlan = planBake(scene, stats, options, receivers, projected, reads, media);
    j.plan = planJson(bakePlan);
    work = tileWork(projected, plan, [&](uint64_t i) { return bakePlan.tileClasses.at(i) == BakePlan::kRendered; });
  }
  CPVS_CHECK(bakePlan.tileClasses.size() == j.tilesTotal);
  std::vector<TileState> states(j.tilesTotal, TileState::Queued);
  for (uint64_t i = 0; i < j.tilesTotal; ++i) {
    if (bakePlan.tileClasses[i] == BakePlan::kUntouched) states[i] = TileState::Untouched;
    if (bakePlan.tileClasses[i] == BakePlan::kUnread) states[i] = TileState::Unread;
  }
  if (auto existing = createJob(request, access, scene, j, states, work)) return *existing;
  spdlog::info("job {} submitted: scene {}, {}^3, {} tiles ({} touched by no triangle, {} read by no receiver)", j.id,
               j.sceneHash, grid.resolution(), j.tilesTotal, bakePlan.tilesUntouched, bakePlan.tilesUnread);
  feed_.notify();
  return status(j.id);
}

std::optional<pb::JobStatus> JobService::createJob(const pb::SubmitBakeRequest& request, const Access& access,
                                                   const Scene& scene, JobRecord& j,
                                                   const std::vector<TileState>& states,
                                                   const std::vector<uint32_t>& work) {
  const pb::BakeSpec& spec = request.spec();
  j.id = randomId("j");
  j.requestId = request.request_id();
  j.owner = access.owner;
  j.sceneHash = spec.scene_hash();
  j.geometryHash = sceneHash(scene).hex();
  storeSpec(j, spec);
  j.priority = spec.priority();
  j.createdMs = nowMs();
  // Checked again and created under one lock: a retry that arrives while its first call
  // is still loading the scene gets the same job (not a unique-key error), and calls
  // submitted at once cannot together exceed the job limit. The tile folder exists
  // before a worker can lease a tile of the job.
  std::lock_guard lock(submitMutex_);
  if (auto existing = knownRequest(request, access)) return existing;
  checkRoom(access);
  artifacts_.createTileFolder(j.id);
  store_.createJob(j, states, work);
  if (std::none_of(states.begin(), states.end(), [](TileState s) { return s == TileState::Queued; }))
    store_.setJobState(j.id, JobState::Merging, "", nowMs());
  for (uint64_t t = 0; t < j.tilesTotal; ++t)
    if (states[t] != TileState::Queued) merges_.mergeTile(j.id, t);
  return std::nullopt;
}

void JobService::checkTileCount(uint64_t tiles, const std::string& what) const {
  if (tiles > limits_.maxTilesPerJob)
    throw FarmError(ErrorKind::InvalidArgument, what + " makes " + std::to_string(tiles) +
                                                    " tiles; this farm takes at most " +
                                                    std::to_string(limits_.maxTilesPerJob) + " per job");
}

pb::JobStatus JobService::submitBundle(const pb::SubmitBakeRequest& request, const Access& access) {
  const pb::BakeSpec& spec = request.spec();
  if (spec.sun_case() != pb::BakeSpec::SUN_NOT_SET)
    throw FarmError(ErrorKind::InvalidArgument, "lights and scene_lights make a light bundle: give no sun with them");
  if (!spec.resolution().empty())
    throw FarmError(ErrorKind::InvalidArgument,
                    "resolution is the sun's: a light's grids take the light's own resolution, or one planned from "
                    "footprint");
  if (spec.options().depth_slices() != 0)
    throw FarmError(ErrorKind::InvalidArgument, "options.depth_slices is the sun's: a light's grids are cubic");
  if (!std::isfinite(spec.footprint()) || spec.footprint() < 0)
    throw FarmError(ErrorKind::InvalidArgument, "footprint must be finite and >= 0 (0: the scene's diagonal / 4096)");
  if (spec.has_pointer_grid() && spec.pointer_grid() > uint32_t(kMaxGridLevels))
    throw FarmError(ErrorKind::InvalidArgument,
                    "pointer_grid " + std::to_string(spec.pointer_grid()) + ": levels 0 to " + std::to_string(kMaxGridLevels));
  JobRecord j;
  std::vector<Light> lights;
  std::vector<AreaLight> areas;
  try {
    j.options = net::fromProto(spec.options());
    lights = net::lightsOf(spec);
    areas = net::areaLightsOf(spec);
    net::checkReceivers(spec.options().receivers());
  } catch (const InputError& e) {
    throw FarmError(ErrorKind::InvalidArgument, e.what());
  }
  checkRoom(access);  // before loading the scene, which may take long
  const Scene scene = scenes_.load(spec.scene_hash());
  LightBundle planned;
  std::vector<double> closest;
  try {
    const ReceiverDeclaration receivers =
        net::declarationOf(net::modelOf(spec.options().receivers()), [&](const std::string& hash) { return scenes_.load(hash); });
    j.receiverHash = receiverHash(receivers);
    // Area lights become their VPLs after the spec's lights, as `cpvs bake` orders them.
    Vec3 lo, hi;
    sceneBounds(scene, lo, hi);
    for (size_t k = 0; k < areas.size(); ++k) checkAreaLight(areas[k], lo, hi, "area_lights[" + std::to_string(k) + "]");
    if (lights.size() + uint64_t(areas.size()) * kMaxVpls > kMaxLights) {
      size_t count = lights.size();
      for (const AreaLight& a : areas) count += a.vpls;
      checkLightCount(count);
    }
    for (Light& l : vplsOf(areas)) lights.push_back(std::move(l));
    if (spec.scene_lights()) lights = withSceneLights(scene, std::move(lights), "scene_lights: the scene");
    checkLightCount(lights.size());
    const double footprint = spec.footprint() > 0 ? spec.footprint() : defaultFootprint(scene);
    planned = planLights(scene, lights, footprint, j.options, closest, receivers);
  } catch (const InputError& e) {
    throw FarmError(ErrorKind::InvalidArgument, e.what());
  }
  for (size_t k = 0; k < planned.grids.size(); ++k) {
    const int log2R = planned.grids[k].grid.log2Resolution();
    if (log2R < limits_.minLog2Resolution || log2R > limits_.maxLog2Resolution)
      throw FarmError(ErrorKind::InvalidArgument,
                      lightLabel(lights[planned.grids[k].light], planned.grids[k].light) + ": a grid of " +
                          std::to_string(uint64_t(1) << log2R) + " is outside this farm's limits (" +
                          std::to_string(1ull << limits_.minLog2Resolution) + " .. " +
                          std::to_string(1ull << limits_.maxLog2Resolution) + ")");
    j.grids.push_back(jobGridOf(planned.grids[k], closest[k]));
  }
  const GridTiles tiles = tilesOf(j);
  checkTileCount(tiles.count(), std::to_string(lights.size()) + " lights in " + std::to_string(j.grids.size()) +
                                    " grids, tiles of " +
                                    std::to_string(uint64_t(1) << j.options.log2TileSize) + " texels,");
  v1::LightList list;
  for (const Light& l : lights) *list.add_lights() = net::toProto(l);
  j.lights = storedJson(list);
  j.plan = lightPlanJson(planned, closest);
  j.tilesTotal = tiles.count();
  // Tiles whose texels all lie outside their light's cone are all lit (no light falls
  // there): done now, merged without a worker, as bakeTile would bake them.
  std::vector<TileState> states(j.tilesTotal, TileState::Queued);
  uint64_t dark = 0;
  for (size_t k = 0; k < planned.grids.size(); ++k) {
    const TilePlan& plan = tiles.plan(k);
    const uint64_t side = uint64_t(1) << plan.log2TileSize();
    for (uint64_t t = 0; t < plan.count(); ++t) {
      const TileCoord at = plan.tile(t);
      if (!planned.grids[k].grid.coneMissesTexels(at.x * side, at.y * side, side, side, planned.grids[k].tanCone)) continue;
      states[tiles.first(k) + t] = TileState::Untouched;
      ++dark;
    }
  }
  if (auto existing = createJob(request, access, scene, j, states)) return *existing;
  spdlog::info("job {} submitted: scene {}, a light bundle of {} lights in {} grids, {} tiles ({} outside every cone)",
               j.id, j.sceneHash, lights.size(), j.grids.size(), j.tilesTotal, dark);
  feed_.notify();
  return status(j.id);
}

JobRecord JobService::visibleJob(const std::string& jobId, const Access& access) {
  auto j = store_.job(jobId);
  if (!j) throw FarmError(ErrorKind::NotFound, "no job " + jobId);
  if (!access.sees(j->owner)) throw FarmError(ErrorKind::PermissionDenied, "job " + jobId + " is another client's");
  return std::move(*j);
}

pb::JobStatus JobService::status(const std::string& jobId, const Access& access) {
  return toStatus(visibleJob(jobId, access));
}

JobService::Page JobService::list(bool includeFinished, uint32_t pageSize, const std::string& pageToken,
                                  const Access& access) {
  const size_t limit = pageSize == 0 ? 100 : std::min<size_t>(pageSize, 1000);
  // The token is the position of the last job shown: its creation time and id, which
  // stay valid while jobs come and go (a job pruned meanwhile is simply not there).
  int64_t afterMs = std::numeric_limits<int64_t>::min();
  std::string afterId;
  if (!pageToken.empty()) {
    const size_t colon = pageToken.find(':');
    afterId = colon == std::string::npos ? "" : pageToken.substr(colon + 1);
    const char* msEnd = pageToken.data() + (colon == std::string::npos ? 0 : colon);
    const auto [end, error] = std::from_chars(pageToken.data(), msEnd, afterMs);
    const bool valid = pageToken.size() <= 128 && colon != std::string::npos && colon > 0 && end == msEnd &&
                       error == std::errc() && !afterId.empty() && std::all_of(afterId.begin(), afterId.end(), [](char c) {
                         return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_';
                       });
    if (!valid) throw FarmError(ErrorKind::InvalidArgument, "page_token is not one this coordinator gave");
  }
  Page page;
  size_t bytes = 0;
  const std::vector<JobRecord> records =
      store_.jobsAfter(includeFinished, afterMs, afterId, limit + 1,
                       access.everything ? std::nullopt : std::optional<std::string>(access.owner));
  for (size_t i = 0; i < records.size(); ++i) {
    pb::JobStatus status = toStatus(records[i]);
    const size_t size = status.ByteSizeLong() + 8;  // with its field tag and length
    if (i == limit || (!page.jobs.empty() && bytes + size > kListReplyBytes)) {
      const JobRecord& last = records[i - 1];
      page.nextPageToken = std::to_string(last.createdMs) + ":" + last.id;
      break;
    }
    bytes += size;
    page.jobs.push_back(std::move(status));
  }
  return page;
}

pb::JobStatus JobService::cancel(const std::string& jobId, const Access& access) {
  visibleJob(jobId, access);
  if (endJob(jobId, JobState::Cancelled, "cancelled")) spdlog::info("job {} cancelled", jobId);
  return status(jobId);
}

std::string JobService::artifactPath(const std::string& jobId, std::string* checksum, const Access& access) {
  const JobRecord j = visibleJob(jobId, access);
  if (j.state != JobState::Done)
    throw FarmError(ErrorKind::FailedPrecondition,
                    "job " + jobId + " is " + net::jobStateName(net::JobState(int(j.state))) + ", not done");
  if (checksum) *checksum = j.artifactChecksum;
  return artifacts_.artifactPath(jobId, isDagMhJob(j));
}

void JobService::failJob(const std::string& jobId, const std::string& error) {
  if (endJob(jobId, JobState::Failed, error)) spdlog::warn("job {} failed: {}", jobId, loggable(error, 1200));
}

bool JobService::endJob(const std::string& jobId, JobState state, const std::string& why) {
  {
    // Under the result lock, so that no result of the job is written after its tiles are
    // cancelled: completeTile takes only tiles still waiting for one.
    std::lock_guard resultLock(resultMutex_);
    auto j = store_.job(jobId);
    if (!j || isFinal(j->state)) return false;  // the first end stands (cancel vs a late failure)
    store_.setJobState(jobId, state, artifacts_.withoutDataFolder(why), nowMs());
    store_.cancelTiles(jobId);
  }
  // Its tile results are removed by the merge thread, after any merge of them queued
  // before: the merge never finds a file gone under it.
  merges_.removeTiles(jobId);
  feed_.notify();
  return true;
}

}  // namespace cpvs::server
