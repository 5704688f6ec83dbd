// The client API (invr.v1.InvrService): gRPC callbacks only. Each call reads or updates the job
// book, or posts its work to the control queue; nothing here renders or builds a scene.
#pragma once

#include "invr/v1/service.grpc.pb.h"
#include "server/admission.h"
#include "server/asset_store.h"
#include "server/auth.h"
#include "server/control_queue.h"
#include "server/job_book.h"
#include "server/scheduler.h"

namespace invr::server {

class ClientService final : public invr::v1::InvrService::CallbackService {
 public:
  ClientService(JobBook& book, const Admission& admission, PreparedProblem& prepared, Scheduler& scheduler, AssetStore& assets,
                uint64_t maxAssetBytes, ControlQueue& control, const Authenticator& auth);

  grpc::ServerReadReactor<invr::v1::AssetChunk>* UploadAsset(grpc::CallbackServerContext*, invr::v1::AssetInfo* info) override;
  grpc::ServerUnaryReactor* SubmitJob(grpc::CallbackServerContext* ctx, const invr::v1::SubmitJobRequest* req,
                                      invr::v1::SubmitJobResponse* resp) override;
  grpc::ServerUnaryReactor* PlanJob(grpc::CallbackServerContext* ctx, const invr::v1::PlanJobRequest* req, invr::v1::JobPlan* resp) override;
  grpc::ServerUnaryReactor* GetJob(grpc::CallbackServerContext* ctx, const invr::v1::GetJobRequest* req, invr::v1::JobStatus* resp) override;
  grpc::ServerUnaryReactor* ListJobs(grpc::CallbackServerContext* ctx, const invr::v1::ListJobsRequest*, invr::v1::ListJobsResponse* resp) override;
  grpc::ServerUnaryReactor* CancelJob(grpc::CallbackServerContext* ctx, const invr::v1::CancelJobRequest* req, invr::v1::JobStatus* resp) override;
  grpc::ServerWriteReactor<invr::v1::ProgressEvent>* WatchJob(grpc::CallbackServerContext*, const invr::v1::WatchJobRequest* req) override;
  grpc::ServerWriteReactor<invr::v1::AssetChunk>* FetchResult(grpc::CallbackServerContext*, const invr::v1::FetchResultRequest* req) override;
  grpc::ServerUnaryReactor* ListWorkers(grpc::CallbackServerContext* ctx, const invr::v1::ListWorkersRequest*,
                                        invr::v1::ListWorkersResponse* resp) override;

 private:
  grpc::Status submit(const invr::v1::SubmitJobRequest& req, invr::v1::SubmitJobResponse& resp);

  JobBook& book_;
  const Admission& admission_;
  PreparedProblem& prepared_;
  Scheduler& scheduler_;
  AssetStore& assets_;
  uint64_t maxAssetBytes_;
  ControlQueue& control_;
  const Authenticator& auth_;
};

}  // namespace invr::server
