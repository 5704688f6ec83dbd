// invr export: a results folder written out as a Mitsuba 3 scene with the optimised values in
// it (meshes as PLY, textures as EXR, transforms applied) and a job file over that scene; or a
// job (zoo name, job file) with its scene as described, the job's initial values kept.
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>

#include "client/commands.h"
#include "client/common/job_argument.h"
#include "core/error.h"
#include "core/optim/results_export.h"
#include "proto/wire/sha256.h"

namespace invr::cli {

namespace {

namespace fs = std::filesystem;
namespace v1 = invr::v1;

struct ExportArgs {
  std::string results;
  std::string out = "export/scene.xml";
  std::vector<std::string> assets;
};

// Assets the service knew by content hash (uploaded meshes, textures): found by hashing the files
// under the folders given, once, on the first request.
class HashIndex {
 public:
  explicit HashIndex(std::vector<fs::path> roots) : roots_(std::move(roots)) {}
  fs::path find(const std::string& sha256) {
    if (!built_) build();
    auto it = files_.find(sha256);
    if (it != files_.end()) return it->second;
    std::string where;
    for (const auto& r : roots_) where += (where.empty() ? "" : ", ") + r.string();
    throw InputError("the job names an uploaded file by its SHA-256 " + sha256.substr(0, 16) + "…, and no file under " + where +
                     " has it: give the folder of the scene's meshes and textures with --assets DIR");
  }

 private:
  void build() {
    built_ = true;
    for (const auto& root : roots_) {
      std::error_code ec;
      for (auto it = fs::recursive_directory_iterator(root, fs::directory_options::skip_permission_denied, ec);
           !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
        if (!it->is_regular_file(ec) || it->file_size(ec) > (uint64_t(4) << 30)) continue;
        try {
          files_.emplace(invr::server::sha256File(it->path()), it->path());
        } catch (const std::exception&) {
          // unreadable: not one of ours
        }
      }
    }
  }
  std::vector<fs::path> roots_;
  std::map<std::string, fs::path> files_;
  bool built_ = false;
};

void runExport(const ExportArgs& a) {
  const fs::path results(a.results), xml(a.out);
  if (xml.extension() != ".xml") throw InputError("-o '" + a.out + "': expected a Mitsuba scene file name ending in .xml");
  if (xml.has_parent_path()) {
    std::error_code ec;
    fs::create_directories(xml.parent_path(), ec);
    if (ec) throw InputError("-o: cannot create the folder '" + xml.parent_path().string() + "': " + ec.message());
  }
  std::vector<fs::path> roots{results};
  for (const auto& d : a.assets) {
    if (!fs::is_directory(d)) throw InputError("--assets '" + d + "': not a folder");
    roots.emplace_back(d);
  }
  auto index = std::make_shared<HashIndex>(roots);
  AssetResolver assets;
  assets.baseDir = results;
  assets.byHash = [index](const std::string& h) { return index->find(h); };
  ResultsExport out;
  if (fs::is_directory(results)) {
    out = exportResults(results, xml, assets);
  } else {  // a job: its scene as described
    AssetResolver jobAssets;
    v1::JobSpec job = jobFromArgument(a.results, jobAssets);
    // The exported job sits beside the XML: its own asset paths (targets, initial meshes) follow it.
    const fs::path dir = fs::absolute(xml).parent_path();
    rebaseAssetPaths(job, fs::absolute(jobAssets.baseDir), dir);
    jobAssets.baseDir = dir;
    out = exportJob(job, xml, jobAssets);
  }
  for (const auto& n : out.notes) std::cerr << "note: " << n << "\n";
  std::cout << "wrote " << fs::absolute(xml).lexically_normal().string() << " (" << out.scene.files.size() - 1
            << " meshes and images beside it) and " << fs::absolute(out.job).lexically_normal().string()
            << " (the job over it); check with: invr render --scene " << xml.string() << " -o "
            << fs::path(xml).replace_extension(".png").string() << "\n";
}

}  // namespace

void addExportCommand(CLI::App& app, int& exitCode) {
  auto args = std::make_shared<ExportArgs>();
  auto* cmd = app.add_subcommand("export",
                                 "Write a results folder (run, fetch, optimize) as a Mitsuba 3 scene with the optimised values in it "
                                 "(meshes/*.ply in world space, textures/*.exr) and a job file over it; or a job (zoo name, job file) "
                                 "with its scene as described, the ground truth of a synthetic job (docs/mitsuba-import.md#export)");
  cmd->add_option("results", args->results,
                  "results folder (holds job.json and parameters.json), or a job: zoo scene name or job file (.json)")
      ->required();
  cmd->add_option("-o,--output", args->out, "the scene file to write (.xml); the job goes beside it as .json")->capture_default_str();
  cmd->add_option("--assets", args->assets,
                  "DIR: a folder holding the job's uploaded meshes and textures (found by content hash; repeatable); the results "
                  "folder is searched too")
      ->allow_extra_args(false);
  cmd->callback([args, &exitCode] {
    runExport(*args);
    exitCode = 0;
  });
}

}  // namespace invr::cli
