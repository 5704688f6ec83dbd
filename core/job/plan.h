// A job's plan: what it will compute (estimators, parameters, pixels, passes) and what one worker
// needs for it, before anything runs (DESIGN.md, principle 1). `invr plan` prints it; the server
// answers PlanJob with it from its workers' view (their thread count).
#pragma once

#include "core/job/memory_model.h"
#include "core/job/problem.h"
#include "invr/v1/service.pb.h"

namespace invr {

// `workerThreads`: threads of the worker the memory estimate is for (each holds a gradient scratch).
invr::v1::JobPlan planJob(const invr::v1::JobSpec& job, const Problem& problem, unsigned workerThreads);

}  // namespace invr
