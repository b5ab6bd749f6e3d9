// The farm inside one test process: the coordinator served on port 0 (FarmServer), a
// worker on a thread, the client library; and the store and the token table on their
// own. The multi-process farm tests (farm_test, farm_security_test) run the same pieces
// as separate programs.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <algorithm>
#include <tuple>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <thread>

#include "error_testing.h"
#include "scene_testing.h"
#include "cpvs/scene/boxes.h"
#include "coordinator/coordinator.h"
#include "cpvs/bake/bake.h"
#include "cpvs/bake/bake_dag_mh.h"
#include "cpvs/bake/bake_lights.h"
#include "cpvs/io/dmh_file.h"
#include "cpvs/io/dmh_tile_file.h"
#include "cpvs/io/sub_dag_file.h"
#include "cpvs/base/hash.h"
#include "cpvs/net/channel.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/query/bundle_query.h"
#include "cpvs/light/perspective_grid.h"
#include "cpvs/base/error.h"
#include "cpvs/base/file.h"
#include "cpvs/client/farm_client.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/net/convert.h"
#include "cpvs/net/model_convert.h"
#include "cpvs/scene/import.h"
#include "cpvs/scene/obj_writer.h"
#include "cpvs/scene/source.h"
#include "rpc/farm_server.h"
#include "store/farm_store.h"
#include "cpvs/runtime/runtime.h"
#include "coordinator/stored_spec.h"
#include "farm_testing.h"
#include "tile_worker.h"

namespace cpvs {
namespace {

using testing::bakeTileWith;
using testing::bakeWith;

namespace fs = std::filesystem;
namespace pb = ::cpvs::v1;

using testing::InProcessFarm;
using testing::TempDir;

// What `cpvs bake FILE` writes for the sun jobs these tests submit: (0.3, -1, 0.2), 256³,
// 64² tiles. A farm's artifact of the same job is these bytes.
CpvsArtifact localBakeOf(const std::string& file) {
  const Scene scene = loadScene(file);
  BakeOptions options;
  options.log2TileSize = 6;
  return testing::localArtifact(scene, makeGrid(scene, LightFrame::fromDirection({0.3, -1, 0.2}), 8), options);
}

TEST(InProcessFarm, ClientCoordinatorAndWorkerInOneProcessGiveTheLocalBytes) {
  TempDir dir("cpvs_in_process_farm");
  const std::string obj = dir / "city.obj";
  writeObj(obj, openScene("city:2:3"));

  InProcessFarm farm(dir / "data");
  ASSERT_GT(farm.server.port(), 0);

  worker::WorkerConfig wc = testing::workerConfig(farm.connection(), dir / "cache");
  wc.workerId = "in-process";
  wc.threads = 2;
  worker::TileWorker tileWorker(wc);
  std::thread workerThread([&] { tileWorker.run(); });

  client::FarmClient& farmClient = farm.client;
  const client::FarmClient::UploadResult up = farmClient.uploadScene(obj);
  EXPECT_FALSE(up.alreadyThere);
  EXPECT_GT(up.triangles, 0u);
  EXPECT_TRUE(farmClient.uploadScene(obj).alreadyThere);  // content-addressed: sent once

  net::BakeSpec spec;
  spec.sceneHash = up.sceneHash;
  spec.sun = Vec3{0.3, -1, 0.2};
  spec.resolution = "256";
  spec.options.tileSize = 64;
  const client::JobStatus submitted = farmClient.submit("in-process-1", spec);
  const client::JobStatus done = farmClient.watch(submitted.jobId);
  EXPECT_EQ(done.state, client::JobState::Done) << done.error;
  EXPECT_EQ(done.tilesTotal, 16u);
  EXPECT_EQ(done.etaSeconds, 0);
  farmClient.download(submitted.jobId, dir / "farm.cpvs");
  {
    // A grid with fewer depth slices is made by the coordinator as `cpvs bake` makes it.
    net::BakeSpec shallow = spec;
    shallow.options.depthSlices = 64;
    const client::JobStatus s = farmClient.watch(farmClient.submit("in-process-shallow", shallow).jobId);
    EXPECT_EQ(s.state, client::JobState::Done) << s.error;
    farmClient.download(s.jobId, dir / "shallow.cpvs");
    const Scene scene = loadScene(obj);
    BakeOptions options;
    options.log2TileSize = 6;
    const CpvsArtifact local =
        testing::localArtifact(scene, makeGrid(scene, LightFrame::fromDirection({0.3, -1, 0.2}), 8, 64), options);
    EXPECT_EQ(readFile(dir / "shallow.cpvs"), encodeCpvs(local, true));
    EXPECT_NE(readFile(dir / "shallow.cpvs"), readFile(dir / "farm.cpvs"));
    shallow.options.depthSlices = 257;
    try {
      (void)farmClient.submit("in-process-too-deep", shallow);
      ADD_FAILURE() << "257 depth slices at 256 were taken";
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find("depth_slices"), std::string::npos) << e.what();
    }
  }
  {
    // What the ETA is fitted to: each rendered tile's triangles, kept at submit, and the
    // seconds its worker reported, kept at its acknowledgement.
    server::FarmStore store(dir / "data/farm.sqlite");
    const server::TileCosts costs = store.tileCosts(submitted.jobId);
    EXPECT_EQ(costs.done.n, double(16 - done.tilesUntouched - done.tilesUnread));
    EXPECT_GE(costs.done.w, costs.done.n);
    EXPECT_GT(costs.done.t, 0);
    EXPECT_EQ(costs.leftTiles, 0u);
    EXPECT_EQ(costs.leftWork, 0);
    EXPECT_TRUE(TileCostLaw::fit(costs.done).has_value());
  }

  // The runtime fetches it into its cache under its content hash, then answers from the
  // cache; an unknown job is the farm's refusal.
  const runtime::FarmAddress address{farm.server.address(), "", ""};
  bool fromCache = true;
  const std::string cached = runtime::fetchArtifact(address, submitted.jobId, dir / "runtime-cache", &fromCache);
  EXPECT_FALSE(fromCache);
  const std::vector<uint8_t> farmBytes = readFile(dir / "farm.cpvs");
  EXPECT_EQ(readFile(cached), farmBytes);
  EXPECT_EQ(cached, (dir / "runtime-cache") + "/" + contentHash(farmBytes.data(), farmBytes.size()).hex() + ".cpvs");
  EXPECT_EQ(runtime::fetchArtifact(address, submitted.jobId, dir / "runtime-cache", &fromCache), cached);
  EXPECT_TRUE(fromCache);
  // A download that stopped half way resumes; one whose kept part is not the artifact's
  // fails its checksum, is dropped, and the next fetch gets the artifact.
  std::filesystem::create_directories(dir / "half/incoming");
  const std::string part = (dir / "half/incoming/") + [&] {
    std::string hex;
    for (unsigned char c : submitted.jobId) hex += {"0123456789abcdef"[c >> 4], "0123456789abcdef"[c & 15]};
    return hex;
  }() + ".cpvs.part";
  writeFileAtomic(part, std::vector<uint8_t>(farmBytes.begin(), farmBytes.begin() + farmBytes.size() / 2));
  EXPECT_EQ(readFile(runtime::fetchArtifact(address, submitted.jobId, dir / "half", &fromCache)), farmBytes);
  EXPECT_FALSE(fromCache);
  std::filesystem::create_directories(dir / "garbled/incoming");
  writeFileAtomic((dir / "garbled/incoming/") + part.substr(part.rfind('/') + 1), std::vector<uint8_t>(100, 7));
  try {
    runtime::fetchArtifact(address, submitted.jobId, dir / "garbled");
    ADD_FAILURE() << "a garbled part was accepted";
  } catch (const runtime::RuntimeError& e) {
    EXPECT_EQ(e.status(), runtime::Status::CorruptArtifact) << e.what();
  }
  EXPECT_EQ(readFile(runtime::fetchArtifact(address, submitted.jobId, dir / "garbled")), farmBytes);
  try {
    runtime::fetchArtifact(address, "no-such-job", dir / "runtime-cache");
    ADD_FAILURE() << "fetched an unknown job";
  } catch (const runtime::RuntimeError& e) {
    EXPECT_EQ(e.status(), runtime::Status::FarmError);
    EXPECT_NE(std::string(e.what()).find("no-such-job"), std::string::npos) << e.what();
  }

  tileWorker.stop();
  workerThread.join();
  farm.server.shutdown(1);

  // With the farm gone the cache still answers; a damaged cached file is not trusted.
  EXPECT_EQ(runtime::fetchArtifact(address, submitted.jobId, dir / "runtime-cache", &fromCache), cached);
  EXPECT_TRUE(fromCache);
  std::vector<uint8_t> damaged = farmBytes;
  damaged[damaged.size() / 2] ^= 1;
  writeFileAtomic(cached, damaged);
  try {
    runtime::fetchArtifact(address, submitted.jobId, dir / "runtime-cache", &fromCache);
    ADD_FAILURE() << "a damaged cached artifact was returned";
  } catch (const runtime::RuntimeError& e) {
    EXPECT_EQ(e.status(), runtime::Status::FarmError) << e.what();  // it went to the farm, which is down
  }

  // The same bake in this process, from the same file.
  EXPECT_EQ(readFile(dir / "farm.cpvs"), encodeCpvs(localBakeOf(obj), true));

