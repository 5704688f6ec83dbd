#include "server/admission.h"

#include <optional>
#include <thread>

#include "core/job/memory_model.h"
#include "core/job/plan.h"
#include "core/job/scene_description.h"
#include "core/error.h"
#include "core/io/job_io.h"
#include "core/limits.h"

namespace invr::server {

namespace v1 = invr::v1;

Admission::Admission(const AssetStore& assets, uint64_t maxJobBytes, std::function<unsigned()> workerThreads)
    : assets_(assets), maxJobBytes_(maxJobBytes), workerThreads_(std::move(workerThreads)) {}

unsigned Admission::threads() const {
  unsigned n = workerThreads_ ? workerThreads_() : 0;
  return n ? n : std::max(1u, std::thread::hardware_concurrency());
}

Problem Admission::build(const v1::JobSpec& spec) const {
  MemoryBudget budget(maxJobBytes_);
  return buildProblem(spec, resolver(&budget), SceneUse::Validate);  // the server never traces a ray
}

AssetResolver Admission::resolver(MemoryBudget* budget) const {
  AssetResolver r;
  r.budget = budget;
  r.byHash = [this](const std::string& h) -> std::filesystem::path {
    if (!assets_.has(h)) throw InputError("asset " + h + " was not uploaded");
    return assets_.path(h);
  };
  return r;
}

namespace {

// Runs a build step; what it throws becomes the status a client gets: over a budget or out of
// memory RESOURCE_EXHAUSTED, a bad input INVALID_ARGUMENT, anything else INTERNAL.
template <class F>
grpc::Status statusOf(F&& build) {
  try {
    build();
  } catch (const ResourceError& e) {
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED, e.what());
  } catch (const InputError& e) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, e.what());
  } catch (const std::bad_alloc&) {
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED, "the job does not fit in the server's memory");
  } catch (const std::exception& e) {
    return grpc::Status(grpc::StatusCode::INTERNAL, e.what());
  }
  return grpc::Status::OK;
}

}  // namespace

grpc::Status Admission::checkSpecAndAssets(v1::JobSpec& spec) const {
  // Fields this server does not know would be stored and sent to every worker unread.
  spec.DiscardUnknownFields();
  try {
    validateJobSpec(spec);  // bounds first: nothing below echoes an unbounded string
  } catch (const InputError& e) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, e.what());
  }
  // A server job may only name built-in scenes and uploaded assets: paths on the client's disk
  // mean nothing here (`invr submit` uploads them and rewrites the references).
  std::optional<grpc::Status> bad;
  forEachAssetRef(spec, [&](v1::AssetRef& ref, const std::string& field) {
    if (bad) return;
    if (ref.source_case() == v1::AssetRef::SOURCE_NOT_SET) return;  // optional (a view without a mask); required ones fail below
    if (ref.has_path())
      bad = grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                         field + ".path: a job on a server references assets by sha256 (upload '" + ref.path() + "' first)");
    else if (!AssetStore::validHash(ref.sha256()))
      bad = grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, field + ".sha256: '" + ref.sha256() + "' is not a SHA-256 hex digest");
    else if (!assets_.has(ref.sha256()))
      bad = grpc::Status(grpc::StatusCode::NOT_FOUND, field + ".sha256: asset " + ref.sha256() + " was not uploaded");
  });
  if (bad) return *bad;
  return grpc::Status::OK;
}

grpc::Status Admission::admit(v1::JobSpec& spec, v1::JobPlan* plan, std::unique_ptr<Problem>* keep) const {
  if (grpc::Status st = checkSpecAndAssets(spec); !st.ok()) return st;
  if (!spec.has_optimization() || spec.optimization().parameters_size() == 0)
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "optimization.parameters: a job needs at least one parameter to recover");
  return statusOf([&] {
    // Every texture, mesh and target is charged to the job's budget before it is allocated; the
    // problem is dropped again once validated unless `keep` takes it.
    MemoryBudget budget(maxJobBytes_);
    Problem p = buildProblem(spec, resolver(&budget), SceneUse::Validate);
    const unsigned n = threads();
    WorkerMemory mem = estimateWorkerMemory(p, n);
    if (plan) *plan = planJob(spec, p, n);
    if (keep) *keep = std::make_unique<Problem>(std::move(p));
    const double state = mem.images + mem.reservoirs + mem.gradients + mem.textures;  // may exceed 2^64: compare as double
    budget.charge(state < double(budget.limit()) ? uint64_t(state) : budget.limit() + 1,
                  "per-worker state (images, reservoirs, gradients of the largest shard, as `invr plan` estimates it)");
  });
}

grpc::Status Admission::describe(v1::JobSpec& spec, v1::SceneDescription* out) const {
  if (grpc::Status st = checkSpecAndAssets(spec); !st.ok()) return st;
  return statusOf([&] {
    MemoryBudget budget(maxJobBytes_);
    std::unique_ptr<Scene> scene = buildJobScene(spec, resolver(&budget), SceneUse::Validate);
    *out = describeScene(*scene);
  });
}

void PreparedProblem::offer(const std::string& job, std::unique_ptr<Problem> p) {
  std::lock_guard<std::mutex> lk(mu_);
  if (problem_ || !p) return;
  job_ = job;
  problem_ = std::move(p);
}

std::unique_ptr<Problem> PreparedProblem::take(const std::string& job) {
  std::lock_guard<std::mutex> lk(mu_);
  if (!problem_ || job_ != job) return nullptr;
  job_.clear();
  return std::move(problem_);
}

void PreparedProblem::drop(const std::string& job) {
  std::lock_guard<std::mutex> lk(mu_);
  if (job_ == job) problem_.reset(), job_.clear();
}

}  // namespace invr::server
