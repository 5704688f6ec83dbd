// One job's step loop on the server: resume from its checkpoint, farm each evaluation's shards
// through the scheduler, apply the optimiser, checkpoint, report progress, and write the results
// (parameters, convergence CSV, final renders from the workers) or fail the job keeping its last
// good parameters. The server runs one JobRunner::run per running job, each on its own thread.
#pragma once

#include <atomic>
#include <functional>
#include <string>

#include "server/admission.h"
#include "server/job_book.h"
#include "server/job_store.h"
#include "server/scheduler.h"

namespace invr::server {

struct RunnerOptions {
  int finalSpp = 64;   // final renders written with the results
  int finalViews = 4;  // ... for the first this many views
};

class JobRunner {
 public:
  JobRunner(RunnerOptions options, JobStore& store, JobBook& book, Scheduler& scheduler, const Admission& admission,
            PreparedProblem& prepared, const std::atomic<bool>& stopping);

  // Runs the job (already marked RUNNING by JobBook::take) to its end. On server shutdown it
  // returns with the job unfinished in the store, to resume on restart.
  void run(const std::string& id);

  // Called after every applied step with its wall time (metrics).
  std::function<void(double stepSeconds)> onStep;

 private:
  struct Context;
  void runSteps(Context& c);
  void writeResults(Context& c);
  void writeSnapshot(Context& c, uint64_t step);  // renders and parameters at c.theta (snapshot_every)
  void fail(Context& c, const std::string& reason);
  std::string writeJob(Context& c);                       // job.json; its name
  std::string writeConvergence(Context& c);               // convergence.csv from the log; its name
  std::vector<std::string> writeCheckpointResults(Context& c);  // a failed or cancelled job's files
  void copyLog(const std::string& id, std::vector<std::string>& files);

  RunnerOptions opt_;
  JobStore& store_;
  JobBook& book_;
  Scheduler& scheduler_;
  const Admission& admission_;
  PreparedProblem& prepared_;
  const std::atomic<bool>& stopping_;
};

}  // namespace invr::server
