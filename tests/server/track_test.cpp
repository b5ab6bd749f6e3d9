// Sun tracks through the coordinator, its RPCs and the client library in one process:
// keyframes baked ahead as jobs and published in order; a subscriber receives every
// version, byte-identical to a local bake of its direction, and resumes after a
// disconnect and after a coordinator restart with no gap and no duplicate; keyframes are
// shared between tracks; night keyframes are left out; bad specs are refused with their
// kind and change nothing.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <thread>

#include "cpvs/bake/bake.h"
#include "cpvs/base/error.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/net/convert.h"
#include "cpvs/net/model_convert.h"
#include "cpvs/scene/import.h"
#include "cpvs/scene/obj_writer.h"
#include "cpvs/scene/source.h"
#include "cpvs/runtime/runtime.h"
#include "cpvs/sun/sun_position.h"
#include "farm_testing.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

using testing::InProcessFarm;
using testing::TempDir;
namespace pb = ::cpvs::v1;

Vec3 quantized(const Vec3& d) {
  const Vec3 u = d / length(d);
  auto q = [](double v) { return std::round(v * 1e9) / 1e9; };
  return {q(u.x), q(u.y), q(u.z)};
}

// The local bake of one keyframe's direction, as the farm's artifact is written.
std::vector<uint8_t> localBytes(const Scene& scene, const Vec3& direction) {
  return encodeCpvs(testing::localArtifact(scene, makeGrid(scene, LightFrame::fromDirection(direction), 7), {}), true);
}

net::TrackSpec directionTrack(const std::string& sceneHash, const std::vector<Vec3>& dirs) {
  net::TrackSpec spec;
  spec.sceneHash = sceneHash;
  spec.resolution = "128";
  spec.name = "three suns";
  spec.keyframesAhead = 1;
  spec.path = dirs;
  return spec;
}

struct Received {
  std::vector<net::TrackVersion> versions;
  std::vector<std::vector<uint8_t>> bytes;
};

// Subscribes after `after` until the track ends, or until `most` versions (0: no limit).
Received follow(client::FarmClient& c, const std::string& track, uint64_t after = 0, size_t most = 0) {
  Received got;
  c.subscribe(track, after, [&](const net::TrackVersion& v, const std::vector<uint8_t>& b) {
    got.versions.push_back(v);
    got.bytes.push_back(b);
    return most == 0 || got.versions.size() < most;
  });
  return got;
}

