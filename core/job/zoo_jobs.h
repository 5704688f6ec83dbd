// Each zoo scene's built-in inverse problem (what to recover, from where, with which method).
#pragma once

#include <string>

#include "invr/v1/job.pb.h"

namespace invr {

// Throws InputError for an unknown scene name.
invr::v1::JobSpec zooJob(const std::string& name);

}  // namespace invr
