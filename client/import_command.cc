// invr import: a Mitsuba 3 scene file written out as the equivalent invr job JSON, to which a user
// adds an optimisation block.
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
  if (!isMitsubaSceneFile(a.scene)) throw InputError("'" + a.scene + "': not a Mitsuba scene file (.xml)");
  namespace fs = std::filesystem;
  // The job names the scene by reference, relative to where the JSON goes; importing then inlines
  // it with every asset path rebased there.
  const fs::path outDir = a.out.empty() ? fs::current_path() : (fs::path(a.out).has_parent_path() ? fs::path(a.out).parent_path() : fs::path("."));
  invr::v1::JobSpec job;
  job.mutable_mitsuba()->set_path(fs::absolute(a.scene).string());
  for (const auto& d : a.sceneArgs.defines) {
    auto eq = d.find('=');
    if (eq == std::string::npos || eq == 0) throw InputError("-D '" + d + "': expected NAME=VALUE");
    (*job.mutable_mitsuba()->mutable_defaults())[d.substr(0, eq)] = d.substr(eq + 1);
  }
  std::vector<std::string> warnings;
  importMitsubaIntoJob(job, outDir, warnings);
  for (const auto& w : warnings) std::cerr << "warning: " << w << "\n";
  if (a.check) {  // everything the job names must load (meshes, textures), as a run would find
    AssetResolver assets;
    assets.baseDir = outDir;
    buildJobScene(job, assets, SceneUse::Validate);
  }
  const std::string json = jobToJson(job);
  const auto& s = job.scene();
  std::string summary = std::to_string(s.shapes_size()) + " shapes, " + std::to_string(s.materials_size()) + " materials, " +
                        std::to_string(s.lights_size()) + " lights, " + std::to_string(s.views_size()) + " views, " +
                        std::to_string(warnings.size()) + " warnings";
  if (a.out.empty()) {
    std::cout << json << "\n";
    std::cerr << "imported " << a.scene << " (" << summary << ")\n";
    return;
  }
  std::ofstream f(a.out);
  if (!(f << json << "\n")) throw InputError("-o: cannot write '" + a.out + "'");
  std::cout << "wrote " << fs::absolute(a.out).lexically_normal().string() << " (" << summary
            << "); add an \"optimization\" block to recover parameters (docs/job-format.md)\n";
}

}  // namespace

void addImportCommand(CLI::App& app, int& exitCode) {
  auto args = std::make_shared<ImportArgs>();
  auto* cmd = app.add_subcommand("import", "Write a Mitsuba 3 scene (.xml) as the equivalent invr job JSON (docs/mitsuba-import.md)");
  cmd->add_option("scene", args->scene, "Mitsuba 3 scene file (.xml)")->required();
  cmd->add_option("-o,--output", args->out, "job file to write (asset paths relative to its folder); default: print to stdout");
  cmd->add_option("-D,--define", args->sceneArgs.defines, "NAME=VALUE: set the scene's <default name=NAME> (repeatable)")->allow_extra_args(false);
  cmd->add_flag("!--no-check", args->check, "skip loading the meshes and textures the job names");
  cmd->callback([args, &exitCode] {
    runImport(*args);
    exitCode = 0;
  });
}

}  // namespace invr::cli