  // A refused call reaches the client as its kind, through the library.
  try {
    farmClient.cancel("no-such-job");
    ADD_FAILURE() << "cancel of an unknown job succeeded";
  } catch (const client::FarmCallError& e) {
    EXPECT_EQ(e.kind(), net::ErrorKind::Unavailable);  // the server is shut down by now
  }
}

// A scene with glass: the workers bake its opaque part, the coordinator builds the glass's
// TOP tree once the DAG is merged, and the artifact is the local bake's to the byte.
// A scene with glass: the workers bake its opaque part, the coordinator builds the glass's
// TOP tree once the DAG is merged, and the artifact is the local bake's to the byte: also
// where a tile holds glass alone (planned as the bake casts: touched by nothing).
TEST(InProcessFarm, TranslucentCastersTravelInTheArtifactAsBakedLocally) {
  TempDir dir("cpvs_in_process_glass");
  Scene boxAndPane;
  appendBox(boxAndPane, {0, 0, 0}, {1, 1, 1});
  testing::appendQuad(boxAndPane, {8, 2, 8}, {8, 2, 10}, {10, 2, 10}, {10, 2, 8});
  boxAndPane.meshes = {{"box", "box", "stone", 0, 12, {0, 0, 0}}, {"pane", "pane", "glass", 12, 2, {0.5f, 0.75f, 1.0f}}};
  finalizeScene(boxAndPane);
  InProcessFarm farm(dir / "data");
  worker::WorkerConfig wc = testing::workerConfig(farm.connection(), dir / "cache");
  worker::TileWorker tileWorker(wc);
  std::thread workerThread([&] { tileWorker.run(); });
  for (const auto& [name, scene] : {std::pair{std::string("city"), testing::glassCity()}, std::pair{std::string("apart"), boxAndPane}}) {
    SCOPED_TRACE(name);
    const std::string glb = dir / (name + ".glb");
    testing::writeGlb(scene, glb);
    const client::FarmClient::UploadResult up = farm.client.uploadScene(glb);
    net::BakeSpec spec;
    spec.sceneHash = up.sceneHash;
    spec.sun = Vec3{0.3, -1, 0.2};
    spec.resolution = "256";
    spec.options.tileSize = 64;
    const client::JobStatus done = farm.client.watch(farm.client.submit("glass-" + name, spec).jobId);
    ASSERT_EQ(done.state, client::JobState::Done) << done.error;
    farm.client.download(done.jobId, dir / "farm.cpvs");
    const CpvsArtifact farmed = readCpvs(dir / "farm.cpvs");
    ASSERT_TRUE(farmed.translucent) << "the glass's tree travels with the CPVS";
    EXPECT_EQ(farmed.translucent->frustumCount(), translucentCasters(scene).triangleCount());

    const CpvsArtifact local = localBakeOf(glb);
    EXPECT_EQ(readFile(dir / "farm.cpvs"), encodeCpvs(local, true));
    if (name == "apart") {
      // The pane's tiles are touched by no opaque triangle: untouched in the plan, as the
      // bake of the opaque part finds them.
      EXPECT_GT(done.tilesUntouched, 0u);
      auto tiles = [](const std::string& plan) {
        const size_t at = plan.find("\"tiles\": {");
        return plan.substr(at, plan.find('}', at) - at);
      };
      EXPECT_EQ(tiles(local.plan), tiles(testing::localArtifact(opaquePart(loadScene(glb)), local.grid, local.options).plan));
    }
  }
  tileWorker.stop();
  workerThread.join();
}

// Tiles no triangle touches are never leased: the coordinator merges them as all lit, and
// the job still gives the local bytes, with either renderer.
TEST(InProcessFarm, UntouchedTilesAreNotLeasedAndBothRenderersGiveTheLocalBytes) {
  TempDir dir("cpvs_in_process_untouched");
  Scene boxes;
  appendBox(boxes, {0, 0, 0}, {1, 1, 1});
  appendBox(boxes, {9, 0, 9}, {10, 3, 10});
  finalizeScene(boxes);
  const std::string obj = dir / "boxes.obj";
  writeObj(obj, boxes);

  InProcessFarm farm(dir / "data");
  worker::WorkerConfig wc = testing::workerConfig(farm.connection(), dir / "cache");
  wc.workerId = "in-process";
  worker::TileWorker tileWorker(wc);
  std::thread workerThread([&] { tileWorker.run(); });
  const client::FarmClient::UploadResult up = farm.client.uploadScene(obj);
  const Scene scene = loadScene(obj);
  // Both renderers for receivers everywhere; the rasterizer for surfaces receivers, and for
  // cameras that see only the first box (the second one's tiles are touched, never read).
  for (const ReceiverKind kind : {ReceiverKind::Everywhere, ReceiverKind::Surfaces, ReceiverKind::Cameras})
    for (Renderer renderer : {Renderer::Raster, Renderer::Embree}) {
      if (kind != ReceiverKind::Everywhere && renderer == Renderer::Embree) continue;
      SCOPED_TRACE(std::string(optionName(renderer)) + ", receivers " + optionName(kind));
      net::BakeSpec spec;
      spec.sceneHash = up.sceneHash;
      spec.sun = Vec3{0.2, -1, 0.1};
      spec.resolution = "256";
      spec.options.tileSize = 32;
      spec.options.renderer = renderer;
      ReceiverDeclaration d;
      d.kind = kind;
      d.maxPcf = 9;
      if (kind != ReceiverKind::Everywhere) {
        spec.options.receivers.emplace();
        spec.options.receivers->kind = kind;
        spec.options.receivers->maxPcf = 9;
      }
      if (kind == ReceiverKind::Cameras) {
        net::Receivers& r = *spec.options.receivers;
        r.cameraRegions.push_back({Vec3{-1, 0.5, -1}, Vec3{2, 1.5, 2}});
        r.viewDistance = 3;
        d.cameraRegions = {{Vec3{-1, 0.5, -1}, Vec3{2, 1.5, 2}}};
        d.viewDistance = 3;
      }
      const uint64_t leasedBefore = tileWorker.tilesLeased();
      const client::JobStatus done = farm.client.watch(
          farm.client.submit(std::string("untouched-") + optionName(renderer) + "-" + optionName(kind), spec).jobId);
      ASSERT_EQ(done.state, client::JobState::Done) << done.error;
      EXPECT_EQ(done.tilesTotal, 64u);
      EXPECT_EQ(done.tilesDone, 64u);
      EXPECT_GT(done.tilesUntouched, 20u) << "the space between the boxes is empty";
      EXPECT_LT(done.tilesUntouched + done.tilesUnread, 64u);
      if (kind == ReceiverKind::Cameras) {
        EXPECT_GT(done.tilesUnread, 0u) << "the cameras never see the second box";
      }
      // The worker baked exactly the others: the status says how many were never leased.
      EXPECT_EQ(tileWorker.tilesLeased() - leasedBefore, 64u - done.tilesUntouched - done.tilesUnread);
      farm.client.download(done.jobId, dir / "farm.cpvs");

      BakeOptions options;
      options.log2TileSize = 5;
      options.renderer = renderer;
      const CpvsArtifact local =
          testing::localArtifact(scene, makeGrid(scene, LightFrame::fromDirection({0.2, -1, 0.1}), 8), options, d);
      EXPECT_EQ(readFile(dir / "farm.cpvs"), encodeCpvs(local, true));
    }
  tileWorker.stop();
  workerThread.join();
  farm.server.shutdown(1);
}

// Receivers travel with a job: surfaces, and a volume of an uploaded closed mesh plus a
// box, bake on the farm to the bytes of the local bake, the declaration's hash included.
TEST(InProcessFarm, ReceiversGiveTheLocalBytes) {
  TempDir dir("cpvs_in_process_receivers");
  Scene scene;
  for (const Vec3& p : {Vec3{-10, 0, -10}, Vec3{-10, 0, 10}, Vec3{10, 0, 10}, Vec3{10, 0, -10}}) scene.positions.push_back(p);
  for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) scene.indices.push_back(i);  // an open ground sheet, facing up
  appendBox(scene, {-3, 0, -3}, {2, 5, 1});
  finalizeScene(scene);
  const std::string obj = dir / "level.obj";
  writeObj(obj, scene);
  Scene mesh;
  appendBox(mesh, {-9, 0, -9}, {9, 2, 9});
  finalizeScene(mesh);
  const std::string meshObj = dir / "volume.obj";
  writeObj(meshObj, mesh);

  InProcessFarm farm(dir / "data");
  worker::WorkerConfig wc = testing::workerConfig(farm.connection(), dir / "cache");
  wc.workerId = "in-process";
  worker::TileWorker tileWorker(wc);
  std::thread workerThread([&] { tileWorker.run(); });
  const std::string sceneHash = farm.client.uploadScene(obj).sceneHash;
  const std::string volumeHash = farm.client.uploadScene(meshObj).sceneHash;
  const Scene loaded = loadScene(obj);
  for (ReceiverKind kind : {ReceiverKind::Surfaces, ReceiverKind::Volume, ReceiverKind::Cameras}) {
    net::BakeSpec spec;
    spec.sceneHash = sceneHash;
    spec.sun = Vec3{0.3, -1, 0.2};
    spec.resolution = "256";
    spec.options.tileSize = 64;
    net::Receivers& r = spec.options.receivers.emplace();
    r.kind = kind;
    r.maxPcf = 5;
    ReceiverDeclaration d;
    d.kind = kind;
    d.maxPcf = 5;
    if (kind == ReceiverKind::Volume) {
      r.volumeSceneHash = volumeHash;
      r.boxes.push_back({Vec3{-4, 5, -4}, Vec3{3, 7, 2}});
      d.volume = loadScene(meshObj);
      appendBox(d.volume, {-4, 5, -4}, {3, 7, 2});
      finalizeScene(d.volume);
      // And a ground layer, from 0.5 to 2 units over surfaces within 30 degrees of level.
      r.groundLayer = 2;
      r.groundLayerFrom = 0.5;
      r.groundSlopeDeg = 30;
      d.groundLayer = 2;
      d.groundLayerFrom = 0.5;
      d.groundSlopeDeg = 30;
    }
    if (kind == ReceiverKind::Cameras) {
      r.cameraRegions.push_back({Vec3{3, 1, 3}, Vec3{8, 2, 8}});
      r.viewDistance = 6;
      d.cameraRegions = {{Vec3{3, 1, 3}, Vec3{8, 2, 8}}};
      d.viewDistance = 6;
      // Sampled from the region, a point and a path: every worker casts the same rays.
      r.cameraPoints = {Vec3{-2, 1.5, 0}};
      r.cameraPaths = {{Vec3{-5, 1, -5}, Vec3{5, 1, -5}}};
      r.cameraVisibility = CameraVisibility::Sampled;
      r.cameraSpacing = 1.5;
      r.cameraRays = 24;
      d.cameraPoints = {Vec3{-2, 1.5, 0}};
      d.cameraPaths = {{Vec3{-5, 1, -5}, Vec3{5, 1, -5}}};
      d.cameraVisibility = CameraVisibility::Sampled;
      d.cameraSpacing = 1.5;
      d.cameraRays = 24;
    }
    const uint64_t leasedBefore = tileWorker.tilesLeased();
    const client::JobStatus done =
        farm.client.watch(farm.client.submit(std::string("receivers-") + optionName(kind), spec).jobId);
    ASSERT_EQ(done.state, client::JobState::Done) << done.error;
    // Tiles no receiver reads are done at submit and never leased.
    EXPECT_EQ(tileWorker.tilesLeased() - leasedBefore, done.tilesTotal - done.tilesUntouched - done.tilesUnread);
    farm.client.download(done.jobId, dir / "farm.cpvs");

    BakeOptions options;
    options.log2TileSize = 6;
    const CpvsArtifact local =
        testing::localArtifact(loaded, makeGrid(loaded, LightFrame::fromDirection({0.3, -1, 0.2}), 8), options, d);
    EXPECT_EQ(readFile(dir / "farm.cpvs"), encodeCpvs(local, true)) << optionName(kind);
  }
  // A volume that is not closed, or names no uploaded mesh, is refused at submit.
  net::BakeSpec bad;
  bad.sceneHash = sceneHash;
  bad.sun = Vec3{0.3, -1, 0.2};
  bad.resolution = "256";
  bad.options.receivers.emplace().kind = ReceiverKind::Volume;
  bad.options.receivers->volumeSceneHash = sceneHash;  // the open level
  auto refusal = [&](const std::string& id) {
    try {
      farm.client.submit(id, bad);
    } catch (const client::FarmCallError& e) {
      return std::make_pair(e.kind(), std::string(e.what()));
    }
    return std::make_pair(net::ErrorKind::Internal, std::string("accepted"));
  };
  auto [kind, message] = refusal("bad-volume");
  EXPECT_EQ(kind, net::ErrorKind::InvalidArgument) << message;
  EXPECT_NE(message.find("must be closed"), std::string::npos) << message;
  bad.options.receivers->volumeSceneHash = std::string(32, 'a');
  std::tie(kind, message) = refusal("missing-volume");
  EXPECT_EQ(kind, net::ErrorKind::NotFound) << message;
  tileWorker.stop();
  workerThread.join();
  farm.server.shutdown(1);
}