TEST(Tracks, VersionsArriveInOrderAndResumeAcrossDisconnectsAndRestarts) {
  TempDir dir("cpvs_track_test");
  const std::string obj = dir / "city.obj";
  writeObj(obj, openScene("city:2:5"));
  const Scene scene = loadScene(obj);
  const std::vector<Vec3> dirs{{0.3, -1, 0.2}, {0.2, -1, 0.3}, {-0.1, -1, 0.4}};
  std::string trackId;
  {
    // A coordinator with no worker: the track is created and its first keyframe waits.
    auto farm = std::make_unique<InProcessFarm>(dir / "data");
    const std::string hash = farm->client.uploadScene(obj).sceneHash;
    const net::TrackStatus created = farm->client.createTrack("track-1", directionTrack(hash, dirs));
    trackId = created.trackId;
    EXPECT_EQ(created.state, net::TrackState::Active);
    EXPECT_EQ(created.keyframesTotal, 3u);
    EXPECT_EQ(farm->client.createTrack("track-1", directionTrack(hash, dirs)).trackId, trackId);  // a retry
    net::TrackSpec other = directionTrack(hash, dirs);
    other.name = "another";
    EXPECT_THROW(farm->client.createTrack("track-1", other), client::FarmCallError);
    const auto jobs = farm->client.list(false);
    ASSERT_EQ(jobs.size(), 1u);  // one keyframe ahead
    EXPECT_LT(jobs[0].spec.priority, 0);  // below interactive bakes
    farm->server.shutdown(1);
  }
  // Restarted on the same folder, with a worker: the track carries on.
  InProcessFarm farm(dir / "data");
  worker::WorkerConfig wc = testing::workerConfig(farm.connection(), dir / "cache");
  wc.threads = 2;
  worker::TileWorker tileWorker(wc);
  std::thread workerThread([&] { tileWorker.run(); });

  // A subscriber that goes away after the first version...
  Received got;
  auto keep = [&](const net::TrackVersion& v, const std::vector<uint8_t>& b) {
    got.versions.push_back(v);
    got.bytes.push_back(b);
    return got.versions.size() != 1;
  };
  EXPECT_EQ(farm.client.subscribe(trackId, 0, keep), 1u);
  // ...and comes back with its token: exactly the rest, then the stream ends with the track.
  EXPECT_EQ(farm.client.subscribe(trackId, 1, keep), 3u);
  ASSERT_EQ(got.versions.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(got.versions[i].sequence, i + 1);
    EXPECT_EQ(got.versions[i].keyframe, i);
    EXPECT_EQ(got.bytes[i], localBytes(scene, quantized(dirs[i]))) << "keyframe " << i;
  }
  const net::TrackStatus done = farm.client.listTracks(true).at(0);
  EXPECT_EQ(done.state, net::TrackState::Finished);
  EXPECT_EQ(done.keyframesPublished, 3u);
  EXPECT_EQ(done.latestSequence, 3u);

  // A second track over the same suns bakes nothing new: its keyframes are the same jobs.
  const size_t jobsBefore = farm.client.list(true).size();
  net::TrackSpec again = directionTrack(farm.client.listTracks(true).at(0).spec.sceneHash, dirs);
  again.name = "again";
  const std::string second = farm.client.createTrack("track-2", again).trackId;
  const Received twice = follow(farm.client, second);
  ASSERT_EQ(twice.versions.size(), 3u);
  EXPECT_EQ(twice.versions[2].jobId, got.versions[2].jobId);
  EXPECT_EQ(twice.bytes, got.bytes);
  EXPECT_EQ(farm.client.list(true).size(), jobsBefore);

  // Retention: a track that keeps two versions offers a late subscriber the newest two.
  net::TrackSpec kept = directionTrack(farm.client.listTracks(true).at(0).spec.sceneHash, dirs);
  kept.name = "kept";
  kept.keepVersions = 2;
  const std::string third = farm.client.createTrack("track-3", kept).trackId;
  for (int i = 0; i < 300 && farm.client.listTracks(true).back().state != net::TrackState::Finished; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const Received late = follow(farm.client, third);
  ASSERT_EQ(late.versions.size(), 2u);
  EXPECT_EQ(late.versions[0].sequence, 2u);
  EXPECT_EQ(late.versions[1].sequence, 3u);

  // Tokens from the future and unknown tracks are refused.
  try {
    farm.client.subscribe(trackId, 9, keep);
    ADD_FAILURE() << "a token from the future was accepted";
  } catch (const client::FarmCallError& e) {
    EXPECT_EQ(e.kind(), net::ErrorKind::OutOfRange) << e.what();
  }
  try {
    farm.client.subscribe("t-none", 0, keep);
    ADD_FAILURE() << "an unknown track was followed";
  } catch (const client::FarmCallError& e) {
    EXPECT_EQ(e.kind(), net::ErrorKind::NotFound) << e.what();
  }
  tileWorker.stop();
  workerThread.join();
}

// A place through an evening: keyframes every two hours from 16:00 to 22:00 in Golden
// (UTC-6 in June); the last is after sunset and is left out, never baked.
TEST(Tracks, APlaceThroughTimeLeavesOutTheNight) {
  TempDir dir("cpvs_track_place_test");
  InProcessFarm farm(dir / "data");
  const std::string obj = dir / "city.obj";
  writeObj(obj, openScene("city:2:5"));
  const Scene scene = loadScene(obj);
  net::TrackSpec spec;
  spec.sceneHash = farm.client.uploadScene(obj).sceneHash;
  spec.resolution = "128";
  spec.keyframesAhead = 4;
  net::PlacePath p;
  p.latitudeDeg = 39.742476;
  p.longitudeDeg = -105.1786;
  p.startUtc = "2024-06-21T16:00:00-06:00";
  p.endUtc = "2024-06-21T22:00:00-06:00";
  p.stepSeconds = 7200;
  spec.path = p;
  worker::WorkerConfig wc = testing::workerConfig(farm.connection(), dir / "cache");
  worker::TileWorker tileWorker(wc);
  std::thread workerThread([&] { tileWorker.run(); });
  const std::string id = farm.client.createTrack("evening", spec).trackId;
  const Received got = follow(farm.client, id);
  tileWorker.stop();
  workerThread.join();
  ASSERT_EQ(got.versions.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    const int64_t instant = unixMillis(parseUtcInstant("2024-06-21T16:00:00-06:00")) + int64_t(i) * 7200000;
    EXPECT_EQ(got.versions[i].instantUnixMs, instant);
    const SunPosition sun = sunPosition(utcFromUnixMillis(instant), {39.742476, -105.1786, 0});
    EXPECT_FALSE(sun.night);
    EXPECT_EQ(got.bytes[i], localBytes(scene, quantized(sun.direction))) << "keyframe " << i;
  }
  EXPECT_TRUE(sunPosition(parseUtcInstant("2024-06-21T22:00:00-06:00"), {39.742476, -105.1786, 0}).night);
  EXPECT_EQ(farm.client.listTracks(true).at(0).state, net::TrackState::Finished);

  // The runtime follows the track: a lookup at a keyframe's instant answers that
  // keyframe; between two, their crossfade; before the first and after the last, those.
  runtime::TrackFollower follower({farm.server.address(), "", ""}, id, runtime::Backend::Auto);
  ASSERT_EQ(follower.waitForVersions(3, 60), 3u) << follower.lastError();
  EXPECT_EQ(follower.lastSequence(), 3u);
  ASSERT_EQ(follower.heldInstants().size(), 3u);
  std::vector<Vec3> points, normals;
  for (int i = 0; i < 400; ++i) {
    points.push_back({double(i % 20) * 2.2 - 2, 0.3 + (i / 20) % 3, double(i / 20) * 2.1 - 2});
    normals.push_back({0, 1, 0});
  }
  std::vector<std::vector<float>> each(3);
  for (size_t k = 0; k < 3; ++k) {
    auto art = runtime::ShadowArtifact::fromBytes(got.bytes[k], "version");
    each[k].resize(points.size());
    for (size_t i = 0; i < points.size(); ++i) each[k][i] = art->cpu().filtered(points[i], normals[i], 5);
  }
  EXPECT_NE(each[0], each[2]) << "the sun moved: the shadows must too";
  const int64_t t0 = got.versions[0].instantUnixMs, t1 = got.versions[1].instantUnixMs;
  std::vector<float> vis;
  for (size_t k = 0; k < 3; ++k) {
    follower.visibility(points, normals, 5, got.versions[k].instantUnixMs, vis);
    EXPECT_EQ(vis, each[k]) << "at keyframe " << k;
  }
  follower.visibility(points, normals, 5, t0 + (t1 - t0) / 4, vis);
  for (size_t i = 0; i < points.size(); ++i) ASSERT_NEAR(vis[i], 0.75f * each[0][i] + 0.25f * each[1][i], 1e-6) << i;
  follower.visibility(points, normals, 5, t0 - 3600000, vis);
  EXPECT_EQ(vis, each[0]);
  follower.visibility(points, normals, 5, got.versions[2].instantUnixMs + 3600000, vis);
  EXPECT_EQ(vis, each[2]);
}

/// A game clock over the equator from the March equinox at 09:00 UTC: `rate` game seconds
/// per real second, a keyframe every `step` game seconds, 64^3, the city uploaded to `farm`.
net::TrackSpec clockTrack(InProcessFarm& farm, const TempDir& dir, double step, double rate, uint32_t ahead) {
  const std::string obj = dir / "city.obj";
  writeObj(obj, openScene("city:1:2"));
  net::TrackSpec spec;
  spec.sceneHash = farm.client.uploadScene(obj).sceneHash;
  spec.resolution = "64";
  spec.keyframesAhead = ahead;
  net::PlacePath p;
  p.startUtc = "2024-03-20T09:00:00Z";
  p.stepSeconds = step;
  spec.path = net::ClockPath{p, rate};
  return spec;
}

// A game clock an hour of game time per real second, keyframes every half game hour:
// the track keeps baking the keyframes around its clock; a subscriber gets them in
// order, each half an hour of game time after the one before, never ending by itself.
TEST(Tracks, AClockKeepsBakingAheadOfItsTime) {
  TempDir dir("cpvs_track_clock_test");
  InProcessFarm farm(dir / "data");
  const net::TrackSpec spec = clockTrack(farm, dir, 1800, 3600, 2);
  worker::WorkerConfig wc = testing::workerConfig(farm.connection(), dir / "cache");
  worker::TileWorker tileWorker(wc);
  std::thread workerThread([&] { tileWorker.run(); });
  const net::TrackStatus created = farm.client.createTrack("clock", spec);
  EXPECT_EQ(created.keyframesTotal, 0u);  // unbounded
  const Received got = follow(farm.client, created.trackId, 0, 4);
  ASSERT_EQ(got.versions.size(), 4u);
  for (size_t i = 1; i < got.versions.size(); ++i) {
    EXPECT_EQ(got.versions[i].sequence, got.versions[i - 1].sequence + 1);
    EXPECT_GT(got.versions[i].keyframe, got.versions[i - 1].keyframe);
    EXPECT_EQ(got.versions[i].instantUnixMs - got.versions[i - 1].instantUnixMs,
              int64_t(got.versions[i].keyframe - got.versions[i - 1].keyframe) * 1800000);
  }
  EXPECT_EQ(farm.client.listTracks(false).at(0).state, net::TrackState::Active);  // a clock does not end
  EXPECT_EQ(farm.client.cancelTrack(created.trackId).state, net::TrackState::Cancelled);
  tileWorker.stop();
  workerThread.join();
}

// A track that cannot advance (here its stored path names no instant, and its pending
// keyframe was cancelled, so every pass wants a keyframe it cannot make) is tried again
// backing off: a quarter second, then a half, one, two..., not on every pass.
TEST(Tracks, ATrackThatCannotAdvanceBacksOff) {
  TempDir dir("cpvs_track_backoff_test");
  InProcessFarm farm(dir / "data");
  const net::TrackSpec spec = clockTrack(farm, dir, 1800, 1, 1);
  const net::TrackStatus created = farm.client.createTrack("backing-off", spec);
  // The stored path broken behind the coordinator's back, as a damaged store would be.
  pb::TrackSpec stored = net::toProto(spec);
  stored.mutable_clock()->mutable_place()->set_start_utc("not an instant");
  const std::string broken = stored.SerializeAsString();
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir / "data/farm.sqlite").c_str(), &db), SQLITE_OK);
  sqlite3_busy_timeout(db, 5000);
  sqlite3_stmt* update = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db, "UPDATE tracks SET spec = ? WHERE id = ?", -1, &update, nullptr), SQLITE_OK);
  sqlite3_bind_blob(update, 1, broken.data(), int(broken.size()), SQLITE_TRANSIENT);
  sqlite3_bind_text(update, 2, created.trackId.c_str(), -1, SQLITE_TRANSIENT);
  ASSERT_EQ(sqlite3_step(update), SQLITE_DONE) << sqlite3_errmsg(db);
  sqlite3_finalize(update);
  sqlite3_close(db);
  for (const client::JobStatus& j : farm.client.list(false)) farm.client.cancel(j.jobId);
  server::TrackService& tracks = farm.coordinator.tracks();
  const auto start = std::chrono::steady_clock::now();
  while (tracks.failedPasses() == 0 && std::chrono::steady_clock::now() - start < std::chrono::seconds(10))
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ASSERT_GT(tracks.failedPasses(), 0u) << "the track never failed";
  const uint64_t first = tracks.failedPasses();
  std::this_thread::sleep_for(std::chrono::seconds(3));
  // Retries 0.25, 0.5, 1 and 2 s after each failure: at most 4 more in 3 s, where a pass
  // every 250 ms would have failed 12 times.
  EXPECT_LE(tracks.failedPasses() - first, 4u);
  EXPECT_GE(tracks.failedPasses() - first, 2u);
}

