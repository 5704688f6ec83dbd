// The server's job store on disk, one folder per job:
//   record.pb       JobRecord (spec, state, reason, result names)
//   checkpoint.pb   Checkpoint (theta, Adam moments, step, random-stream counter)
//   progress.jsonl  one ProgressEvent per line, in sequence order
//   results/        files FetchResult serves
// Records and checkpoints are written to a temporary file and renamed, so a crash (even kill -9)
// leaves either the old or the new version, never half of one.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "invr/v1/service.pb.h"

namespace invr::server {

class JobStore {
 public:
  explicit JobStore(std::filesystem::path dir);

  std::vector<invr::v1::JobRecord> loadAll() const;  // every job, by id
  std::string newJobId();                            // job-000001, job-000002, ...

  void saveRecord(const invr::v1::JobRecord& record) const;
  void saveCheckpoint(const std::string& job, const invr::v1::Checkpoint& ck) const;
  std::optional<invr::v1::Checkpoint> loadCheckpoint(const std::string& job) const;
  void appendEvent(const std::string& job, const invr::v1::ProgressEvent& event) const;
  std::vector<invr::v1::ProgressEvent> loadEvents(const std::string& job) const;

  std::filesystem::path jobDir(const std::string& job) const { return dir_ / job; }
  std::filesystem::path resultsDir(const std::string& job) const { return dir_ / job / "results"; }

 private:
  std::filesystem::path dir_;
  uint64_t next_ = 1;
};

// Writes bytes to path through a temporary file and a rename (fsync'd).
void writeFileAtomically(const std::filesystem::path& path, const std::string& bytes);

}  // namespace invr::server