// A DAG-MH job (format dagmh): each farm tile baked by a worker into the parts of a
// DAG-MH, merged at the coordinator as they come, tiles no receiver reads made there;
// the artifact is the .dmh `cpvs bake --format dagmh` writes, to the byte, and the
// runtime opens it.
TEST(InProcessFarm, ADagMhJobGivesTheLocalBytes) {
  TempDir dir("cpvs_in_process_dagmh");
  const std::string obj = dir / "city.obj", boxesObj = dir / "boxes.obj";
  writeObj(obj, openScene("city:2:3"));
  Scene boxes;  // two boxes far apart: most tiles see no triangle and hold no receiver
  appendBox(boxes, {-40, 0, -40}, {-36, 6, -36});
  appendBox(boxes, {36, 0, 36}, {40, 3, 40});
  finalizeScene(boxes);
  writeObj(boxesObj, boxes);
  InProcessFarm farm(dir / "data");
  worker::WorkerConfig wc = testing::workerConfig(farm.connection(), dir / "cache");
  wc.workerId = "in-process";
  worker::TileWorker tileWorker(wc);
  std::thread workerThread([&] { tileWorker.run(); });
  const std::string uploaded = farm.client.uploadScene(obj).sceneHash;
  for (const auto& [file, kind] : std::vector<std::pair<std::string, ReceiverKind>>{
           {obj, ReceiverKind::Surfaces}, {obj, ReceiverKind::Everywhere}, {boxesObj, ReceiverKind::Surfaces}}) {
    const Scene loaded = loadScene(file);
    net::BakeSpec spec;
    spec.sceneHash = farm.client.uploadScene(file).sceneHash;
    spec.sun = Vec3{0.3, -1, 0.2};
    spec.resolution = "2048";
    spec.options.tileSize = 1024;  // four farm tiles of four parts each
    spec.format = net::ArtifactFormat::DagMh;
    ReceiverDeclaration d;
    d.kind = kind;
    if (kind != ReceiverKind::Everywhere) {
      net::Receivers& r = spec.options.receivers.emplace();
      r.kind = kind;
      r.maxPcf = 3;
      d.maxPcf = 3;
    }
    const uint64_t leasedBefore = tileWorker.tilesLeased();
    const client::JobStatus done =
        farm.client.watch(farm.client.submit("dagmh-" + fs::path(file).stem().string() + "-" + optionName(kind), spec).jobId);
    ASSERT_EQ(done.state, client::JobState::Done) << done.error;
    EXPECT_EQ(done.spec.format, net::ArtifactFormat::DagMh);
    EXPECT_EQ(done.tilesTotal, 4u);
    EXPECT_EQ(tileWorker.tilesLeased() - leasedBefore, done.tilesTotal - done.tilesUntouched - done.tilesUnread);
    EXPECT_GT(done.peakMergeBytes, 0u);
    if (file == boxesObj) {
      EXPECT_GT(done.tilesUntouched + done.tilesUnread, 0u) << "made by the coordinator, all lit";
    }
    farm.client.download(done.jobId, dir / "farm.dmh");

    DmhArtifact local;
    local.grid = makeGrid(loaded, LightFrame::fromDirection({0.3, -1, 0.2}), 11);
    local.options.log2TileSize = 10;
    local.options.receivers = kind;
    if (kind != ReceiverKind::Everywhere) local.options.receiverPcf = 3;
    local.sceneHash = sceneHash(loaded);
    local.receiverHash = receiverHash(d);
    local.dag = bakeDagMh(loaded, local.grid, local.options, d);
    EXPECT_EQ(readFile(dir / "farm.dmh"), encodeDmh(local, true)) << optionName(kind);
    EXPECT_EQ(done.bytes, local.dag.bytes());
    const auto artifact = runtime::ShadowArtifact::open(dir / "farm.dmh");
    EXPECT_EQ(artifact->kind(), runtime::ArtifactKind::DagMh);
    // A game fetches it into its cache as a .dmh, and finds it there the next time.
    const runtime::FarmAddress address{farm.server.address(), "", ""};
    bool fromCache = true;
    const std::string cached = runtime::fetchArtifact(address, done.jobId, dir / "runtime-cache", &fromCache);
    EXPECT_FALSE(fromCache);
    EXPECT_EQ(fs::path(cached).extension(), ".dmh");
    EXPECT_EQ(readFile(cached), readFile(dir / "farm.dmh"));
    EXPECT_EQ(runtime::fetchArtifact(address, done.jobId, dir / "runtime-cache", &fromCache), cached);
    EXPECT_TRUE(fromCache);
  }
  // What a DAG-MH cannot be is refused at submit, by name.
  const std::vector<std::pair<std::function<void(net::BakeSpec&)>, std::string>> refusals{
      {[](net::BakeSpec& s) { s.options.depthSlices = 64; }, "depth_slices"},
      {[](net::BakeSpec& s) { s.options.renderer = Renderer::Embree; }, "raster"},
      {[](net::BakeSpec& s) { s.media.push_back({"fog", 0.01, 0.01, 0}); }, "media"},
      {[](net::BakeSpec& s) {
         s.sun = std::monostate{};
         s.resolution.clear();
         s.lights.push_back(Light{});
         s.lights.back().kind = LightKind::Point;
         s.lights.back().position = {0, 5, 0};
       },
       "light bundle"}};
  for (const auto& [change, words] : refusals) {
    net::BakeSpec bad;
    bad.sceneHash = uploaded;
    bad.sun = Vec3{0.3, -1, 0.2};
    bad.resolution = "256";
    bad.format = net::ArtifactFormat::DagMh;
    change(bad);
    try {
      farm.client.submit("dagmh-bad-" + words, bad);
      ADD_FAILURE() << words << ": accepted";
    } catch (const client::FarmCallError& e) {
      EXPECT_EQ(e.kind(), net::ErrorKind::InvalidArgument) << e.what();
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  }
  tileWorker.stop();
  workerThread.join();
  farm.server.shutdown(1);
}

// A DAG-MH job's lease says its format, and its tile takes only its own parts: a
// sub-DAG, or the parts of another tile, are refused (and the tile stays to do).
TEST(InProcessFarm, ADagMhTileTakesOnlyItsOwnParts) {
  TempDir dir("cpvs_in_process_dagmh_parts");
  const std::string obj = dir / "city.obj";
  writeObj(obj, openScene("city:2:3"));
  InProcessFarm farm(dir / "data");
  net::BakeSpec spec;
  spec.sceneHash = farm.client.uploadScene(obj).sceneHash;
  spec.sun = Vec3{0.3, -1, 0.2};
  spec.resolution = "256";
  spec.options.tileSize = 128;
  spec.format = net::ArtifactFormat::DagMh;
  const std::string job = farm.client.submit("dagmh-parts", spec).jobId;

  auto workers = pb::Workers::NewStub(net::makeChannel(farm.connection()));
  pb::LeaseRequest request;
  request.set_worker_id("by-hand");
  pb::TileLease lease;
  {
    grpc::ClientContext ctx;
    ASSERT_TRUE(workers->LeaseTile(&ctx, request, &lease).ok());
  }
  ASSERT_TRUE(lease.granted());
  EXPECT_EQ(lease.job_id(), job);
  EXPECT_EQ(lease.format(), pb::ARTIFACT_FORMAT_DAG_MH);
  auto complete = [&](const std::vector<uint8_t>& bytes) {
    grpc::ClientContext ctx;
    pb::CompleteReply reply;
    auto writer = workers->CompleteTile(&ctx, &reply);
    pb::TileResultChunk chunk;
    chunk.set_lease_id(lease.lease_id());
    chunk.set_total_size(bytes.size());
    chunk.set_checksum(contentHash(bytes.data(), bytes.size()).hex());
    chunk.set_data(std::string(bytes.begin(), bytes.end()));
    writer->Write(chunk);
    writer->WritesDone();
    const grpc::Status status = writer->Finish();
    return std::make_pair(status, reply.accepted());
  };
  auto tilesDone = [&] {
    for (const client::JobStatus& s : farm.client.list(true))
      if (s.jobId == job) return s.tilesDone;
    return uint64_t(999);
  };
  const Scene scene = loadScene(obj);
  const OrthoGrid grid = makeGrid(scene, LightFrame::fromDirection({0.3, -1, 0.2}), 8);
  BakeOptions options = net::fromProto(lease.options());
  const BakeScene prepared(scene, grid, Renderer::Raster, 0, {});
  const auto refused = [&](const std::vector<uint8_t>& bytes, const std::string& what) {
    const auto [status, accepted] = complete(bytes);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << what << ": " << status.error_message();
    EXPECT_NE(status.error_message().find("rejected result"), std::string::npos) << status.error_message();
    EXPECT_EQ(tilesDone(), 0u) << what;
  };
  refused(encodeSubDag(bakeTileWith(scene, grid, lease.tile_x(), lease.tile_y(), options)), "a sub-DAG");
  refused(encodeDagMhTiles(bakeDagMhFarmTile(prepared, options, lease.tile_x() ^ 1, lease.tile_y())), "another tile");
  const auto [status, accepted] =
      complete(encodeDagMhTiles(bakeDagMhFarmTile(prepared, options, lease.tile_x(), lease.tile_y())));
  EXPECT_TRUE(status.ok()) << status.error_message();
  EXPECT_TRUE(accepted);
  EXPECT_EQ(tilesDone(), 1u);
  farm.server.shutdown(1);
}

// A worker keeps the tiles it bakes under the content that decides them (tile_key.h):
// the same bake submitted again is sent whole from its tile cache, an edited scene's
// tiles the edit did not reach too, and each artifact is the local bake's; the cache
// survives the worker's restart.
TEST(InProcessFarm, AWorkerSendsTheTilesItBakedBeforeFromItsTileCache) {
  TempDir dir("cpvs_in_process_tile_cache");
  const Scene city = openScene("city:3:4");
  Scene edited = city;
  appendBox(edited, {1, 0, 1}, {3, 2, 3});  // a kiosk on a street corner
  finalizeScene(edited);
  const std::string before = dir / "city.obj", after = dir / "edited.obj";
  writeObj(before, city);
  writeObj(after, edited);
  InProcessFarm farm(dir / "data");
  auto submit = [&](const std::string& file, const std::string& id) {
    net::BakeSpec spec;
    spec.sceneHash = farm.client.uploadScene(file).sceneHash;
    spec.sun = Vec3{0.3, -1, 0.2};
    spec.resolution = "256";
    spec.options.tileSize = 64;
    const client::JobStatus done = farm.client.watch(farm.client.submit(id, spec).jobId);
    EXPECT_EQ(done.state, client::JobState::Done) << done.error;
    farm.client.download(done.jobId, dir / (id + ".cpvs"));
    return done;
  };
  for (int run = 0; run < 2; ++run) {  // the second worker restarts on the first one's cache
    worker::WorkerConfig wc = testing::workerConfig(farm.connection(), dir / "cache");
    wc.threads = 2;
    worker::TileWorker tileWorker(wc);
    std::thread workerThread([&] { tileWorker.run(); });
    const std::string id = "city-" + std::to_string(run);
    const client::JobStatus done = submit(before, id);
    const uint64_t leased = done.tilesTotal - done.tilesUntouched - done.tilesUnread;
    EXPECT_EQ(readFile(dir / (id + ".cpvs")), encodeCpvs(localBakeOf(before), true));
    EXPECT_EQ(tileWorker.tilesReused(), run == 0 ? 0u : leased) << "the second time, every tile was baked before";
    EXPECT_EQ(done.tilesReused, tileWorker.tilesReused()) << "the job's status says so";
    if (run == 1) {
      const client::JobStatus edited = submit(after, "edited");
      EXPECT_EQ(readFile(dir / "edited.cpvs"), encodeCpvs(localBakeOf(after), true));
      EXPECT_GT(edited.tilesReused, 0u);
      EXPECT_LT(edited.tilesReused, edited.tilesTotal - edited.tilesUntouched - edited.tilesUnread)
          << "the kiosk's tiles are baked";
      EXPECT_EQ(edited.tilesReused, tileWorker.tilesReused() - leased);
    }
    tileWorker.stop();
    workerThread.join();
  }
}

TEST(InProcessFarm, UnknownJobsAndRefusalsAreTheirKinds) {
  TempDir dir("cpvs_in_process_refusals");
  InProcessFarm farm(dir / "data");
  client::FarmClient& farmClient = farm.client;
  try {
    farmClient.cancel("no-such-job");
    ADD_FAILURE();
  } catch (const client::FarmCallError& e) {
    EXPECT_EQ(e.kind(), net::ErrorKind::NotFound);
    EXPECT_TRUE(e.callerCanFix());
    EXPECT_NE(std::string(e.what()).find("NOT_FOUND: no job no-such-job"), std::string::npos) << e.what();
  }
  net::BakeSpec spec;
  spec.sceneHash = std::string(32, 'a');
  spec.sun = Vec3{0, -1, 0};
  spec.resolution = "256";
  try {
    farmClient.submit("r", spec);
    ADD_FAILURE();
  } catch (const client::FarmCallError& e) {
    EXPECT_EQ(e.kind(), net::ErrorKind::NotFound) << e.what();  // the scene was never uploaded
  }
}

server::JobRecord sampleJob(const std::string& id, int priority, uint64_t tiles) {
  server::JobRecord j;
  j.id = id;
  j.requestId = "req-" + id;
  j.sceneHash = std::string(32, 'b');
  j.geometryHash = std::string(32, 'c');
  j.spec = "spec bytes";
  j.priority = priority;
  j.createdMs = 1000;
  j.tilesTotal = tiles;
  OrthoGrid g;
  g.frame = LightFrame::fromDirection({0.3, -1, 0.2});
  g.log2Resolution = 10;
  g.origin = {1.5, -2.25, 1e5};
  g.u0 = -3.125;
  g.v0 = 7.5;
  g.d0 = -0.0625;
  g.extent = 12.75;
  g.depthExtent = 3.5;
  j.grids = {server::JobGrid{gridSpecOf(g)}};
  j.options.closed = ClosedMode::Off;
  j.options.exit = ExitMode::Approx;
  j.options.cull = false;
  j.options.compress = CompressMode::BottomUp;
  j.options.undefinedRule = UndefinedRule::Old;
  j.options.log2TileSize = 7;
  return j;
}

// A light bundle asked for wrongly is refused with what is wrong, before any tile exists.
TEST(InProcessFarm, ABadLightBundleIsRefusedWithWhatIsWrong) {
  TempDir dir("cpvs_in_process_bundle_refusals");
  InProcessFarm farm(dir / "data");
  // As the wire carries it: some of these a client's model cannot even hold.
  const pb::BakeSpec sun = net::toProto(farm.uploadAndSpec(dir / "city.obj", "city:1:1", "256"));
  pb::BakeSpec lamp = sun;
  lamp.clear_sun();
  lamp.clear_resolution();
  pb::Light* spot = lamp.add_lights();
  spot->set_kind(pb::LIGHT_SPOT);
  *spot->mutable_position() = net::toProto(Vec3{8, 20, 8});
  *spot->mutable_direction() = net::toProto(Vec3{0, -1, 0});
  spot->set_cone_deg(40);
  spot->set_resolution("256");
  const std::vector<std::pair<std::function<void(pb::BakeSpec&)>, std::string>> cases{
      {[](pb::BakeSpec& s) { *s.mutable_sun_direction() = net::toProto(Vec3{0, -1, 0}); }, "give no sun"},
      {[](pb::BakeSpec& s) { s.set_resolution("512"); }, "resolution is the sun's"},
      {[](pb::BakeSpec& s) { s.set_footprint(-1); }, "footprint must be finite"},
      {[](pb::BakeSpec& s) { s.set_footprint(std::numeric_limits<double>::quiet_NaN()); }, "footprint must be finite"},
      {[](pb::BakeSpec& s) { s.set_pointer_grid(6); }, "pointer_grid 6"},
      {[](pb::BakeSpec& s) { s.mutable_options()->mutable_receivers()->set_kind(pb::RECEIVERS_VOLUME); },
       "RECEIVERS_VOLUME needs"},
      {[](pb::BakeSpec& s) { s.mutable_lights(0)->set_cone_deg(0); }, "light 0: the cone's half-angle"},
      {[](pb::BakeSpec& s) { s.mutable_lights(0)->clear_direction(); }, "lights[0]"},
      {[](pb::BakeSpec& s) { s.mutable_lights(0)->set_resolution("300"); }, "lights[0]"},
      {[](pb::BakeSpec& s) {
         for (int k = 0; k < 5000; ++k) *s.add_lights() = s.lights(0);
       }, "lights"},
      {[](pb::BakeSpec& s) { s.set_scene_lights(true); }, "the scene holds no point, spot or area light"},
      {[](pb::BakeSpec& s) { s.mutable_lights(0)->set_area(1); }, "lights[0]: an area number is the farm's"},
      {[](pb::BakeSpec& s) {
         pb::AreaLight* a = s.add_area_lights();
         *a->mutable_centre() = net::toProto(Vec3{8, 20, 8});
         *a->mutable_edge_u() = net::toProto(Vec3{1, 0, 0});
         *a->mutable_edge_v() = net::toProto(Vec3{2, 0, 0});
       }, "area_lights[0]: the edges are zero or parallel"},
      {[](pb::BakeSpec& s) {
         pb::AreaLight* a = s.add_area_lights();
         *a->mutable_centre() = net::toProto(Vec3{800, 20, 8});
         *a->mutable_edge_u() = net::toProto(Vec3{1, 0, 0});
         *a->mutable_edge_v() = net::toProto(Vec3{0, 0, -1});
       }, "area_lights[0]: the position"},
      {[](pb::BakeSpec& s) {
         pb::AreaLight* a = s.add_area_lights();
         *a->mutable_centre() = net::toProto(Vec3{8, 20, 8});
         *a->mutable_edge_u() = net::toProto(Vec3{1, 0, 0});
         *a->mutable_edge_v() = net::toProto(Vec3{0, 0, -1});
         a->set_resolution("2048");
       }, "area_lights[0]: VPL resolution"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    pb::BakeSpec bad = lamp;
    cases[i].first(bad);
    try {
      farm.submitMessage("bad-" + std::to_string(i), bad);
      ADD_FAILURE() << "case " << i << " was accepted";
    } catch (const client::FarmCallError& e) {
      EXPECT_EQ(e.kind(), net::ErrorKind::InvalidArgument) << i << ": " << e.what();
      EXPECT_NE(std::string(e.what()).find(cases[i].second), std::string::npos) << i << ": " << e.what();
    }
  }
  // A sun bake takes neither a pointer grid nor a footprint.
  for (int i = 0; i < 2; ++i) {
    pb::BakeSpec bad = sun;
    if (i) bad.set_footprint(0.5);
    else bad.set_pointer_grid(2);
    EXPECT_THROW(farm.submitMessage("bad-sun-" + std::to_string(i), bad), client::FarmCallError);
  }
  EXPECT_TRUE(farm.client.list(true).empty());
  // The good one is accepted: one light, one grid, 16 tiles of 64.
  lamp.mutable_options()->set_tile_size(64);
  const pb::JobStatus ok = farm.submitMessage("good", lamp);
  EXPECT_EQ(ok.lights(), 1u);
  EXPECT_EQ(ok.grids(), 1u);
  EXPECT_EQ(ok.tiles_total(), 16u);
}

// A lamp's fixture named in its light: the workers bake its tiles without the shade, and
// the bundle is the local bake's (every grid's bytes and the plan that records it).
TEST(InProcessFarm, ALightsFixtureIsLeftOutOnTheWorkersAsInTheLocalBake) {
  TempDir dir("cpvs_in_process_fixture");
  // A street and a closed lamp shade around the bulb, as separate OBJ objects.
  const std::string obj = dir / "lamp.obj";
  std::ofstream(obj) << "o street\nv -50 0 -50\nv -50 0 50\nv 50 0 50\nv 50 0 -50\nf 1 2 3 4\no lamp\n"
                        "v -1 4 -1\nv 1 4 -1\nv -1 6 -1\nv 1 6 -1\nv -1 4 1\nv 1 4 1\nv -1 6 1\nv 1 6 1\n"
                        "f 5 9 11 7\nf 6 8 12 10\nf 5 6 10 9\nf 7 11 12 8\nf 5 7 8 6\nf 9 10 12 11\n";
  InProcessFarm farm(dir / "data");
  worker::WorkerConfig wc = testing::workerConfig(farm.connection(), dir / "cache");
  wc.threads = 2;
  worker::TileWorker tileWorker(wc);
  std::thread workerThread([&] { tileWorker.run(); });

  Light lamp;
  lamp.position = {0.3, 5, -0.2};
  lamp.direction = {0.1, -1, 0};
  lamp.coneDeg = 60;
  lamp.log2Resolution = 8;
  lamp.exclude = {"lamp"};
  net::BakeSpec spec;
  spec.sceneHash = farm.client.uploadScene(obj).sceneHash;
  spec.lights = {lamp};
  spec.options.tileSize = 64;
  const client::JobStatus submitted = farm.client.submit("fixture", spec);
  const client::JobStatus done = farm.client.watch(submitted.jobId);
  ASSERT_EQ(done.state, client::JobState::Done) << done.error;
  farm.client.download(submitted.jobId, dir / "farm.cpvs");
  // Declared receivers: the workers keep what lookups on the surfaces read (the shade's
  // too, though it casts nothing), as the local bake does.
  net::BakeSpec declared = spec;
  declared.options.receivers.emplace().kind = ReceiverKind::Surfaces;
  declared.options.receivers->maxPcf = 5;
  const client::JobStatus submittedSurfaces = farm.client.submit("fixture-surfaces", declared);
  const client::JobStatus doneSurfaces = farm.client.watch(submittedSurfaces.jobId);
  ASSERT_EQ(doneSurfaces.state, client::JobState::Done) << doneSurfaces.error;
  farm.client.download(submittedSurfaces.jobId, dir / "farm-surfaces.cpvs");
  tileWorker.stop();
  workerThread.join();

  const Scene scene = loadScene(obj);
  BakeOptions options;
  options.log2TileSize = 6;
  const LightBundle local = bakeLights(scene, {lamp}, defaultFootprint(scene), options, sceneHash(scene));
  const LightBundle fromFarm = readBundle(dir / "farm.cpvs");
  ASSERT_EQ(fromFarm.grids.size(), 1u);
  EXPECT_EQ(fromFarm.grids[0].bytes, local.grids[0].bytes);
  EXPECT_EQ(fromFarm.plan, local.plan);
  ReceiverDeclaration surfaces;
  surfaces.kind = ReceiverKind::Surfaces;
  surfaces.maxPcf = 5;
  BakeOptions surfacesOptions = options;
  surfacesOptions.receivers = ReceiverKind::Surfaces;
  surfacesOptions.receiverPcf = 5;
  const LightBundle localSurfaces = bakeLights(scene, {lamp}, defaultFootprint(scene), surfacesOptions, sceneHash(scene),
                                               nullptr, nullptr, nullptr, surfaces);
  const LightBundle farmSurfaces = readBundle(dir / "farm-surfaces.cpvs");
  EXPECT_EQ(encodeBundle(farmSurfaces, false), encodeBundle(localSurfaces, false));
  EXPECT_EQ(farmSurfaces.receiverHash, receiverHash(surfaces));
  EXPECT_EQ(farmSurfaces.options.receivers, ReceiverKind::Surfaces);
  EXPECT_NE(fromFarm.plan.find("\"exclude\": [\"lamp\"]"), std::string::npos) << fromFarm.plan;
  const BundleQuery q(fromFarm);
  EXPECT_EQ(q.filtered(0, {0.5, 0, 0.5}, {0, 1, 0}, 3), 1.0f) << "under the lamp, lit through its shade";

  // A fixture the scene does not name is refused at submit.
  spec.lights[0].exclude[0] = "lampshade";
  try {
    farm.client.submit("no-such-fixture", spec);
    ADD_FAILURE() << "a fixture the scene does not name was accepted";
  } catch (const client::FarmCallError& e) {
    EXPECT_EQ(e.kind(), net::ErrorKind::InvalidArgument);
    EXPECT_NE(std::string(e.what()).find("no mesh of the scene is named 'lampshade'"), std::string::npos) << e.what();
  }
}

// A bundle whose stored lights are damaged cannot bake a tile: it fails at its first
// lease instead of leasing its tiles until their attempts run out.
TEST(InProcessFarm, ABundleWhoseStoredLightsAreDamagedFailsAtItsFirstLease) {
  TempDir dir("cpvs_in_process_damaged_lights");
  const std::string obj = dir / "street.obj";
  std::ofstream(obj) << "o street\nv -50 0 -50\nv -50 0 50\nv 50 0 50\nv 50 0 -50\nf 1 2 3 4\n"
                        "o post\nv -1 0 -1\nv 1 0 -1\nv 0 6 0\nf 5 6 7\n";
  std::string job;
  {
    InProcessFarm farm(dir / "data");
    Light lamp;
    lamp.position = {0.3, 5, -0.2};
    lamp.direction = {0.1, -1, 0};
    lamp.coneDeg = 60;
    lamp.log2Resolution = 7;
    net::BakeSpec spec;
    spec.sceneHash = farm.client.uploadScene(obj).sceneHash;
    spec.lights = {lamp};
    job = farm.client.submit("damaged", spec).jobId;
  }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir / "data/farm.sqlite").c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "UPDATE jobs SET lights = x'ff01'", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
  InProcessFarm farm(dir / "data");
  EXPECT_THROW(farm.coordinator.leases().lease("w"), net::FarmError);
  const pb::JobStatus failed = farm.coordinator.jobs().status(job);
  EXPECT_EQ(failed.state(), pb::JOB_FAILED);
  EXPECT_NE(failed.error().find("its stored lights do not hold light 0"), std::string::npos) << failed.error();
  EXPECT_FALSE(farm.coordinator.leases().lease("w").granted()) << "no tile of it is leased again";
}

TEST(FarmStore, TypedColumnsRoundTripAndLeasesFollowPriority) {
  TempDir dir("cpvs_farm_store");
  server::FarmStore store(dir / "farm.sqlite");
  store.createJob(sampleJob("low", 0, 2));
  store.createJob(sampleJob("high", 5, 1));
  const auto back = store.job("low");
  ASSERT_TRUE(back.has_value());
  const server::JobRecord want = sampleJob("low", 0, 2);
  EXPECT_EQ(back->options, want.options);
  ASSERT_EQ(back->grids.size(), 1u) << "a sun job's one grid";
  EXPECT_TRUE(back->grids[0].grid == want.grids[0].grid);
  EXPECT_EQ(back->grids[0].grid.projection, Projection::Orthographic);
  EXPECT_EQ(back->grids[0].grid.log2Resolution, 10);
  EXPECT_FALSE(back->isBundle());
  EXPECT_EQ(back->spec, "spec bytes");
  EXPECT_EQ(back->grids[0].grid.depthSlices, 0u);
  {
    // A grid coarser in depth keeps its slices.
    server::FarmStore other(dir / "other.sqlite");
    server::JobRecord shallow = sampleJob("shallow", 0, 1);
    shallow.grids[0].grid.depthSlices = 256;
    other.createJob(shallow);
    EXPECT_EQ(other.job("shallow")->grids.at(0).grid.depthSlices, 256u);
  }

  // A light bundle's grids come back in order with every value, an infinite `closest`
  // (a grid no triangle reaches) included.
  server::JobRecord bundle = sampleJob("bundle", 0, 3);
  bundle.lights = std::string("light\0table", 11);
  bundle.grids.clear();
  for (uint32_t g = 0; g < 2; ++g) {
    server::JobGrid jg;
    jg.grid.projection = Projection::Perspective;
    jg.grid.position = {1.25 + g, -7.5, 1e-3};
    jg.grid.frame = LightFrame::fromDirection({0.1, -1, 0.3 * g});
    jg.grid.tanHalfFov = 0.75 + g;
    jg.grid.near = 0.0625;
    jg.grid.far = 80.5;
    jg.grid.log2Resolution = 9 - int(g);
    jg.grid.tanCone = 0.5;
    jg.light = g;
    jg.closest = g ? std::numeric_limits<double>::infinity() : 3.375;
    bundle.grids.push_back(jg);
  }
  store.createJob(bundle, std::vector<server::TileState>(3, server::TileState::Untouched));  // leases nothing below
  const auto b2 = store.job("bundle");
  ASSERT_TRUE(b2.has_value());
  EXPECT_EQ(b2->lights, bundle.lights);
  ASSERT_EQ(b2->grids.size(), 2u);
  for (size_t g = 0; g < 2; ++g) {
    const server::JobGrid &got = b2->grids[g], &want = bundle.grids[g];
    EXPECT_TRUE(got.grid == want.grid) << "grid " << g;
    EXPECT_EQ(got.light, want.light);
    EXPECT_EQ(got.closest, want.closest);
  }

  // Highest priority first, then the other job's tiles in order; nothing after that.
  auto a = store.leaseNextTile("w", "l1", 2000, 5000);
  auto b = store.leaseNextTile("w", "l2", 2000, 5000);
  auto c = store.leaseNextTile("w", "l3", 2000, 5000);
  ASSERT_TRUE(a && b && c);
  EXPECT_EQ(a->jobId, "high");
  EXPECT_EQ(b->jobId, "low");
  EXPECT_EQ(c->jobId, "low");
  EXPECT_NE(b->tile, c->tile);
  EXPECT_FALSE(store.leaseNextTile("w", "l4", 2000, 5000).has_value());
  // A renewed lease survives the reaper; an expired one goes back to the queue.
  EXPECT_TRUE(store.renewLease("l2", 9000));
  const auto expired = store.expireLeases(6000);
  EXPECT_EQ(expired.size(), 2u);  // l1 and l3
  EXPECT_TRUE(store.completeTile("low", b->tile));
  EXPECT_FALSE(store.completeTile("low", b->tile));  // the first result stands
  EXPECT_EQ(store.job("low")->tilesDone, 1u);
}

// Turns a store of this build's schema into one of schema 8: a sun job's grid in the jobs
// table's columns, job_grids with a bundle's perspective grids only.
void downgradeToSchema8(sqlite3* db) {
  const char* moved[][2] = {{"light_dir_x", "dir_x"}, {"light_dir_y", "dir_y"}, {"light_dir_z", "dir_z"},
                            {"frame_u_x", "u_x"},     {"frame_u_y", "u_y"},     {"frame_u_z", "u_z"},
                            {"frame_v_x", "v_x"},     {"frame_v_y", "v_y"},     {"frame_v_z", "v_z"},
                            {"origin_x", "origin_x"}, {"origin_y", "origin_y"}, {"origin_z", "origin_z"},
                            {"u0", "u0"},             {"v0", "v0"},             {"d0", "d0"},
                            {"extent", "extent"},     {"depth_extent", "depth_extent"},
                            {"log2_resolution", "log2_resolution"}};
  std::string sql;
  for (const auto& [job, grid] : moved)
    sql += std::string("ALTER TABLE jobs ADD COLUMN ") + job + (std::string(job) == "log2_resolution" ? " INTEGER; " : " REAL; ") +
           "UPDATE jobs SET " + job + " = (SELECT " + grid + " FROM job_grids WHERE job_grids.job_id = jobs.id AND projection = 0); ";
  sql += "DELETE FROM job_grids WHERE projection = 0; ALTER TABLE job_grids DROP COLUMN depth_slices; ";
  for (const char* column : {"projection", "origin_x", "origin_y", "origin_z", "u0", "v0", "d0", "extent", "depth_extent"})
    sql += std::string("ALTER TABLE job_grids DROP COLUMN ") + column + "; ";
  sql += "ALTER TABLE scenes DROP COLUMN owner; ALTER TABLE jobs DROP COLUMN receiver_scene; "
         "ALTER TABLE tracks DROP COLUMN scene_hash; ALTER TABLE tracks DROP COLUMN receiver_scene; "
         "ALTER TABLE tiles DROP COLUMN work; "
         "ALTER TABLE tiles DROP COLUMN seconds; ALTER TABLE tiles DROP COLUMN reused; PRAGMA user_version = 8";
  ASSERT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
}

// A store of schema 8 (a sun job's grid in the jobs table) is upgraded in place: every
// job's grids come back from job_grids, a sun's and a bundle's alike.
TEST(FarmStore, ASchemaEightStoreKeepsEveryGridOfEveryJob) {
  TempDir dir("cpvs_farm_store_v8");
  const std::string path = dir / "farm.sqlite";
  const server::JobRecord sun = sampleJob("sun", 0, 2);
  server::JobRecord bundle = sampleJob("bundle", 0, 1);
  bundle.lights = "lights";
  const PerspectiveGrid spot({1.5, 20.25, -3}, LightFrame::fromDirection({0.2, -1, 0.1}), 0.75, 0.0625, 80.5, 9);
  bundle.grids = {server::JobGrid{gridSpecOf(spot, 0.5), 0, 3.25}};
  {
    server::FarmStore store(path);
    store.createJob(sun);
    store.createJob(bundle);
  }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  downgradeToSchema8(db);
  sqlite3_close(db);
  server::FarmStore store(path);
  const auto s = store.job("sun"), b = store.job("bundle");
  ASSERT_TRUE(s && b);
  ASSERT_EQ(s->grids.size(), 1u);
  EXPECT_TRUE(s->grids[0].grid == sun.grids[0].grid);
  EXPECT_EQ(s->grids[0].closest, std::numeric_limits<double>::infinity());
  ASSERT_EQ(b->grids.size(), 1u);
  EXPECT_TRUE(b->grids[0].grid == bundle.grids[0].grid);
  EXPECT_EQ(b->grids[0].closest, 3.25);
  store.createJob(sampleJob("after", 0, 1));
  EXPECT_TRUE(store.job("after")->grids.at(0).grid == sun.grids[0].grid);
  // Scenes gained their owner (schema 10): none for those stored before.
  store.putScene({"s1", "a.obj", "", 100, 100, 12, true, "alice"});
  EXPECT_EQ(store.scene("s1")->owner, "alice");
}

// A store of schema 10 kept specs and lights as serialized protobuf: opened by the
// coordinator's rewrite, they become JSON documents that say the same, and the scenes
// they name fill their columns.
TEST(FarmStore, ASchemaTenStoreHasItsSpecsRewrittenAsJson) {
  TempDir dir("cpvs_farm_store_v10");
  const std::string path = dir / "farm.sqlite";
  pb::BakeSpec spec;
  spec.set_scene_hash(std::string(32, 'b'));
  spec.set_resolution("4K");
  spec.mutable_options()->mutable_receivers()->set_kind(pb::RECEIVERS_VOLUME);
  spec.mutable_options()->mutable_receivers()->set_volume_scene_hash(std::string(32, '7'));
  spec.set_name("with a volume");
  pb::LightList lights;
  lights.add_lights()->set_kind(pb::LIGHT_POINT);
  pb::TrackSpec trackSpec;
  trackSpec.set_scene_hash(std::string(32, '8'));
  trackSpec.set_resolution("1K");
  trackSpec.mutable_options()->mutable_receivers()->set_kind(pb::RECEIVERS_VOLUME);
  trackSpec.mutable_options()->mutable_receivers()->set_volume_scene_hash(std::string(32, '6'));
  {
    server::FarmStore store(path);
    server::JobRecord j = sampleJob("old", 0, 1);
    j.spec = spec.SerializeAsString();
    j.lights = lights.SerializeAsString();
    store.createJob(j);
    server::JobRecord sun = sampleJob("sun", 0, 1);
    sun.spec = pb::BakeSpec().SerializeAsString();  // an empty message: no bytes at all
    store.createJob(sun);
    server::TrackRecord t;
    t.id = "t1";
    t.requestId = "rt1";
    t.spec = trackSpec.SerializeAsString();
    store.createTrack(t);
  }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db,
                         "ALTER TABLE jobs DROP COLUMN receiver_scene; ALTER TABLE tracks DROP COLUMN scene_hash; "
                         "ALTER TABLE tracks DROP COLUMN receiver_scene; "
                         "ALTER TABLE tiles DROP COLUMN work; ALTER TABLE tiles DROP COLUMN seconds; ALTER TABLE tiles DROP COLUMN reused; "
                         "ALTER TABLE job_grids DROP COLUMN depth_slices; PRAGMA user_version = 10",
                         nullptr, nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(db);
  server::FarmStore store(path, server::legacySpecRewrite());
  const auto j = store.job("old");
  ASSERT_TRUE(j.has_value());
  EXPECT_EQ(j->spec.front(), '{') << j->spec;
  EXPECT_NE(j->spec.find("\"volume_scene_hash\":\"77777777777777777777777777777777\""), std::string::npos) << j->spec;
  EXPECT_TRUE(server::sameMessage(server::bakeSpecOf(*j), spec));
  EXPECT_TRUE(server::sameMessage(server::lightListOf(*j), lights));
  EXPECT_EQ(j->receiverScene, std::string(32, '7'));
  EXPECT_EQ(store.job("sun")->spec, "{}");
  EXPECT_TRUE(store.job("sun")->lights.empty());  // a sun job has none
  const auto t = store.track("t1");
  ASSERT_TRUE(t.has_value());
  EXPECT_TRUE(server::sameMessage(server::trackSpecOf(*t), trackSpec));
  EXPECT_EQ(t->sceneHash, std::string(32, '8'));
  EXPECT_EQ(t->receiverScene, std::string(32, '6'));
  // A damaged spec is a clear error, not an empty message.
  server::JobRecord damaged = *j;
  damaged.spec = "{\"scene_hash\": 3";
  EXPECT_THROW(server::bakeSpecOf(damaged), FormatError);
}

// The scenes retention may forget: none a job names (its scene or its receiver volume's)
// or an active track bakes (its scene or its receiver volume's).
TEST(FarmStore, UnusedScenesAreThoseNoJobOrActiveTrackNames) {
  TempDir dir("cpvs_farm_store_unused");
  server::FarmStore store(dir / "farm.sqlite");
  const std::string unused(32, 'd'), jobScene(32, 'b'), volume(32, '7'), tracked(32, '8'), ended(32, '9'),
      trackVolume(32, '6');
  for (const std::string& hash : {unused, jobScene, volume, tracked, ended, trackVolume})
    store.putScene({hash, "s.obj", "", 2, 2, 1, true, ""});
  server::JobRecord j = sampleJob("j", 0, 1);  // its scene is jobScene
  j.receiverScene = volume;
  store.createJob(j);
  for (const auto& [id, hash, state] : {std::tuple{"t1", tracked, 1}, std::tuple{"t2", ended, 2}}) {
    server::TrackRecord t;
    t.id = id;
    t.requestId = std::string("r") + id;
    t.sceneHash = hash;
    t.receiverScene = state == 1 ? trackVolume : "";
    t.state = state;
    store.createTrack(t);
  }
  std::vector<std::string> pruned = store.pruneUnusedScenes(std::numeric_limits<int64_t>::max(), 100);
  std::sort(pruned.begin(), pruned.end());
  EXPECT_EQ(pruned, (std::vector<std::string>{ended, unused}));  // sorted
}

// Each tile's work (triangles) is kept with it, and the seconds of the tiles done; the
// sums the ETA fits count done tiles with work and seconds, and the work left.
TEST(FarmStore, TileCostsSumTheTilesDoneAndTheWorkLeft) {
  TempDir dir("cpvs_farm_store_costs");
  server::FarmStore store(dir / "farm.sqlite");
  server::JobRecord j = sampleJob("j", 0, 5);
  store.createJob(j, {server::TileState::Queued, server::TileState::Queued, server::TileState::Untouched,
                      server::TileState::Queued, server::TileState::Queued},
                  {10, 20, 0, 30, 40});
  EXPECT_EQ(store.tileCosts("j").done.n, 0);
  EXPECT_EQ(store.tileCosts("j").leftTiles, 4u);
  EXPECT_EQ(store.tileCosts("j").leftWork, 100);
  EXPECT_TRUE(store.completeTile("j", 0, 1.5));
  EXPECT_TRUE(store.completeTile("j", 3, 2.5));
  EXPECT_FALSE(store.completeTile("j", 3, 9.0));  // the first result's seconds stand
  const server::TileCosts c = store.tileCosts("j");
  EXPECT_EQ(c.done.n, 2);
  EXPECT_EQ(c.done.w, 40);
  EXPECT_EQ(c.done.ww, 100 + 900);
  EXPECT_EQ(c.done.t, 4.0);
  EXPECT_EQ(c.done.wt, 10 * 1.5 + 30 * 2.5);
  EXPECT_EQ(c.leftTiles, 2u);
  EXPECT_EQ(c.leftWork, 60);
  // A tile a worker sent from its tile cache is done and counted, but its seconds are not
  // a bake's: the ETA's sums leave it out.
  EXPECT_TRUE(store.completeTile("j", 1, 0.01, true));
  EXPECT_EQ(store.tileCosts("j").done.n, 2);
  EXPECT_EQ(store.tileCosts("j").leftTiles, 1u);
  EXPECT_EQ(store.job("j")->tilesReused, 1u);
  EXPECT_EQ(store.job("j")->tilesDone, 4u);  // with the untouched one
  // A job made without work (a bundle, or an upgraded store's) has none to fit.
  store.createJob(sampleJob("none", 0, 2));
  EXPECT_TRUE(store.completeTile("none", 0, 3.0));
  EXPECT_EQ(store.tileCosts("none").done.n, 0);
  EXPECT_EQ(store.tileCosts("none").leftTiles, 0u);
}

// The bytes a client's scenes take (its upload quota's reading): announced by its uploads
// in progress, and stored; another owner's are not its.
TEST(FarmStore, SceneBytesAreCountedPerOwner) {
  TempDir dir("cpvs_farm_store_scene_bytes");
  server::FarmStore store(dir / "farm.sqlite");
  EXPECT_EQ(store.sceneBytesOf("alice").uploading, 0u);
  store.putScene({"s1", "a.obj", "", 100, 100, 12, true, "alice"});
  store.putScene({"s2", "b.obj", "", 1000, 10, 0, false, "alice"});
  store.putScene({"s3", "c.obj", "", 7000, 0, 0, false, "alice"});
  store.putScene({"s4", "d.obj", "", 50000, 50000, 4, true, "bob"});
  store.putScene({"s5", "e.obj", "", 3, 0, 0, false, ""});
  const server::SceneBytes alice = store.sceneBytesOf("alice"), bob = store.sceneBytesOf("bob");
  EXPECT_EQ(alice.uploading, 8000u);
  EXPECT_EQ(alice.stored, 100u);
  EXPECT_EQ(bob.uploading, 0u);
  EXPECT_EQ(bob.stored, 50000u);
  EXPECT_EQ(store.sceneBytesOf("").uploading, 3u);
}

// A store of schema 2 (before the renderer column) is upgraded in place: its jobs were
// baked by Embree, and they keep every other field.
TEST(FarmStore, ASchemaTwoStoreIsUpgradedAndItsJobsKeepEmbree) {
  TempDir dir("cpvs_farm_store_v2");
  const std::string path = dir / "farm.sqlite";
  {
    server::FarmStore store(path);
    server::JobRecord j = sampleJob("old", 0, 2);
    j.options.renderer = Renderer::Raster;
    store.createJob(j);
  }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  downgradeToSchema8(db);
  ASSERT_EQ(sqlite3_exec(db,
                         "ALTER TABLE jobs DROP COLUMN renderer; ALTER TABLE jobs DROP COLUMN receivers; "
                         "ALTER TABLE jobs DROP COLUMN receiver_pcf; ALTER TABLE jobs DROP COLUMN receiver_hash; "
                         "ALTER TABLE jobs DROP COLUMN plan; ALTER TABLE tiles DROP COLUMN failed_by; "
                         "ALTER TABLE jobs DROP COLUMN owner; ALTER TABLE scenes DROP COLUMN last_used_ms; DROP TABLE versions; "
                         "ALTER TABLE jobs DROP COLUMN lights; DROP TABLE job_grids; "
                         "DROP TABLE keyframes; "
                         "DROP TABLE tracks; PRAGMA user_version = 2",
                         nullptr, nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(db);
  server::FarmStore store(path);
  const auto back = store.job("old");
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(back->options.renderer, Renderer::Embree);
  EXPECT_EQ(back->options.receivers, ReceiverKind::Everywhere);  // and baked for receivers everywhere
  EXPECT_EQ(back->receiverHash, Hash128{});
  ASSERT_EQ(back->grids.size(), 1u);
  EXPECT_TRUE(back->grids[0].grid == sampleJob("old", 0, 2).grids[0].grid);
  EXPECT_EQ(back->tilesTotal, 2u);
  EXPECT_EQ(back->owner, "");  // made before owners: every client sees it
  EXPECT_TRUE(back->lights.empty());  // made before light bundles: a sun bake
  server::JobRecord fresh = sampleJob("new", 0, 1);
  store.createJob(fresh);
  EXPECT_EQ(store.job("new")->options.renderer, Renderer::Raster);
}

// R25: a store whose pages were damaged (a bad disk, a copy cut short) is refused at
// start with what to do, not found out by the first job that reads the page.
TEST(FarmStore, ADamagedStoreIsRefusedAtStart) {
  TempDir dir("cpvs_farm_store_damaged");
  const std::string path = dir / "farm.sqlite";
  {
    server::FarmStore store(path);
    for (int i = 0; i < 40; ++i) store.createJob(sampleJob("j" + std::to_string(i), 0, 64));
  }
  std::vector<uint8_t> bytes = readFile(path);
  ASSERT_GT(bytes.size(), 5u * 4096);
  for (size_t i = 3 * 4096; i < 3 * 4096 + 512; ++i) bytes[i] = uint8_t(i * 131);
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  }
  try {
    server::FarmStore store(path);
    ADD_FAILURE() << "a damaged store was opened";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("is damaged"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("empty --data folder"), std::string::npos) << e.what();
  }
}

TEST(FarmStore, ADatabaseOfAnotherSchemaIsRefusedWithWhatToDo) {
  TempDir dir("cpvs_farm_store_schema");
  const std::string path = dir / "farm.sqlite";
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "CREATE TABLE jobs(id TEXT PRIMARY KEY, grid BLOB)", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
  try {
    server::FarmStore store(path);
    ADD_FAILURE() << "an older database was opened";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("schema version 1"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("empty --data folder"), std::string::npos) << e.what();
  }
}

TEST(TokenTable, RolesFromAFileAndWhatEachMayCall) {
  TempDir dir("cpvs_tokens");
  const std::string c = "ada5488cf52579ea83782e5446deeaff636815e7", w = "1426e4ffcdb984edcbc63533326ea7d6325e7f04",
                    a = "174925fc779e85a1db618e5b4e29c2ba603c5ab6";
  std::ofstream(dir / "tokens") << "# farm tokens\nclient " << c << "\nworker " << w << "\nadmin " << a << "\n";
  const server::TokenTable t = server::TokenTable::load(dir / "tokens");
  EXPECT_TRUE(t.enabled());
  EXPECT_EQ(t.roleOf(c), server::Role::Client);
  EXPECT_EQ(t.roleOf(w), server::Role::Worker);
  EXPECT_EQ(t.roleOf(a), server::Role::Admin);
  EXPECT_FALSE(t.roleOf("nope").has_value());
  EXPECT_FALSE(t.roleOf(c.substr(0, 32)).has_value());  // a prefix is not the token
  // Only SHA-256 digests are held (R18), never a token as sent.
  std::vector<std::string> digests = t.digestsForTests();
  std::sort(digests.begin(), digests.end());
  EXPECT_EQ(digests, (std::vector<std::string>{"43a81a9265b14741e45cbe31676f157dcd44b49757dfa779d92af1cce6e9591f",
                                               "a36c0388b2513f35e1f160c064eee6b1eab0bfb4aa1a8f8d46a7911ee0f5c8c3",
                                               "ba7526a3a42b9e53cbf1c1fcf160b25d117653eaeb55bc4b223fcb905a1cd707"}));
  EXPECT_TRUE(server::TokenTable::allows(server::Role::Admin, server::Role::Worker));
  EXPECT_FALSE(server::TokenTable::allows(server::Role::Client, server::Role::Worker));
  std::ofstream(dir / "bad") << "superuser " << c << "\n";
  EXPECT_THROW(server::TokenTable::load(dir / "bad"), InputError);
  // Owners (R28): named, shared by the tokens that name them; else each token its own.
  EXPECT_EQ(t.ownerOf(c), "token-a36c0388b251");  // 12 hex digits of its SHA-256
  EXPECT_FALSE(t.ownerOf("nope").has_value());
  std::ofstream(dir / "owned") << "client " << c << " team-a\nclient " << w << " team-a\n";
  const server::TokenTable owned = server::TokenTable::load(dir / "owned");
  EXPECT_EQ(owned.ownerOf(c), "team-a");
  EXPECT_EQ(owned.ownerOf(w), "team-a");
  for (const std::string& line : {"client " + c + " two words", "client " + c + " team/a", "client " + c + " " + std::string(65, 'x')}) {
    std::ofstream(dir / "bad") << line << "\n";
    EXPECT_THROW(server::TokenTable::load(dir / "bad"), InputError) << line;
  }
}

// R7: tokens a person made up, or left as shipped, are refused when the table loads.
TEST(TokenTable, PlaceholderAndWeakTokensAreRefused) {
  TempDir dir("cpvs_weak_tokens");
  auto refused = [&](const std::string& token, const std::string& words) {
    std::ofstream(dir / "tokens") << "client " << token << "\n";
    try {
      server::TokenTable::load(dir / "tokens");
      ADD_FAILURE() << "accepted " << token;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("too weak"), std::string::npos) << e.what();
    }
  };
  refused("REPLACE_WITH_CLIENT_TOKEN", "placeholder");
  refused("changeme-changeme-changeme-changeme", "placeholder");
  refused("client-token-0123456789", "fewer than 32");
  refused("31415926535897932384626433832795", "bits");  // 32 digits: 106 bits
  refused("abababababababababababababababababab", "distinct");
  refused("0123456789abcdef0123456789abcdef0123", "pattern of");
  refused("a1b2c3d4e5f6a7b8c9d0000000000aaaaaaaaaa", "one character 9 times");
  // The shipped Kubernetes secret's values are placeholders: applied unchanged, the
  // coordinator does not start.
  std::ifstream yaml(std::string(CPVS_SOURCE_DIR) + "/deploy/k8s/secret-tokens.yaml");
  std::stringstream text;
  text << yaml.rdbuf();
  const std::string shipped = text.str();
  const size_t at = shipped.find("client REPLACE_WITH");
  ASSERT_NE(at, std::string::npos);
  refused(shipped.substr(at + 7, shipped.find('\n', at) - at - 7), "placeholder");
  // What make-secrets.sh makes (64 hex digits) and 32 random letters and digits pass.
  EXPECT_FALSE(server::weaknessOf("9c0f4b5e2a7d61f38e4c2b9a0d7f5e6c1b3a8d2f4e6c0b9a7d5f3e1c2b4a6d8f").has_value());
  EXPECT_FALSE(server::weaknessOf("Zq3xW9pL2vK8mN4rT6yB1cH5jF7gD0sA").has_value());
}

TEST(Convert, ReceiversRoundTripAndBadOnesAreNamed) {
  BakeOptions o;
  o.receivers = ReceiverKind::SurfacesTwoSided;
  o.receiverPcf = 3;
  EXPECT_EQ(net::fromProto(net::toProto(o)), o);
  EXPECT_FALSE(net::toProto(BakeOptions{}).has_receivers());
  pb::BakeOptions p;
  p.mutable_receivers()->set_kind(pb::RECEIVERS_SURFACES);
  EXPECT_EQ(net::fromProto(p).receiverPcf, 9);  // 0: the widest
  auto refused = [](pb::Receivers r, const std::string& words) {
    try {
      net::checkReceivers(r);
      ADD_FAILURE() << "accepted: " << words;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  pb::Receivers r;
  r.set_kind(pb::ReceiverKind(9));
  refused(r, "kind: unknown value 9");
  r.set_kind(pb::RECEIVERS_SURFACES);
  r.set_max_pcf(4);
  refused(r, "max_pcf 4");
  r.set_max_pcf(11);
  refused(r, "max_pcf 11");
  r.set_max_pcf(9);
  r.set_volume_scene_hash(std::string(32, 'a'));
  refused(r, "only RECEIVERS_VOLUME and RECEIVERS_CAMERAS take a volume");
  r.clear_volume_scene_hash();
  r.set_view_distance(5);
  refused(r, "view_distance must be positive and finite for RECEIVERS_CAMERAS, 0 otherwise");
  r.set_kind(pb::RECEIVERS_CAMERAS);
  refused(r, "camera_points or camera_paths are needed");
  r.set_view_distance(0);
  r.set_volume_scene_hash(std::string(32, 'a'));
  r.set_kind(pb::RECEIVERS_VOLUME);
  r.set_volume_scene_hash("../../etc/passwd");
  refused(r, "volume_scene_hash");
  r.clear_volume_scene_hash();
  refused(r, "needs volume_scene_hash, boxes or ground_layer");
  r.set_ground_layer(-2);
  refused(r, "ground_layer must be a finite number >= 0");
  r.set_ground_layer(2);
  EXPECT_NO_THROW(net::checkReceivers(r));  // a volume that is only a ground layer
  r.set_ground_layer_from(2);
  refused(r, "ground_layer_from must be at least 0 and below ground_layer");
  r.set_ground_layer_from(0.5);
  r.set_ground_slope_deg(90);
  refused(r, "ground_slope_deg must be at least 0 and below 90");
  r.set_ground_slope_deg(30);
  EXPECT_NO_THROW(net::checkReceivers(r));
  r.clear_ground_slope_deg();
  r.set_ground_layer(0);
  r.set_ground_layer_from(0);
  pb::ReceiverBox& b = *r.add_boxes();
  *b.mutable_min() = net::toProto(Vec3{0, 0, 0});
  *b.mutable_max() = net::toProto(Vec3{1, std::nan(""), 1});
  refused(r, "not finite with min < max");
  *b.mutable_max() = net::toProto(Vec3{1, 1, 1});
  EXPECT_NO_THROW(net::checkReceivers(r));
  for (int i = 0; i < net::kMaxReceiverBoxes; ++i) *r.add_boxes() = b;
  refused(r, "at most 4096");

  // Cameras: points and paths, sampled visibility and its settings.
  pb::Receivers c;
  c.set_kind(pb::RECEIVERS_CAMERAS);
  c.set_view_distance(5);
  *c.add_camera_points() = net::toProto(Vec3{0, std::nan(""), 0});
  refused(c, "camera_points: a point is not finite");
  *c.mutable_camera_points(0) = net::toProto(Vec3{0, 1, 0});
  EXPECT_NO_THROW(net::checkReceivers(c));
  c.set_camera_spacing(2);
  refused(c, "camera_spacing and camera_rays are for CAMERA_VISIBILITY_SAMPLED only");
  c.set_camera_visibility(pb::CAMERA_VISIBILITY_SAMPLED);
  EXPECT_NO_THROW(net::checkReceivers(c));
  c.set_camera_rays(5000);
  refused(c, "camera_rays 5000 is above 2048");
  c.set_camera_rays(64);
  c.set_camera_visibility(pb::CameraVisibility(7));
  refused(c, "camera_visibility: unknown value 7");
  c.set_camera_visibility(pb::CAMERA_VISIBILITY_SAMPLED);
  c.add_camera_paths();
  refused(c, "a path has no points");
  c.clear_camera_paths();
  c.set_kind(pb::RECEIVERS_SURFACES);
  refused(c, "camera_regions, camera_points or camera_paths are needed for RECEIVERS_CAMERAS, and only there");
}

TEST(Convert, OptionsAndGridsRoundTripAndTheWeakHashStaysHome) {
  BakeOptions o;
  o.closed = ClosedMode::On;
  o.exit = ExitMode::Approx;
  o.cull = false;
  o.compress = CompressMode::None;
  o.undefinedRule = UndefinedRule::Old;
  o.log2TileSize = 9;
  EXPECT_EQ(net::fromProto(net::toProto(o)), o);
  OrthoGrid g = orthoGridOf(sampleJob("x", 0, 1).grids[0].grid, "grid");
  g.depthSlices = uint32_t(g.resolution() / 4);  // a grid coarser in depth keeps its slices
  const OrthoGrid back = orthoGridOf(net::gridSpecOf(net::toProto(gridSpecOf(g))), "grid");
  EXPECT_EQ(back.depthSlices, g.depthSlices);
  EXPECT_EQ(back.origin, g.origin);
  EXPECT_EQ(back.extent, g.extent);
  EXPECT_EQ(back.frame.u, g.frame.u);
  EXPECT_TRUE(gridSpecOf(back) == gridSpecOf(g));
  // A spot grid round-trips with its cone; neither projection is made from the other's.
  const PerspectiveGrid spot({1.5, 20.25, -3}, LightFrame::fromDirection({0.2, -1, 0.1}), 0.75, 0.0625, 80.5, 9);
  const pb::GridSpec sp = net::toProto(gridSpecOf(spot, 0.5));
  const GridSpec spotSpec = net::gridSpecOf(sp);
  EXPECT_TRUE(spotSpec == gridSpecOf(spot, 0.5));
  const PerspectiveGrid spotBack = perspectiveGridOf(spotSpec, "grid");
  EXPECT_EQ(spotBack.position(), spot.position());
  EXPECT_EQ(spotBack.frame().dir, spot.frame().dir);
  EXPECT_EQ(spotBack.frame().u, spot.frame().u);
  EXPECT_EQ(spotBack.tanHalfFov(), spot.tanHalfFov());
  EXPECT_EQ(spotBack.near(), spot.near());
  EXPECT_EQ(spotBack.far(), spot.far());
  EXPECT_EQ(spotBack.log2Resolution(), 9);
  EXPECT_EQ(spotSpec.tanCone, 0.5);
  EXPECT_NE(testing::inputErrorOf([&] { orthoGridOf(spotSpec, "grid"); }).find("grid: a perspective grid, not the orthographic"),
            std::string::npos);
  EXPECT_THROW(perspectiveGridOf(gridSpecOf(g), "grid"), InputError);
  pb::GridSpec badCone = sp;
  badCone.set_tan_cone(0);
  EXPECT_NE(testing::inputErrorOf([&] { perspectiveGridOf(net::gridSpecOf(badCone), "grid"); }).find("cone"), std::string::npos);
  pb::GridSpec badNear = sp;
  badNear.set_near(100);
  EXPECT_THROW(perspectiveGridOf(net::gridSpecOf(badNear), "grid"), InputError);
  pb::GridSpec badProjection = sp;
  badProjection.set_projection(pb::GridProjection(7));
  EXPECT_NE(testing::inputErrorOf([&] { net::gridSpecOf(badProjection); }).find("grid.projection 7 is not a projection"),
            std::string::npos);
  pb::GridSpec badResolution = sp;
  badResolution.set_log2_resolution(4000000000u);
  EXPECT_NE(testing::inputErrorOf([&] { net::gridSpecOf(badResolution); }).find("out of range"), std::string::npos);
  o.hash = HashKind::WeakForTests;
  EXPECT_THROW(net::toProto(o), InputError);
  pb::BakeOptions p;
  p.set_tile_size(100);
  EXPECT_THROW(net::fromProto(p), InputError);
  p.set_tile_size(0);
  EXPECT_EQ(net::fromProto(p).log2TileSize, kDefaultLog2TileSize);
}

}  // namespace
}  // namespace cpvs
