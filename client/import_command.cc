// invr import: a Mitsuba 3 scene file written out as the equivalent invr job JSON, to which a user
// adds an optimisation block; or any job argument (zoo name, job file, `-`) with its --param, -D
// and --set applied, written out as one self-contained job (what the Python client submits).
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>

#include "client/commands.h"
#include "client/common/job_argument.h"
#include "core/error.h"
#include "core/io/job_io.h"
#include "core/io/mitsuba_import.h"
#include "core/scene/scene_builder.h"

namespace invr::cli {

namespace {

struct ImportArgs {
  std::string scene;
  std::string out;
  SceneArgs sceneArgs;
  bool check = true;
};

void runImport(const ImportArgs& a) {
  namespace fs = std::filesystem;
  const fs::path outDir = a.out.empty() ? fs::current_path() : (fs::path(a.out).has_parent_path() ? fs::path(a.out).parent_path() : fs::path("."));
  invr::v1::JobSpec job;
  std::vector<std::string> warnings;
  if (isMitsubaSceneFile(a.scene) && a.sceneArgs.params.empty()) {
    // The job names the scene by reference, relative to where the JSON goes; importing then
    // inlines it with every asset path rebased there.
    if (!fs::exists(a.scene)) throw InputError("Mitsuba scene '" + a.scene + "': not found");
    job.mutable_mitsuba()->set_path(fs::absolute(a.scene).string());
    for (const auto& d : a.sceneArgs.defines) {
      auto eq = d.find('=');
      if (eq == std::string::npos || eq == 0) throw InputError("-D '" + d + "': expected NAME=VALUE");
      (*job.mutable_mitsuba()->mutable_defaults())[d.substr(0, eq)] = d.substr(eq + 1);
    }
    importMitsubaIntoJob(job, outDir, warnings);
    applySets(job, a.sceneArgs.sets);
  } else {
    AssetResolver from;
    job = a.sceneArgs.params.empty() ? jobFromArgument(a.scene, from, a.sceneArgs) : optimizationJobFromArgument(a.scene, from, a.sceneArgs);
    rebaseAssetPaths(job, from.baseDir, outDir);
  }
  for (const auto& w : warnings) std::cerr << "warning: " << w << "\n";
  if (a.check) {  // everything the job names must load (meshes, textures), as a run would find
    AssetResolver assets;
    assets.baseDir = outDir;
    buildJobScene(job, assets, SceneUse::Validate);
  }
  const std::string json = jobToJson(job);
  const auto& s = job.scene();
  std::string summary = job.has_scene() ? std::to_string(s.shapes_size()) + " shapes, " + std::to_string(s.materials_size()) + " materials, " +
                                              std::to_string(s.lights_size()) + " lights, " + std::to_string(s.views_size()) + " views, " +
                                              std::to_string(warnings.size()) + " warnings"
                                        : "zoo scene " + job.zoo();
  if (a.out.empty()) {
    std::cout << json << "\n";
    std::cerr << "imported " << a.scene << " (" << summary << ")\n";
    return;
  }
  std::error_code ec;
  if (fs::path(a.out).has_parent_path()) fs::create_directories(fs::path(a.out).parent_path(), ec);
  if (ec) throw InputError("-o: cannot create the folder '" + fs::path(a.out).parent_path().string() + "': " + ec.message());
  std::ofstream f(a.out);
  if (!(f << json << "\n")) throw InputError("-o: cannot write '" + a.out + "'");
  std::cout << "wrote " << fs::absolute(a.out).lexically_normal().string() << " (" << summary << ")"
            << (job.has_optimization() ? "" : "; add an \"optimization\" block to recover parameters (docs/job-format.md)") << "\n";
}

}  // namespace

void addImportCommand(CLI::App& app, int& exitCode) {
  auto args = std::make_shared<ImportArgs>();
  auto* cmd = app.add_subcommand("import",
                                 "Write a Mitsuba 3 scene (.xml) as the equivalent invr job JSON (docs/mitsuba-import.md); or any job "
                                 "(zoo name, job file, - for standard input) with --param, -D and --set applied, as one job file");
  cmd->add_option("scene", args->scene, "Mitsuba 3 scene file (.xml), zoo scene name, job file (.json) or - (JSON on standard input)")->required();
  cmd->add_option("--param", args->sceneArgs.params,
                  "NAME[=V[,V,V]]: recover this parameter (invr or Mitsuba name); replaces the job's parameter list (repeatable)")
      ->allow_extra_args(false);
  cmd->add_option("--set", args->sceneArgs.sets, "FIELD.PATH=VALUE: set any job field, e.g. optimization.steps=50 (repeatable)")
      ->allow_extra_args(false);
  cmd->add_option("-o,--output", args->out, "job file to write (asset paths relative to its folder); default: print to stdout");
  cmd->add_option("-D,--define", args->sceneArgs.defines, "NAME=VALUE: set the scene's <default name=NAME> (repeatable)")->allow_extra_args(false);
  cmd->add_flag("!--no-check", args->check, "skip loading the meshes and textures the job names");
  cmd->callback([args, &exitCode] {
    runImport(*args);
    exitCode = 0;
  });
}

}  // namespace invr::cli
