// Checks a worker's TaskResult against the task it answers, before anything of it is used: a
// result from a faulty or hostile worker fails its task (which is retried elsewhere), never the
// server.
#pragma once

#include <cstddef>
#include <string>

#include "invr/v1/service.pb.h"

namespace invr::server {

// What the server knows of the job when it reads a result.
struct ResultShape {
  size_t parameters = 0;  // gradient length of a GRADIENT task that is not render-only
  int width = 0, height = 0;  // film size of FINAL_RENDER images
};

// Empty when `result` is a well-formed answer to `task`; otherwise what is wrong with it, e.g.
// "gradient has 7 values, the job has 12 parameters". Error results (error non-empty) are
// well-formed when their error text is within bounds.
std::string checkTaskResult(const invr::v1::Task& task, const invr::v1::TaskResult& result, const ResultShape& shape);

}  // namespace invr::server
