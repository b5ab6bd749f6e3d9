// Following a sun track: a subscription thread, versions uploaded beside the ones in use,
// lookups crossfaded between the two around an instant.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <map>
#include <mutex>
#include <thread>

#include "cpvs/client/farm_client.h"
#include "cpvs/runtime/runtime.h"

namespace cpvs::runtime {

namespace {

// One version ready for lookups.
struct Held {
  uint64_t sequence = 0;
  int64_t instantMs = 0;
  std::shared_ptr<ShadowLookups> lookups;
};

constexpr size_t kHeldVersions = 3;

}  // namespace

struct TrackFollower::Impl {
  FarmAddress farm;
  std::string trackId;
  Backend backend;
  DeviceOptions options;
  // One device for every version (declared before `held`, which it outlives).
  std::unique_ptr<GpuDevice> device;
  mutable std::mutex mutex;
  std::condition_variable arrived;
  std::map<int64_t, Held> held;  // by instant
  uint64_t received = 0, last = 0;
  std::string error;
  std::atomic<bool> stopping{false};

  void run() {
    if (backend != Backend::Cpu) {
      try {
        device = GpuDevice::create(options);
      } catch (const RuntimeError&) {
        // No device: each version's lookups decide (the CPU for Auto, an error for Gpu).
      }
    }
    int pauseMs = 125;
    uint64_t receivedBefore = 0;
    while (!stopping) {
      try {
        client::FarmClient c(net::Connection{farm.address, farm.token, farm.caFile});
        uint64_t from;
        {
          std::lock_guard lock(mutex);
          from = last;
        }
        c.subscribe(trackId, from, [&](const client::TrackVersion& v, const std::vector<uint8_t>& bytes) {
          if (stopping) return false;
          // Made ready (decoded, uploaded) without the lock; swapped in with it.
          Held h;
          h.sequence = v.sequence;
          h.instantMs = v.instantUnixMs != 0 ? v.instantUnixMs : int64_t(v.sequence);
          auto artifact = ShadowArtifact::fromBytes(bytes, "track " + trackId + " version " + std::to_string(v.sequence));
          h.lookups = device ? std::make_shared<ShadowLookups>(artifact, *device, backend)
                             : std::make_shared<ShadowLookups>(artifact, backend, options);
          std::lock_guard lock(mutex);
          held[h.instantMs] = std::move(h);
          while (held.size() > kHeldVersions) held.erase(held.begin());
          ++received;
          last = v.sequence;
          error.clear();
          arrived.notify_all();
          return !stopping.load();
        });
        if (!stopping) {  // the track ended: nothing more will come
          std::lock_guard lock(mutex);
          error = "the track ended";
          arrived.notify_all();
          return;
        }
      } catch (const std::exception& e) {
        std::lock_guard lock(mutex);
        error = e.what();
      }
      // Backing off: 0.25 s after a version arrived, doubling while none does, up to 8 s (a
      // coordinator restarting is found within seconds, one that is gone is not hammered).
      uint64_t now;
      {
        std::lock_guard lock(mutex);
        now = received;
      }
      pauseMs = now != receivedBefore ? 250 : std::min(pauseMs * 2, 8000);
      receivedBefore = now;
      for (int waited = 0; waited < pauseMs && !stopping; waited += 50)
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }
};

TrackFollower::TrackFollower(FarmAddress farm, std::string trackId, Backend backend, const DeviceOptions& options)
    : impl_(std::make_shared<Impl>()) {
  impl_->farm = std::move(farm);
  impl_->trackId = std::move(trackId);
  impl_->backend = backend;
  impl_->options = options;
  // The thread shares the state: a subscription waiting on a quiet track cannot be
  // interrupted from here, so it ends on its own, at the track's next version or end.
  std::thread([impl = impl_] { impl->run(); }).detach();
}

TrackFollower::~TrackFollower() {
  impl_->stopping = true;
  std::lock_guard lock(impl_->mutex);
  impl_->held.clear();
}

uint64_t TrackFollower::waitForVersions(uint64_t count, double timeoutSeconds) {
  std::unique_lock lock(impl_->mutex);
  impl_->arrived.wait_for(lock, std::chrono::duration<double>(timeoutSeconds),
                          [&] { return impl_->received >= count || impl_->error == "the track ended"; });
  return impl_->received;
}

uint64_t TrackFollower::lastSequence() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->last;
}

std::string TrackFollower::lastError() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->error;
}

std::vector<int64_t> TrackFollower::heldInstants() const {
  std::lock_guard lock(impl_->mutex);
  std::vector<int64_t> out;
  for (const auto& [instant, h] : impl_->held) out.push_back(instant);
  return out;
}

void TrackFollower::visibility(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
                               int64_t instantMs, std::vector<float>& out) {
  Held before, after;
  {
    std::lock_guard lock(impl_->mutex);
    if (impl_->held.empty()) throw RuntimeError(Status::InvalidArgument, "no version of track " + impl_->trackId + " yet");
    auto next = impl_->held.upper_bound(instantMs);
    if (next == impl_->held.begin()) {
      before = next->second;
    } else if (next == impl_->held.end()) {
      before = std::prev(next)->second;
    } else {
      before = std::prev(next)->second;
      after = next->second;
    }
  }
  before.lookups->visibility(points, normals, pcf, out);
  if (!after.lookups) return;
  const double w = double(instantMs - before.instantMs) / double(after.instantMs - before.instantMs);
  std::vector<float> second;
  after.lookups->visibility(points, normals, pcf, second);
  for (size_t i = 0; i < out.size(); ++i) out[i] = float((1 - w) * out[i] + w * second[i]);
}

}  // namespace cpvs::runtime
