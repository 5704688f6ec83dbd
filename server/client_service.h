// The client API (invr.v1.InvrService): gRPC callbacks only. Each call reads or updates the job
// book, or posts its work to the control queue; nothing here renders or builds a scene. Every
// method takes its request as raw bytes and parses them itself (raw_messages.h), so a malformed
// request gets INVALID_ARGUMENT, not gRPC's UNIMPLEMENTED.
#pragma once

#include "invr/v1/service.grpc.pb.h"
#include "server/admission.h"
#include "server/asset_store.h"
#include "server/auth.h"
#include "server/control_queue.h"
#include "server/job_book.h"
#include "server/scheduler.h"

namespace invr::server {

using RawClientApi = invr::v1::InvrService::WithRawCallbackMethod_UploadAsset<invr::v1::InvrService::WithRawCallbackMethod_SubmitJob<
    invr::v1::InvrService::WithRawCallbackMethod_GetJob<invr::v1::InvrService::WithRawCallbackMethod_ListJobs<
        invr::v1::InvrService::WithRawCallbackMethod_CancelJob<invr::v1::InvrService::WithRawCallbackMethod_WatchJob<
            invr::v1::InvrService::WithRawCallbackMethod_FetchResult<invr::v1::InvrService::WithRawCallbackMethod_ListWorkers<
                invr::v1::InvrService::WithRawCallbackMethod_PlanJob<
                    invr::v1::InvrService::WithRawCallbackMethod_DescribeScene<
                        invr::v1::InvrService::WithRawCallbackMethod_ResolveJob<invr::v1::InvrService::Service>>>>>>>>>>>;

class ClientService final : public RawClientApi {
 public:
  ClientService(JobBook& book, const Admission& admission, PreparedProblem& prepared, Scheduler& scheduler, AssetStore& assets,
                uint64_t maxAssetBytes, ControlQueue& control, const Authenticator& auth);

  // Each request is the serialised message its proto names (UploadAsset: AssetChunk messages;
  // WatchJob and FetchResult write ProgressEvent and AssetChunk messages).
  grpc::ServerReadReactor<grpc::ByteBuffer>* UploadAsset(grpc::CallbackServerContext*, grpc::ByteBuffer* info) override;
  grpc::ServerUnaryReactor* SubmitJob(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* req, grpc::ByteBuffer* resp) override;
  grpc::ServerUnaryReactor* PlanJob(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* req, grpc::ByteBuffer* resp) override;
  grpc::ServerUnaryReactor* DescribeScene(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* req, grpc::ByteBuffer* resp) override;
  grpc::ServerUnaryReactor* ResolveJob(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* req, grpc::ByteBuffer* resp) override;
  grpc::ServerUnaryReactor* GetJob(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* req, grpc::ByteBuffer* resp) override;
  grpc::ServerUnaryReactor* ListJobs(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* req, grpc::ByteBuffer* resp) override;
  grpc::ServerUnaryReactor* CancelJob(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* req, grpc::ByteBuffer* resp) override;
  grpc::ServerWriteReactor<grpc::ByteBuffer>* WatchJob(grpc::CallbackServerContext*, const grpc::ByteBuffer* req) override;
  grpc::ServerWriteReactor<grpc::ByteBuffer>* FetchResult(grpc::CallbackServerContext*, const grpc::ByteBuffer* req) override;
  grpc::ServerUnaryReactor* ListWorkers(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* req, grpc::ByteBuffer* resp) override;

 private:
  // A unary call whose answer builds a scene (reads meshes and textures): parsed and checked
  // here, answered from the control queue, never on a gRPC thread.
  template <class Req, class Resp, class Work>
  grpc::ServerUnaryReactor* answerOffThread(grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* bytes, grpc::ByteBuffer* out,
                                            const char* method, Work work);

  grpc::Status submit(const invr::v1::SubmitJobRequest& req, const std::string& submittedBy, invr::v1::SubmitJobResponse& resp);

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
