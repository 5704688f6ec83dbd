// The scene argument of `render` and `optimize`: a zoo scene name, or a job file (.json) whose
// relative asset paths resolve against the file's folder.
#pragma once

#include <filesystem>
#include <string>

#include "core/diff/zoo_jobs.h"
#include "core/error.h"
#include "core/io/job_io.h"
#include "core/scene/scene_builder.h"

namespace invr::cli {

inline bool isJobFile(const std::string& arg) { return arg.size() > 5 && arg.substr(arg.size() - 5) == ".json"; }

// Loads a job file (setting assets.baseDir), or returns the zoo scene's built-in job.
inline invr::v1::JobSpec jobFromArgument(const std::string& arg, AssetResolver& assets) {
  if (isJobFile(arg)) {
    std::filesystem::path p(arg);
    if (!std::filesystem::exists(p)) throw InputError("job file '" + arg + "': not found");
    assets.baseDir = p.has_parent_path() ? p.parent_path() : std::filesystem::path(".");
    return loadJobFile(p);
  }
  return zooJob(arg);  // InputError listing the known names
}

}  // namespace invr::cli
