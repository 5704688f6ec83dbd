#include "client/common/job_argument.h"

#include <fstream>
#include <iostream>
#include <sstream>

#include "core/error.h"
#include "core/io/mitsuba_import.h"

namespace invr::cli {

namespace v1 = invr::v1;
namespace fs = std::filesystem;

bool isJobFile(const std::string& arg) { return arg.size() > 5 && arg.substr(arg.size() - 5) == ".json"; }

void addSceneArgs(CLI::App* cmd, SceneArgs& a, bool withParams) {
  // One value per occurrence, so a positional after them is not taken for one.
  cmd->add_option("-D,--define", a.defines, "NAME=VALUE: set a Mitsuba scene's <default name=NAME> (repeatable)")->allow_extra_args(false);
  if (withParams)
    cmd->add_option("--param", a.params,
                    "NAME[=V[,V,V]]: recover this parameter (invr or Mitsuba name, e.g. red.reflectance.value=0.01,0.2,0.9), starting "
                    "at the values given; replaces the job's parameter list (repeatable)")
        ->allow_extra_args(false);
  cmd->add_option("--set", a.sets,
                  "FIELD.PATH=VALUE: set any job field, e.g. optimization.steps=50, optimization.parameters[0].learning_rate=0.05, "
                  "render.spp=64, optimization.method=pt (repeatable; applied after the job is loaded)")
      ->allow_extra_args(false);
}

namespace {

// The source an argument names: `-` (standard input), a job file, a Mitsuba scene or a zoo name.
JobSource sourceOf(const std::string& arg) {
  JobSource src;
  src.name = arg;
  if (arg == "-") {  // the job's JSON on standard input; its relative paths from the working directory
    std::stringstream text;
    text << std::cin.rdbuf();
    src.kind = JobSource::Kind::JobJson;
    src.json = text.str();
    src.name = "<stdin>";
    src.baseDir = fs::path(".");
  } else if (isJobFile(arg)) {
    fs::path p(arg);
    if (!fs::exists(p)) throw InputError("job file '" + arg + "': not found");
    std::ifstream in(p);
    if (!in) throw InputError("job file '" + arg + "': cannot open");
    std::stringstream text;
    text << in.rdbuf();
    src.kind = JobSource::Kind::JobJson;
    src.json = text.str();
    src.baseDir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  } else if (isMitsubaSceneFile(arg)) {
    src.kind = JobSource::Kind::MitsubaXml;
    src.xml = arg;
  } else {
    src.kind = JobSource::Kind::Zoo;
    src.zoo = arg;
  }
  return src;
}

v1::JobSpec resolved(const std::string& arg, AssetResolver& assets, const SceneArgs& a, bool forOptimization, bool* imported) {
  JobOverrides ov{a.defines, forOptimization ? a.params : std::vector<std::string>{}, a.sets};
  ResolvedJob r = resolveJob(sourceOf(arg), ov, forOptimization);
  for (const auto& w : r.warnings) std::cerr << "warning: " << w << "\n";
  if (!r.baseDir.empty()) assets.baseDir = r.baseDir;  // a zoo job names no files
  if (imported) *imported = r.imported;
  return std::move(r.job);
}

}  // namespace

v1::JobSpec jobFromArgument(const std::string& arg, AssetResolver& assets, const SceneArgs& sceneArgs, bool* imported) {
  return resolved(arg, assets, sceneArgs, false, imported);
}

v1::JobSpec optimizationJobFromArgument(const std::string& arg, AssetResolver& assets, const SceneArgs& sceneArgs) {
  return resolved(arg, assets, sceneArgs, true, nullptr);
}

}  // namespace invr::cli
