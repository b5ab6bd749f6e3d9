// Sun tracks: a scene, options, a resolution and a sun path (a place through a span of
// time, a list of directions, or a game clock). The service keeps the next keyframes of
// every active track submitted as bake jobs at a priority below interactive bakes (whose
// tiles are leased first, so they preempt between tiles), publishes each finished
// keyframe, in order, as the track's next version, and keeps the newest versions for
// subscribers. A keyframe is a job whose request id is named by its content (scene,
// resolution, options, quantized direction), so a keyframe baked before, by this track
// or another, is the same job and is not baked again.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "coordinator/change_feed.h"
#include "coordinator/job_service.h"
#include "cpvs/base/vec3.h"
#include "cpvs/v1/farm.pb.h"
#include "store/farm_store.h"

namespace cpvs::server {

struct TrackLimits {
  uint64_t maxKeyframes = 10000;  // of a bounded track
  uint32_t maxAhead = 16;
  uint32_t maxKeep = 1024;
};

/// How the request id of every keyframe job starts (clients may not use it).
constexpr const char* kKeyframeRequestPrefix = "keyframe-";

/// Priority of keyframe jobs: below every interactive bake's default (0).
constexpr int kKeyframePriority = -100;

class TrackService {
 public:
  TrackService(FarmStore& store, JobService& jobs, ChangeFeed& feed, TrackLimits limits = {});
  ~TrackService() { stop(); }

  /// Validates the spec (a path with keyframes above the horizon, within the limits) and
  /// submits its first keyframes; idempotent by request id like SubmitBake.
  /// Tracks and their keyframe jobs are the creating client's (`access`, R28).
  pb::TrackStatus create(const pb::CreateTrackRequest& request, const Access& access = Access::all());
  pb::TrackStatus status(const std::string& trackId, const Access& access = Access::all());
  std::vector<pb::TrackStatus> list(bool includeEnded, const Access& access = Access::all());
  /// Ends the track; its pending keyframe jobs that no other track waits for are cancelled.
  pb::TrackStatus cancel(const std::string& trackId, const Access& access = Access::all());
  /// The first kept version after `sequence`; nullopt when there is none yet.
  std::optional<VersionRecord> versionAfter(const std::string& trackId, uint64_t sequence);

  /// One pass over the active tracks: publishes finished keyframes in order, skips failed
  /// ones, submits the next ones. The service's thread runs it on every job change and at
  /// least every 250 ms; tests may call it directly.
  void tick();
  void start();
  /// As of the last pass: tracks active, and the most keyframes a clock track's clock has
  /// reached that are not published yet (its subscribers show an older sun meanwhile).
  uint64_t activeTracks() const { return activeTracks_; }
  uint64_t keyframeLag() const { return keyframeLag_; }
  /// Passes over a track that failed (its scene gone, the store failing): each one waits
  /// twice as long as the one before for its next (a quarter second to a minute).
  uint64_t failedPasses() const { return failedPasses_; }
  void stop();

 private:
  pb::TrackStatus toStatus(const TrackRecord& t) const;
  /// One track's pass; returns its keyframe lag (0 unless it follows a clock).
  uint64_t advance(const TrackRecord& t);
  /// Submits keyframe `k`'s job; returns its id.
  std::string submitKeyframe(const pb::TrackSpec& spec, const Vec3& direction, const std::string& owner);
  /// The track, when `access` may see it: NotFound, PermissionDenied otherwise.
  TrackRecord visibleTrack(const std::string& trackId, const Access& access);

  FarmStore& store_;
  JobService& jobs_;
  ChangeFeed& feed_;
  TrackLimits limits_;
  std::mutex tickMutex_;  // one pass at a time (the thread's, a test's, create's)
  std::thread thread_;
  bool stopping_ = false;
  std::atomic<uint64_t> activeTracks_ = 0, keyframeLag_ = 0, failedPasses_ = 0;
  struct Failing {
    int failures = 0;
    std::chrono::steady_clock::time_point retryAt{};
  };
  std::map<std::string, Failing> failing_;  // by track id, under tickMutex_
};

}  // namespace cpvs::server
