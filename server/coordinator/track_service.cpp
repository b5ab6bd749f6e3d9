#include "coordinator/track_service.h"

#include <spdlog/spdlog.h>

#include <cmath>

#include "coordinator/clock.h"
#include "coordinator/stored_spec.h"
#include "cpvs/base/error.h"
#include "cpvs/base/hash.h"
#include "cpvs/net/convert.h"
#include "cpvs/net/model_convert.h"
#include "cpvs/net/error_kind.h"
#include "cpvs/sun/sun_position.h"

namespace cpvs::server {

using net::ErrorKind;
using net::FarmError;

namespace {

constexpr int kActive = pb::TRACK_ACTIVE, kFinished = pb::TRACK_FINISHED, kCancelled = pb::TRACK_CANCELLED;

// One keyframe of a path: its instant (Unix ms; 0 for direction lists) and the sunlight's
// direction, or night.
struct Keyframe {
  int64_t instantMs = 0;
  Vec3 direction;
  bool night = false;
};

const pb::PlacePath& placeOf(const pb::TrackSpec& s) { return s.has_clock() ? s.clock().place() : s.place(); }

SceneAxes axesOf(const pb::PlacePath& p) {
  SceneAxes axes;
  if (!p.up().empty()) axes.up = SceneAxes::parseAxis(p.up(), "up");
  if (!p.north().empty()) axes.north = SceneAxes::parseAxis(p.north(), "north");
  axes.check();
  return axes;
}

Keyframe keyframeOf(const pb::TrackSpec& spec, uint64_t i) {
  Keyframe k;
  if (spec.has_directions()) {
    const pb::Vec3& d = spec.directions().directions(int(i));
    const Vec3 v{d.x(), d.y(), d.z()};
    const double n = length(v);
    k.direction = v / n;
    return k;
  }
  const pb::PlacePath& p = placeOf(spec);
  k.instantMs = unixMillis(parseUtcInstant(p.start_utc(), "start_utc")) + int64_t(std::llround(double(i) * p.step_seconds() * 1000));
  const SunPosition sun = sunPosition(utcFromUnixMillis(k.instantMs), {p.latitude_deg(), p.longitude_deg(), p.height_m()},
                                      {}, std::nullopt, axesOf(p));
  k.night = sun.night;
  k.direction = sun.direction;
  return k;
}

// The direction as the job names it: rounded to 1e-9 (0.0002") so that the same sun from
// two tracks, or two runs, is the same job.
Vec3 quantized(const Vec3& d) {
  auto q = [](double v) { return std::round(v * 1e9) / 1e9; };
  return {q(d.x), q(d.y), q(d.z)};
}

// Keyframes of a bounded path (0 for a clock), after checking the path.
uint64_t keyframeCount(const pb::TrackSpec& spec, const TrackLimits& limits) {
  if (spec.has_directions()) {
    if (spec.directions().directions_size() == 0) throw InputError("the direction list is empty");
    for (const auto& d : spec.directions().directions()) {
      const double n = std::sqrt(d.x() * d.x() + d.y() * d.y() + d.z() * d.z());
      if (!(n > 0) || !std::isfinite(n)) throw InputError("a direction of the list is zero or not finite");
    }
    if (uint64_t(spec.directions().directions_size()) > limits.maxKeyframes)
      throw InputError("more than " + std::to_string(limits.maxKeyframes) + " directions");
    return uint64_t(spec.directions().directions_size());
  }
  if (!spec.has_place() && !spec.has_clock()) throw InputError("the track has no sun path (place, directions or clock)");
  const pb::PlacePath& p = placeOf(spec);
  if (!(p.step_seconds() > 0) || !std::isfinite(p.step_seconds())) throw InputError("step_seconds must be positive");
  axesOf(p);
  const int64_t start = unixMillis(parseUtcInstant(p.start_utc(), "start_utc"));
  // The place itself (latitude and longitude in range) through the first keyframe.
  sunPosition(utcFromUnixMillis(start), {p.latitude_deg(), p.longitude_deg(), p.height_m()});
  if (spec.has_clock()) {
    if (!(spec.clock().rate() > 0) || !std::isfinite(spec.clock().rate())) throw InputError("the clock's rate must be positive");
    if (!p.end_utc().empty()) throw InputError("a clock has no end_utc");
    return 0;
  }
  const int64_t end = unixMillis(parseUtcInstant(p.end_utc(), "end_utc"));
  if (end < start) throw InputError("end_utc " + p.end_utc() + " is before start_utc " + p.start_utc());
  const double count = std::floor(double(end - start) / (p.step_seconds() * 1000)) + 1;
  if (count > double(limits.maxKeyframes))
    throw InputError("the path makes " + std::to_string(uint64_t(count)) + " keyframes; a track has at most " +
                     std::to_string(limits.maxKeyframes) + " (a longer step, or a shorter span)");
  return uint64_t(count);
}

}  // namespace

TrackService::TrackService(FarmStore& store, JobService& jobs, ChangeFeed& feed, TrackLimits limits)
    : store_(store), jobs_(jobs), feed_(feed), limits_(limits) {}

pb::TrackStatus TrackService::toStatus(const TrackRecord& t) const {
  pb::TrackStatus s;
  s.set_track_id(t.id);
  s.set_request_id(t.requestId);
  s.set_state(pb::TrackState(t.state));
  try {
    *s.mutable_spec() = trackSpecOf(t);
  } catch (const FormatError& e) {
    spdlog::error("{}", e.what());  // the status still tells the track's state
  }
  s.set_keyframes_total(t.keyframesTotal);
  s.set_keyframes_published(t.published);
  s.set_keyframes_skipped(t.skipped);
  s.set_latest_sequence(t.latestSequence);
  s.set_error(t.error);
  s.set_created_unix_ms(t.createdMs);
  return s;
}

std::string TrackService::submitKeyframe(const pb::TrackSpec& spec, const Vec3& direction, const std::string& owner) {
  net::BakeSpec b;
  b.sceneHash = spec.scene_hash();
  b.sun = direction;
  b.resolution = spec.resolution();
  b.options = net::modelOf(spec.options());
  b.priority = kKeyframePriority;
  b.name = "keyframe";
  // Named by what it bakes: the same keyframe from any of one owner's tracks is the same
  // job (owners share no job, R28).
  const std::string content = net::toProto(b).SerializeAsString() + (owner.empty() ? "" : "\n" + owner);
  const std::string requestId = kKeyframeRequestPrefix + contentHash(content.data(), content.size()).hex();
  return jobs_.submit(requestId, b, owner.empty() ? Access::all() : Access::of(owner)).job_id();  // '': no tokens
}

pb::TrackStatus TrackService::create(const pb::CreateTrackRequest& request, const Access& access) {
  const pb::TrackSpec& spec = request.spec();
  if (request.request_id().empty() || request.request_id().size() > 128)
    throw FarmError(ErrorKind::InvalidArgument, "request_id must be 1..128 characters");
  if (auto known = store_.trackByRequest(request.request_id())) {
    if (!access.sees(known->owner))
      throw FarmError(ErrorKind::AlreadyExists, "request_id " + request.request_id() + " is taken; use another");
    if (!sameMessage(trackSpecOf(*known), spec))
      throw FarmError(ErrorKind::AlreadyExists, "request_id " + request.request_id() + " names another track");
    return toStatus(*known);
  }
  if (spec.name().size() > 256) throw FarmError(ErrorKind::InvalidArgument, "name is longer than 256 characters");
  if (spec.keyframes_ahead() > limits_.maxAhead)
    throw FarmError(ErrorKind::InvalidArgument, "keyframes_ahead is above " + std::to_string(limits_.maxAhead));
  if (spec.keep_versions() > limits_.maxKeep)
    throw FarmError(ErrorKind::InvalidArgument, "keep_versions is above " + std::to_string(limits_.maxKeep));
  TrackRecord t;
  try {
    t.keyframesTotal = keyframeCount(spec, limits_);
    // A path whose sun never rises gives nothing to bake: refused, not a track of nights.
    const uint64_t look = t.keyframesTotal ? t.keyframesTotal
                                           : uint64_t(std::ceil(86400.0 / placeOf(spec).step_seconds())) + 1;
    uint64_t first = look;
    for (uint64_t i = 0; i < std::min<uint64_t>(look, limits_.maxKeyframes) && first == look; ++i)
      if (!keyframeOf(spec, i).night) first = i;
    if (first == look)
      throw InputError(spec.has_clock() ? "the sun stays below the horizon through the clock's first day (polar night)"
                                        : "the sun is below the horizon at every keyframe of the path (night)");
    t.nextKeyframe = spec.has_clock() ? 0 : first;
  } catch (const InputError& e) {
    throw FarmError(ErrorKind::InvalidArgument, e.what());
  }
  // The first keyframe's job checks the scene, the resolution and the options.
  const Keyframe k0 = keyframeOf(spec, t.nextKeyframe);
  KeyframeRecord k;
  if (!k0.night) {
    k.keyframe = t.nextKeyframe;
    k.instantMs = k0.instantMs;
    k.direction = quantized(k0.direction);
    k.jobId = submitKeyframe(spec, k.direction, access.owner);
  }
  t.id = randomId("t");
  t.requestId = request.request_id();
  t.owner = access.owner;
  storeSpec(t, spec);
  t.state = kActive;
  t.createdMs = nowMs();
  {
    // No pass of the track thread between the track and its first keyframe: it would
    // submit that keyframe again. (After a crash between the two, a pass submits it: the
    // same request id, so the same job.)
    std::lock_guard lock(tickMutex_);
    store_.createTrack(t);
    if (!k0.night) {
      k.trackId = t.id;
      store_.addKeyframe(k);
    }
  }
  spdlog::info("track {} created: {} keyframes{}", t.id, t.keyframesTotal ? std::to_string(t.keyframesTotal) : "unbounded",
               spec.name().empty() ? "" : " (" + spec.name() + ")");
  feed_.notify();
  tick();
  return status(t.id);
}

TrackRecord TrackService::visibleTrack(const std::string& trackId, const Access& access) {
  auto t = store_.track(trackId);
  if (!t) throw FarmError(ErrorKind::NotFound, "no track " + trackId);
  if (!access.sees(t->owner)) throw FarmError(ErrorKind::PermissionDenied, "track " + trackId + " is another client's");
  return std::move(*t);
}

pb::TrackStatus TrackService::status(const std::string& trackId, const Access& access) {
  return toStatus(visibleTrack(trackId, access));
}

std::vector<pb::TrackStatus> TrackService::list(bool includeEnded, const Access& access) {
  std::vector<pb::TrackStatus> out;
  for (const TrackRecord& t : store_.tracks(includeEnded))
    if (access.sees(t.owner)) out.push_back(toStatus(t));
  return out;
}

pb::TrackStatus TrackService::cancel(const std::string& trackId, const Access& access) {
  std::lock_guard lock(tickMutex_);
  if (visibleTrack(trackId, access).state == kActive) {
    store_.setTrackState(trackId, kCancelled, "cancelled");
    for (const KeyframeRecord& k : store_.pendingKeyframes(trackId))
      if (!store_.jobWantedByAnotherTrack(k.jobId, trackId)) jobs_.cancel(k.jobId);
    spdlog::info("track {} cancelled", trackId);
    feed_.notify();
  }
  return status(trackId);
}

std::optional<VersionRecord> TrackService::versionAfter(const std::string& trackId, uint64_t sequence) {
  return store_.versionAfter(trackId, sequence);
}

uint64_t TrackService::advance(const TrackRecord& t) {
  const pb::TrackSpec spec = trackSpecOf(t);
  const uint64_t ahead = spec.keyframes_ahead() ? spec.keyframes_ahead() : 2;
  const uint64_t keep = spec.keep_versions() ? spec.keep_versions() : 16;
  bool changed = false;
  // Publish in keyframe order: a keyframe waits for the ones before it.
  std::vector<KeyframeRecord> pending = store_.pendingKeyframes(t.id);
  size_t published = 0;
  for (const KeyframeRecord& k : pending) {
    pb::JobStatus job;
    try {
      job = jobs_.status(k.jobId);
    } catch (const FarmError& e) {
      if (e.kind != ErrorKind::NotFound) throw;
      // A finished job reused from long ago and pruned before this track recorded it:
      // skipped, not a track stalled behind it for good.
      store_.skipKeyframe(t.id, k.keyframe);
      spdlog::warn("track {}: keyframe {} skipped: its job {} is no longer held", t.id, k.keyframe, k.jobId);
      ++published;
      changed = true;
      continue;
    }
    if (job.state() == pb::JOB_DONE) {
      std::string checksum;
      jobs_.artifactPath(k.jobId, &checksum);
      const VersionRecord v = store_.publishKeyframe(t.id, k.keyframe, checksum, job.file_bytes(), keep, nowMs());
      spdlog::info("track {}: keyframe {} published as version {}", t.id, k.keyframe, v.sequence);
    } else if (job.state() == pb::JOB_FAILED || job.state() == pb::JOB_CANCELLED) {
      store_.skipKeyframe(t.id, k.keyframe);
      spdlog::warn("track {}: keyframe {} skipped: its job {} ended {}", t.id, k.keyframe, k.jobId,
                   job.error().empty() ? "cancelled" : job.error());
    } else {
      break;
    }
    ++published;
    changed = true;
  }
  uint64_t inFlight = pending.size() - published;
  uint64_t next = t.nextKeyframe;
  // A clock's keyframes are those from the one the clock is in up to `ahead` after it.
  std::optional<uint64_t> clockNow;
  if (spec.has_clock()) {
    const pb::PlacePath& p = spec.clock().place();
    const double gameSeconds = double(nowMs() - t.createdMs) / 1000.0 * spec.clock().rate();
    clockNow = uint64_t(std::floor(gameSeconds / p.step_seconds()));
    if (next < *clockNow) {
      next = *clockNow;  // keyframes the clock has passed are of no use to anyone
      store_.advanceNextKeyframe(t.id, next);
    }
  }
  while (inFlight < ahead && (t.keyframesTotal == 0 || next < t.keyframesTotal) && (!clockNow || next <= *clockNow + ahead)) {
    const Keyframe k = keyframeOf(spec, next);
    if (k.night) {
      store_.advanceNextKeyframe(t.id, ++next);
      continue;
    }
    KeyframeRecord r;
    r.trackId = t.id;
    r.keyframe = next;
    r.instantMs = k.instantMs;
    r.direction = quantized(k.direction);
    try {
      r.jobId = submitKeyframe(spec, r.direction, t.owner);
    } catch (const FarmError& e) {
      // No room for another job now (the farm's quota): try again on the next pass.
      if (e.kind == ErrorKind::ResourceExhausted) break;
      throw;
    }
    store_.addKeyframe(r);
    ++next;
    ++inFlight;
    changed = true;
  }
  if (t.keyframesTotal != 0 && next >= t.keyframesTotal && inFlight == 0) {
    store_.setTrackState(t.id, kFinished, "");
    spdlog::info("track {} finished", t.id);
    changed = true;
  }
  if (changed) feed_.notify();
  uint64_t lag = 0;
  if (clockNow)
    for (size_t i = published; i < pending.size(); ++i) lag += pending[i].keyframe <= *clockNow;
  return lag;
}

void TrackService::tick() {
  std::lock_guard lock(tickMutex_);
  uint64_t active = 0, lag = 0;
  const auto now = std::chrono::steady_clock::now();
  for (const TrackRecord& t : store_.tracks(false)) {
    ++active;
    auto failing = failing_.find(t.id);
    if (failing != failing_.end() && now < failing->second.retryAt) continue;
    try {
      lag = std::max(lag, advance(t));
      if (failing != failing_.end()) {
        spdlog::info("track {} advances again after {} failed pass(es)", t.id, failing->second.failures);
        failing_.erase(failing);
      }
    } catch (const std::exception& e) {
      // A track that cannot advance now (its scene gone, the store failing) is retried
      // later, backing off, and does not stop the others.
      Failing& f = failing_[t.id];
      ++f.failures;
      ++failedPasses_;
      const double wait = std::min(60.0, 0.25 * double(uint64_t(1) << std::min(f.failures - 1, 8)));
      f.retryAt = now + std::chrono::milliseconds(int64_t(wait * 1000));
      spdlog::error("track {}: {} (trying again in {} s)", t.id, e.what(), wait);
    }
  }
  // Tracks that ended are forgotten.
  if (failing_.size() > active)
    for (auto it = failing_.begin(); it != failing_.end();) {
      auto track = store_.track(it->first);
      it = (!track || track->state != kActive) ? failing_.erase(it) : std::next(it);
    }
  activeTracks_ = active;
  keyframeLag_ = lag;
}

void TrackService::start() {
  thread_ = std::thread([this] {
    uint64_t seen = 0;
    while (true) {
      seen = feed_.waitForChange(seen, 250);
      {
        std::lock_guard lock(tickMutex_);
        if (stopping_) return;
      }
      try {
        tick();
      } catch (const std::exception& e) {
        spdlog::error("tracks: {}", e.what());  // the store could not list them: next pass
      }
    }
  });
}

void TrackService::stop() {
  {
    std::lock_guard lock(tickMutex_);
    stopping_ = true;
  }
  feed_.wakeAll();
  if (thread_.joinable()) thread_.join();
}

}  // namespace cpvs::server
