// Admission: everything a job must pass before it is queued (SubmitJob) or planned (PlanJob) —
// the same checks, errors and status codes for both — and the problem a validated job was built
// with, kept for its run so it is built once.
//
// Runs off the gRPC threads (building a problem reads meshes and textures).
#pragma once

#include <grpcpp/grpcpp.h>

#include <functional>
#include <memory>
#include <mutex>
#include <string>

#include "core/job/problem.h"
#include "invr/v1/service.pb.h"
#include "server/asset_store.h"

namespace invr::server {

class Admission {
 public:
  // `workerThreads`: threads of the largest connected worker (0 when none is connected: the
  // machine's own count is assumed), for the memory model.
  Admission(const AssetStore& assets, uint64_t maxJobBytes, std::function<unsigned()> workerThreads);

  // OK, INVALID_ARGUMENT (the spec), NOT_FOUND (an asset not uploaded) or RESOURCE_EXHAUSTED (over
  // the job memory limit). Unknown fields are discarded from `spec`. `plan` receives the plan;
  // `keep` the validated problem.
  grpc::Status admit(invr::v1::JobSpec& spec, invr::v1::JobPlan* plan, std::unique_ptr<Problem>* keep = nullptr) const;

  // The scene's optimisable parameters (DescribeScene): the same spec and asset checks and memory
  // limit as admit, without needing an optimisation block.
  grpc::Status describe(invr::v1::JobSpec& spec, invr::v1::SceneDescription* out) const;

  // The server's copy of a job's problem (validated, no BVH) under the job memory limit.
  Problem build(const invr::v1::JobSpec& spec) const;

 private:
  unsigned threads() const;
  grpc::Status checkSpecAndAssets(invr::v1::JobSpec& spec) const;
  AssetResolver resolver(MemoryBudget* budget) const;
  const AssetStore& assets_;
  uint64_t maxJobBytes_;
  std::function<unsigned()> workerThreads_;
};

// One queued job's validated problem, kept until it starts. One slot: jobs queued behind it are
// built again when they start, so a long queue holds no problems in memory.
class PreparedProblem {
 public:
  void offer(const std::string& job, std::unique_ptr<Problem> p);  // kept if the slot is free
  std::unique_ptr<Problem> take(const std::string& job);            // null unless it holds `job`
  void drop(const std::string& job);

 private:
  std::mutex mu_;
  std::string job_;
  std::unique_ptr<Problem> problem_;
};

}  // namespace invr::server
