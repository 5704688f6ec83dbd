// The CLI's side of the service: a thin wrapper over the gRPC stubs that turns statuses into
// ExitErrors with the right exit code, uploads a job's local assets, and watches progress.
#pragma once

#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "invr/v1/service.grpc.pb.h"
#include "proto/wire/security.h"

namespace invr::cli {

class ServiceClient {
 public:
  // Plaintext without `security`'s CA; its token (if any) goes with every call.
  explicit ServiceClient(const std::string& address, invr::wire::ClientSecurity security = {});

  // Uploads every asset the job names by path (relative to baseDir) and rewrites the reference
  // to its sha256, so the job means the same thing on the server.
  void uploadAssets(invr::v1::JobSpec& job, const std::filesystem::path& baseDir);
  std::string upload(const std::filesystem::path& file);

  // The job a CLI argument names (zoo name, job file, `-`, Mitsuba scene) with its overrides,
  // resolved by the server (ResolveJob, the code `invr` runs locally): the files it names are
  // uploaded as the server asks for them, and the spec names them by sha256.
  invr::v1::JobSpec resolve(const std::string& arg, const std::vector<std::string>& defines, const std::vector<std::string>& params,
                            const std::vector<std::string>& sets, bool forOptimization);

  invr::v1::SubmitJobResponse submit(const invr::v1::JobSpec& job, const std::string& requestId);
  invr::v1::JobStatus get(const std::string& job);
  // The job's plan as the server sees it (validated as a submission would be; not queued).
  invr::v1::JobPlan plan(const invr::v1::JobSpec& job);
  // The optimisable parameters of the job's scene, as the server sees it.
  invr::v1::SceneDescription describe(const invr::v1::JobSpec& job);
  invr::v1::ListJobsResponse list();
  invr::v1::JobStatus cancel(const std::string& job);
  invr::v1::ListWorkersResponse workers();
  // Waits until at least n workers are connected; false after timeoutSeconds.
  bool waitForWorkers(int n, double timeoutSeconds);

  // Streams events from `fromSequence` until the job's final event; returns its status, or
  // nullopt if `interrupted` became true first. When the stream breaks (a server restart), waits
  // up to reconnectSeconds() for the server to be reachable again and resumes from the last
  // sequence seen; only then does it give up (server unavailable).
  std::optional<invr::v1::JobStatus> watch(const std::string& job, uint64_t fromSequence,
                                           const std::function<void(const invr::v1::ProgressEvent&)>& onEvent,
                                           const std::atomic<bool>& interrupted);

  // Downloads every result file into dir; returns how many.
  int fetchAll(const std::string& job, const std::filesystem::path& dir);
  // Downloads one result file (a name from JobStatus.results) into dir.
  void fetchOne(const std::string& job, const std::string& name, const std::filesystem::path& dir);

  const std::string& address() const { return address_; }
  double reconnectSeconds() const { return reconnectSeconds_; }
  void setReconnectSeconds(double s) { reconnectSeconds_ = s; }

 private:
  std::string address_;
  invr::wire::ClientSecurity security_;
  std::shared_ptr<grpc::Channel> channel_;
  double reconnectSeconds_ = 60;
  std::unique_ptr<invr::v1::InvrService::Stub> stub_;
};

// Throws ExitError for a failed status: UNAVAILABLE -> server unavailable; INVALID_ARGUMENT,
// NOT_FOUND, RESOURCE_EXHAUSTED, FAILED_PRECONDITION -> input error; anything else -> internal.
void throwIfFailed(const grpc::Status& status, const std::string& what);

// Exit code for a finished job's state (0 for SUCCEEDED).
int exitCodeFor(invr::v1::JobState state);

// One line per event for people, or one JSON object per event (--json).
std::string describeEvent(const invr::v1::ProgressEvent& event);
std::string eventJson(const invr::v1::ProgressEvent& event);

}  // namespace invr::cli
