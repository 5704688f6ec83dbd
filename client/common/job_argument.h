// The scene/job argument of render, optimize, run, submit, plan and import: a zoo scene name, a job
// file (.json, whose relative asset paths resolve against its folder, and whose scene may be a
// Mitsuba file: {"mitsuba": {"path": ...}}), `-` (a job's JSON on standard input, relative paths
// from the working directory) or a Mitsuba 3 scene file (.xml), imported on the spot. The
// resolution itself is core's (core/job/job_source.h), which the server's ResolveJob shares.
#pragma once

#include <CLI/CLI.hpp>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "core/job/job_source.h"  // applySets, rebaseAssetPaths, importMitsubaIntoJob
#include "core/scene/scene_builder.h"
#include "invr/v1/job.pb.h"

namespace invr::cli {

bool isJobFile(const std::string& arg);  // .json

// Options every command that reads a scene argument shares.
struct SceneArgs {
  std::vector<std::string> defines;  // -D name=value: Mitsuba <default> overrides
  std::vector<std::string> params;   // --param NAME[=V[,V,V]]: the parameters to recover
  std::vector<std::string> sets;     // --set FIELD.PATH=VALUE: any job field (optimization.steps=50)
};
void addSceneArgs(CLI::App* cmd, SceneArgs& a, bool withParams);

// Loads the job an argument names (setting assets.baseDir). A Mitsuba scene, directly or through
// a job file, becomes an inline scene; its import warnings go to stderr.
// `imported` (optional) says whether the scene came from a Mitsuba file.
invr::v1::JobSpec jobFromArgument(const std::string& arg, AssetResolver& assets, const SceneArgs& sceneArgs = {}, bool* imported = nullptr);

// The job an optimisation command runs: jobFromArgument, then --param replaces the parameter list.
// A scene without an optimisation block (a Mitsuba file, a job file without one) needs --param;
// the error says so. For a Mitsuba scene the optimisation takes the scene's depth, with method pt
// where paths are longer than direct illumination.
invr::v1::JobSpec optimizationJobFromArgument(const std::string& arg, AssetResolver& assets, const SceneArgs& sceneArgs);

}  // namespace invr::cli
