// Sampled camera visibility: the exact caster against testing every triangle, bit for bit;
// occluders hide what the faced (conservative) declaration keeps; the sample is the same
// on any thread count (on the calling thread alone under a limit of one, as `--threads 1`
// sets) and a subset of the faced sides; positions, budgets and refusals.
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <tbb/task_scheduler_observer.h>

#include <atomic>
#include <chrono>
#include <thread>

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <optional>
#include <random>

#include "cpvs/bake/camera_views.h"
#include "cpvs/bake/receivers.h"
#include "cpvs/base/error.h"
#include "cpvs/raytrace/exact_caster.h"
#include "cpvs/scene/boxes.h"
#include "scene_testing.h"
#include "cpvs/scene/procedural_city.h"

namespace cpvs {
namespace {

using testing::appendQuad;

/// Counts TBB worker threads joining the calling thread's arena to run its tasks.
struct WorkerEntries : tbb::task_scheduler_observer {
  std::atomic<int> count{0};
  WorkerEntries() { observe(true); }
  ~WorkerEntries() override { observe(false); }
  void on_scheduler_entry(bool isWorker) override { count += isWorker ? 1 : 0; }
};

/// The procedural city and sampled cameras: a street level region in the middle, a path
/// along an edge and up. `faced`: the sides the faced declaration of the same places keeps.
ReceiverDeclaration cityCameras(const Scene& city, std::vector<uint8_t>* faced = nullptr) {
  ReceiverDeclaration d;
  d.kind = ReceiverKind::Cameras;
  Vec3 lo, hi;
  sceneBounds(city, lo, hi);
  const Vec3 mid = (lo + hi) * 0.5;
  const double e = hi.x - lo.x;
  d.cameraRegions = {{Vec3{mid.x - 0.1 * e, lo.y + 0.01 * e, mid.z - 0.1 * e}, Vec3{mid.x + 0.1 * e, lo.y + 0.02 * e, mid.z + 0.1 * e}}};
  d.cameraPaths = {{Vec3{lo.x, lo.y + 0.01 * e, lo.z}, Vec3{hi.x, lo.y + 0.01 * e, lo.z}, Vec3{hi.x, hi.y, hi.z}}};
  d.viewDistance = 0.3 * e;
  if (faced) *faced = receivingSides(city, d);
  d.cameraVisibility = CameraVisibility::Sampled;
  d.cameraSpacing = 0.04 * e;
  d.cameraRays = 32;
  return d;
}

TEST(ExactCaster, AgreesBitForBitWithTestingEveryTriangle) {
  // Random triangles and a grid of quads sharing edges and vertices (rays through them tie).
  Scene s;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-10, 10);
  for (int i = 0; i < 300; ++i) {
    const Vec3 c{u(rng), u(rng), u(rng)};
    const uint32_t base = uint32_t(s.positions.size());
    for (int k = 0; k < 3; ++k) s.positions.push_back(c + Vec3{u(rng), u(rng), u(rng)} * 0.15);
    for (uint32_t k : {0u, 1u, 2u}) s.indices.push_back(base + k);
  }
  for (int x = -4; x < 4; ++x)
    for (int z = -4; z < 4; ++z) appendQuad(s, {double(x), 0, double(z)}, {double(x), 0, z + 1.0}, {x + 1.0, 0, z + 1.0}, {x + 1.0, 0, double(z)});
  finalizeScene(s);
  const ExactCaster caster(s);
  int hits = 0;
  for (int i = 0; i < 20000; ++i) {
    Vec3 o{u(rng), u(rng), u(rng)}, d{u(rng), u(rng), u(rng)};
    if (i % 5 == 0) d = Vec3{0, i % 10 == 0 ? -1.0 : 1.0, 0} * (1 + i % 3);  // axis-aligned: zero components
    if (i % 7 == 0) d = Vec3{double(int(u(rng)) % 4), 0, double(int(u(rng)) % 4)} - o;  // through a grid vertex
    if (i % 11 == 0) d = Vec3{double(int(u(rng)) % 4) + 0.5, 0, double(int(u(rng)) % 4)} - o;  // through an edge
    const double tMax = i % 3 == 0 ? 2.0 : 1e9;
    const ExactCaster::Hit a = caster.firstHit(o, d, tMax), b = caster.firstHitBruteForce(o, d, tMax);
    ASSERT_EQ(a.triangle, b.triangle) << i;
    if (a.triangle != ExactCaster::kNoHit) {
      ++hits;
      EXPECT_EQ(a.t, b.t) << i;
      EXPECT_GT(a.t, 0);
      EXPECT_LE(a.t, tMax);
    }
  }
  EXPECT_GT(hits, 3000);
  // Straight down onto a shared edge of two quads: both triangles on it tie, the lower index wins.
  Scene two;
  appendQuad(two, {-1, 0, 0}, {-1, 0, 1}, {0, 0, 1}, {0, 0, 0});
  appendQuad(two, {0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {1, 0, 0});
  finalizeScene(two);
  const ExactCaster pair(two);
  const ExactCaster::Hit edge = pair.firstHit({0, 5, 0.5}, {0, -1, 0}, 10);
  ASSERT_NE(edge.triangle, ExactCaster::kNoHit);
  EXPECT_EQ(edge.t, 5);
  EXPECT_EQ(pair.firstHitBruteForce({0, 5, 0.5}, {0, -1, 0}, 10).triangle, edge.triangle);
  EXPECT_LT(edge.triangle, 2u);  // the first quad's
  EXPECT_EQ(pair.firstHit({0, 5, 0.5}, {0, -1, 0}, 4.9).triangle, ExactCaster::kNoHit);  // beyond tMax
  EXPECT_EQ(ExactCaster(Scene{}).firstHit({0, 0, 0}, {1, 0, 0}, 1).triangle, ExactCaster::kNoHit);
}

// A camera at the origin looking along +z at a target quad facing it, behind a wall that
// covers it; a second quad off to the side it sees; a closed box it sees from outside.
Scene occludedScene() {
  Scene s;
  appendQuad(s, {-1, -1, 10}, {-1, 1, 10}, {1, 1, 10}, {1, -1, 10});    // 0,1: the target, facing -z
  appendQuad(s, {-3, -3, 5}, {-3, 3, 5}, {3, 3, 5}, {3, -3, 5});        // 2,3: the wall, facing -z
  appendQuad(s, {-9, -1, 2}, {-9, 1, 2}, {-9, 1, 4}, {-9, -1, 4});      // 4,5: a side quad, facing +x
  appendBox(s, {6, -1, -1}, {8, 1, 1});                                  // 6..17: a closed box
  finalizeScene(s);
  return s;
}

ReceiverDeclaration cameraAtOrigin(CameraVisibility visibility) {
  ReceiverDeclaration d;
  d.kind = ReceiverKind::Cameras;
  d.cameraPoints = {Vec3{0, 0, 0}};
  d.viewDistance = 30;
  d.cameraVisibility = visibility;
  if (visibility == CameraVisibility::Sampled) d.cameraRays = 64;
  return d;
}

TEST(CameraViews, OccludersHideWhatTheFacedDeclarationKeeps) {
  const Scene s = occludedScene();
  const std::vector<uint8_t> faced = receivingSides(s, cameraAtOrigin(CameraVisibility::Faced));
  const CameraViews sampled = sampleCameraViews(s, cameraAtOrigin(CameraVisibility::Sampled));
  EXPECT_EQ(receivingSides(s, cameraAtOrigin(CameraVisibility::Sampled)), sampled.sides);
  // Faced: the target's front (it faces the camera) is kept though the wall hides it.
  EXPECT_EQ(faced[0], 1);
  EXPECT_EQ(faced[1], 1);
  // Sampled: the wall's front, not the target; the side quad's front.
  EXPECT_EQ(sampled.sides[0], 0);
  EXPECT_EQ(sampled.sides[1], 0);
  EXPECT_EQ(sampled.sides[2], 1);
  EXPECT_EQ(sampled.sides[3], 1);
  EXPECT_EQ(sampled.sides[4], 1);
  EXPECT_EQ(sampled.sides[5], 1);
  // The box: only faces that look at the camera, only their outside.
  int boxSeen = 0;
  for (size_t t = 6; t < s.triangleCount(); ++t) {
    EXPECT_LE(sampled.sides[t], 1) << t;
    EXPECT_EQ(sampled.sides[t] & ~faced[t], 0) << t;
    boxSeen += sampled.sides[t];
  }
  EXPECT_GE(boxSeen, 2);   // its -x face
  EXPECT_LE(boxSeen, 6);   // never its +x face
  EXPECT_EQ(sampled.positions, 1u);
  EXPECT_EQ(sampled.rays, 6u * 64 * 64);
  EXPECT_GT(sampled.hits, 0u);
  // Out of the view distance: nothing.
  ReceiverDeclaration near = cameraAtOrigin(CameraVisibility::Sampled);
  near.viewDistance = 1.5;
  for (uint8_t side : sampleCameraViews(s, near).sides) EXPECT_EQ(side, 0);
}

// The child process of TheCastHonoursAThreadLimit: a limit of CPVS_TEST_THREAD_LIMIT
// threads (0: none) set before any parallel work, as `--threads` does; its exit status
// is 100 plus how many times a TBB worker joined the cast (so that a child that ran no
// test, exiting 0, is no answer).
TEST(CameraViewsChild, DISABLED_CastUnderALimit) {
  const char* text = std::getenv("CPVS_TEST_THREAD_LIMIT");
  if (!text) GTEST_SKIP() << "run by TheCastHonoursAThreadLimit";
  std::optional<tbb::global_control> limit;
  if (std::atoi(text) > 0) limit.emplace(tbb::global_control::max_allowed_parallelism, size_t(std::atoi(text)));
  const Scene city = makeProceduralCity(6, 11);
  const ReceiverDeclaration d = cityCameras(city);
  WorkerEntries workers;
  (void)sampleCameraViews(city, d);
  std::_Exit(100 + std::min(workers.count.load(), 100));
}

// `--threads 1` (a TBB limit set before any parallel work) keeps the camera cast on the
// calling thread: in a fresh process, no TBB worker joins it; without the limit, they do.
TEST(CameraViews, TheCastHonoursAThreadLimit) {
  const std::string self = std::filesystem::read_symlink("/proc/self/exe").string();
  auto workersJoining = [&](int limit) {
    const std::string command = "CPVS_TEST_THREAD_LIMIT=" + std::to_string(limit) + " '" + self +
                                "' --gtest_also_run_disabled_tests --gtest_filter=CameraViewsChild.* >/dev/null 2>&1";
    const int status = std::system(command.c_str());
    return WIFEXITED(status) && WEXITSTATUS(status) >= 100 ? WEXITSTATUS(status) - 100 : -1;
  };
  EXPECT_EQ(workersJoining(1), 0);
  if (std::thread::hardware_concurrency() > 1) {
    // A busy machine may run a short cast before a worker wakes: a few tries.
    int joined = 0;
    for (int attempt = 0; attempt < 3 && joined <= 0; ++attempt) joined = workersJoining(0);
    EXPECT_GT(joined, 0) << "the count sees workers";
  }
}

TEST(CameraViews, SampledSidesAreTheSameOnAnyThreadCountAndWithinTheFacedOnes) {
  const Scene city = makeProceduralCity(6, 11);
  std::vector<uint8_t> faced;
  const ReceiverDeclaration d = cityCameras(city, &faced);
  const CameraViews many = sampleCameraViews(city, d);
  CameraViews one;
  {
    tbb::global_control serial(tbb::global_control::max_allowed_parallelism, 1);
    one = sampleCameraViews(city, d);
  }
  EXPECT_EQ(one.sides, many.sides);
  EXPECT_EQ(one.hits, many.hits);
  size_t seen = 0, facedCount = 0;
  for (size_t t = 0; t < faced.size(); ++t) {
    EXPECT_EQ(many.sides[t] & ~faced[t], 0) << t;
    seen += many.sides[t] != 0;
    facedCount += faced[t] != 0;
  }
  EXPECT_GT(seen, 0u);
  EXPECT_LT(seen, facedCount);  // occluders in a city hide sides the faced test keeps

  // An independent sample (another seed) sees mostly what the first saw.
  const CameraViews other = sampleCameraViews(city, d, 1, &many.sides);
  EXPECT_EQ(other.positions, many.positions);
  EXPECT_LT(other.hitsOutside, other.hits / 20);
  EXPECT_GT(other.areaDeclared, 0);
  EXPECT_EQ(sampleCameraViews(city, d, 0, &many.sides).hitsOutside, 0u);  // itself: nothing outside
}

TEST(CameraViews, PositionsCoverTheirPlacesAndDenseDeclarationsAreRefused) {
  ReceiverDeclaration d;
  d.kind = ReceiverKind::Cameras;
  d.viewDistance = 80;  // the default spacing: 5
  d.cameraVisibility = CameraVisibility::Sampled;
  d.cameraRegions = {{Vec3{0, 0, 0}, Vec3{10, 2, 10}}};
  d.cameraPoints = {Vec3{-1, -2, -3}};
  d.cameraPaths = {{Vec3{0, 0, 0}, Vec3{12, 0, 0}}, {Vec3{4, 4, 4}}};
  EXPECT_EQ(cameraSpacing(d), 5);
  const std::vector<Vec3> p = cameraPositions(d);
  // The point; the region's 3 x 2 x 3 grid (corners included); the path's 0, 4, 8, 12; the
  // one-point path.
  ASSERT_EQ(p.size(), 1u + 18 + 4 + 1);
  EXPECT_EQ(p[0], (Vec3{-1, -2, -3}));
  EXPECT_EQ(p[1], (Vec3{0, 0, 0}));
  EXPECT_EQ(p[18], (Vec3{10, 2, 10}));
  EXPECT_EQ(p[20], (Vec3{4, 0, 0}));
  EXPECT_EQ(p[23], (Vec3{4, 4, 4}));
  const std::vector<Vec3> q = cameraPositions(d, 3);
  ASSERT_EQ(q.size(), p.size());
  EXPECT_EQ(q[0], p[0]);  // points stay where they are
  int moved = 0;
  for (size_t i = 1; i < 19; ++i) {
    EXPECT_TRUE(q[i].x >= 0 && q[i].x <= 10 && q[i].y >= 0 && q[i].y <= 2 && q[i].z >= 0 && q[i].z <= 10) << i;
    moved += !(q[i] == p[i]);
  }
  EXPECT_GT(moved, 12);
  for (size_t i = 19; i < 23; ++i) EXPECT_TRUE(q[i].y == 0 && q[i].z == 0 && q[i].x >= 0 && q[i].x <= 12) << i;

  d.cameraSpacing = 0.001;
  d.cameraRegions = {{Vec3{0, 0, 0}, Vec3{100, 100, 100}}};
  try {
    cameraPositions(d);
    ADD_FAILURE() << "a declaration of 10^15 positions was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("raise the camera spacing"), std::string::npos) << e.what();
  }
}

TEST(CameraViews, TheDeclarationIsCheckedAndHashed) {
  ReceiverDeclaration d = cameraAtOrigin(CameraVisibility::Faced);
  EXPECT_NO_THROW(checkReceiverDeclaration(d));
  const Hash128 faced = receiverHash(d);
  d.cameraSpacing = 2;
  EXPECT_THROW(checkReceiverDeclaration(d), InputError);  // a spacing is for sampled visibility
  d.cameraVisibility = CameraVisibility::Sampled;
  EXPECT_NO_THROW(checkReceiverDeclaration(d));
  const Hash128 sampled = receiverHash(d);
  EXPECT_NE(sampled, faced);
  d.cameraSpacing = 3;
  EXPECT_NE(receiverHash(d), sampled);
  d.cameraRays = kMaxCameraRays + 1;
  EXPECT_THROW(checkReceiverDeclaration(d), InputError);
  d.cameraRays = 0;
  d.cameraPaths = {{}};
  EXPECT_THROW(checkReceiverDeclaration(d), InputError);  // a path without points
  d.cameraPaths = {{Vec3{0, std::nan(""), 0}}};
  EXPECT_THROW(checkReceiverDeclaration(d), InputError);
  d.cameraPaths.clear();
  d.cameraPoints.clear();
  EXPECT_THROW(checkReceiverDeclaration(d), InputError);  // no place at all
  ReceiverDeclaration surfaces;
  surfaces.kind = ReceiverKind::Surfaces;
  surfaces.cameraPoints = {Vec3{0, 0, 0}};
  EXPECT_THROW(checkReceiverDeclaration(surfaces), InputError);
  // Points change the hash; a declaration with regions only keeps the one it had.
  ReceiverDeclaration a = cameraAtOrigin(CameraVisibility::Faced), b = a;
  b.cameraPoints.push_back({1, 1, 1});
  EXPECT_NE(receiverHash(a), receiverHash(b));
  // Points and regions whose numbers line up still hash apart: every list is counted.
  ReceiverDeclaration points = cameraAtOrigin(CameraVisibility::Faced), regions = points;
  points.cameraPoints = {Vec3{-5, 0, 0}, Vec3{1, 0, 0}, Vec3{1, 1, 1}};
  regions.cameraPoints.clear();
  regions.cameraRegions = {{Vec3{-3, -5, 0}, Vec3{0, -3, 1}}, {Vec3{0, 0, -3}, Vec3{1, 1, 1}}};
  EXPECT_NE(receiverHash(points), receiverHash(regions));
  // A sampled declaration too dense to cast is refused by the check itself.
  ReceiverDeclaration dense = cameraAtOrigin(CameraVisibility::Sampled);
  dense.cameraRegions = {{Vec3{0, 0, 0}, Vec3{1000, 10, 1000}}};
  dense.cameraSpacing = 0.5;
  try {
    checkReceiverDeclaration(dense);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("lower the rays per face (now 64)"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace cpvs