// Bad specs: each refused with its kind and message, no track and no job created.
TEST(Tracks, BadSpecsAreRefusedAndChangeNothing) {
  TempDir dir("cpvs_track_bad_test");
  InProcessFarm farm(dir / "data");
  const std::string obj = dir / "city.obj";
  writeObj(obj, openScene("city:1:1"));
  const std::string hash = farm.client.uploadScene(obj).sceneHash;
  auto place = [&](const char* start, const char* end, double step, double lat) {
    net::TrackSpec s;
    s.sceneHash = hash;
    s.resolution = "128";
    net::PlacePath p;
    p.latitudeDeg = lat;
    p.startUtc = start;
    p.endUtc = end;
    p.stepSeconds = step;
    s.path = p;
    return s;
  };
  struct Bad {
    net::TrackSpec spec;
    const char* message;
  };
  net::TrackSpec noPath;
  noPath.sceneHash = hash;
  noPath.resolution = "128";
  net::TrackSpec unknownScene = directionTrack(std::string(32, 'a'), {{0, -1, 0}});
  net::TrackSpec zeroDirection = directionTrack(hash, {{0, 0, 0}});
  const std::vector<Bad> cases{
      {place("2024-06-21T12:00Z", "2024-06-21T10:00Z", 600, 40), "is before start_utc"},
      {place("2024-06-21T12:00Z", "2024-06-21T13:00Z", 0, 40), "step_seconds must be positive"},
      {place("2024-06-21T00:00Z", "2024-06-22T00:00Z", 1, 40), "at most 10000"},
      {place("2024-06-21T12:00Z", "2024-06-21T13:00Z", 600, 91), "latitude"},
      {place("2024-12-21T00:00Z", "2024-12-22T00:00Z", 3600, 85), "below the horizon at every keyframe"},
      {place("2024-06-21T12:00", "2024-06-21T13:00Z", 600, 40), "expected ISO 8601"},
      {noPath, "no sun path"},
      {zeroDirection, "zero or not finite"},
      {unknownScene, ""},
  };
  int n = 0;
  for (const Bad& b : cases) {
    try {
      farm.client.createTrack("bad-" + std::to_string(n++), b.spec);
      ADD_FAILURE() << "accepted: " << b.message;
    } catch (const client::FarmCallError& e) {
      EXPECT_TRUE(e.callerCanFix()) << e.what();
      EXPECT_NE(std::string(e.what()).find(b.message), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(farm.client.listTracks(true).empty());
  EXPECT_TRUE(farm.client.list(true).empty());
  try {
    farm.client.cancelTrack("t-none");
    ADD_FAILURE();
  } catch (const client::FarmCallError& e) {
    EXPECT_EQ(e.kind(), net::ErrorKind::NotFound);
  }
}

}  // namespace
}  // namespace cpvs
