// The gRPC edge of the coordinator: authorization, message limits, and FarmError kinds
// turned into statuses. Everything else is Coordinator's.
#pragma once

#include <atomic>
#include <memory>

#include "coordinator/coordinator.h"
#include "rpc/auth.h"
#include "rpc/gatekeeper.h"
#include "cpvs/v1/farm.grpc.pb.h"

namespace cpvs::server {

class FarmService final : public pb::Farm::Service {
 public:
  FarmService(Coordinator& c, Gatekeeper& gate) : c_(c), gate_(gate) {}

  grpc::Status GetUploadStatus(grpc::ServerContext*, const pb::SceneRef*, pb::UploadStatus*) override;
  grpc::Status UploadScene(grpc::ServerContext*, grpc::ServerReader<pb::UploadSceneChunk>*,
                           pb::UploadSceneReply*) override;
  grpc::Status SubmitBake(grpc::ServerContext*, const pb::SubmitBakeRequest*, pb::JobStatus*) override;
  grpc::Status WatchJob(grpc::ServerContext*, const pb::JobRef*, grpc::ServerWriter<pb::JobStatus>*) override;
  grpc::Status CancelJob(grpc::ServerContext*, const pb::JobRef*, pb::JobStatus*) override;
  grpc::Status ListJobs(grpc::ServerContext*, const pb::ListJobsRequest*, pb::ListJobsReply*) override;
  grpc::Status DownloadArtifact(grpc::ServerContext*, const pb::DownloadRequest*,
                                grpc::ServerWriter<pb::ArtifactChunk>*) override;
  grpc::Status CreateTrack(grpc::ServerContext*, const pb::CreateTrackRequest*, pb::TrackStatus*) override;
  grpc::Status ListTracks(grpc::ServerContext*, const pb::ListJobsRequest*, pb::ListTracksReply*) override;
  grpc::Status CancelTrack(grpc::ServerContext*, const pb::TrackRef*, pb::TrackStatus*) override;
  grpc::Status Subscribe(grpc::ServerContext*, const pb::SubscribeRequest*, grpc::ServerWriter<pb::VersionChunk>*) override;

 private:
  /// A slot for one long-lived stream of `kind` ("watch": WatchJob, "subscribe"), or nothing when
  /// CoordinatorConfig::maxWatches are open (R15): each holds a server thread.
  std::shared_ptr<void> streamSlot(const char* kind);

  Coordinator& c_;
  Gatekeeper& gate_;
  std::atomic<int> openStreams_{0};
};

class WorkerService final : public pb::Workers::Service {
 public:
  WorkerService(Coordinator& c, Gatekeeper& gate) : c_(c), gate_(gate) {}

  grpc::Status LeaseTile(grpc::ServerContext*, const pb::LeaseRequest*, pb::TileLease*) override;
  grpc::Status RenewLease(grpc::ServerContext*, const pb::RenewRequest*, pb::RenewReply*) override;
  grpc::Status FetchScene(grpc::ServerContext*, const pb::FetchSceneRequest*,
                          grpc::ServerWriter<pb::SceneChunk>*) override;
  grpc::Status CompleteTile(grpc::ServerContext*, grpc::ServerReader<pb::TileResultChunk>*,
                            pb::CompleteReply*) override;
  grpc::Status FailTile(grpc::ServerContext*, const pb::FailRequest*, pb::FailReply*) override;

 private:
  Coordinator& c_;
  Gatekeeper& gate_;
};

}  // namespace cpvs::server
