// The worker API (invr.v1.WorkerService): one bidirectional stream per worker connection, whose
// messages go to the scheduler, and asset downloads.
#pragma once

#include "invr/v1/service.grpc.pb.h"
#include "server/asset_store.h"
#include "server/auth.h"
#include "server/scheduler.h"

namespace invr::server {

class WorkerService final : public invr::v1::WorkerService::CallbackService {
 public:
  WorkerService(Scheduler& scheduler, const AssetStore& assets, const Authenticator& auth)
      : scheduler_(scheduler), assets_(assets), auth_(auth) {}

  grpc::ServerBidiReactor<invr::v1::WorkerMessage, invr::v1::ServerMessage>* Connect(grpc::CallbackServerContext*) override;
  grpc::ServerWriteReactor<invr::v1::AssetChunk>* FetchAsset(grpc::CallbackServerContext*, const invr::v1::FetchAssetRequest* req) override;

 private:
  Scheduler& scheduler_;
  const AssetStore& assets_;
  const Authenticator& auth_;
};

}  // namespace invr::server
