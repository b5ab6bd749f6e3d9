// What the coordinator forgets on purpose (R16, R25, R15): finished jobs past their
// retention, with their artifacts and tile results, scenes no job has used as long, and
// uploads abandoned half-way. Without
// it every job and upload ever made stays on disk and in every listing.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <thread>

#include "coordinator/artifact_store.h"
#include "coordinator/scene_store.h"
#include "store/farm_store.h"

namespace cpvs::server {

struct RetentionRules {
  double keepFinishedSeconds = 30 * 86400.0;  // a finished job (and its artifact), an unused scene: kept this long; 0: forever
  double uploadExpirySeconds = 86400.0;       // an upload with no byte for this long is dropped; 0: never
  double intervalSeconds = 60;                // how often the rules are applied
};

class Housekeeper {
 public:
  Housekeeper(FarmStore& store, ArtifactStore& artifacts, SceneStore& scenes, RetentionRules rules);
  ~Housekeeper() { stop(); }

  void start();
  void stop();
  /// Applies the rules once now. Called by the thread, and at start after removing files
  /// the store no longer knows (a prune cut short).
  void runOnce();

 private:
  void loop();

  FarmStore& store_;
  ArtifactStore& artifacts_;
  SceneStore& scenes_;
  RetentionRules rules_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace cpvs::server
