#include <tbb/global_control.h>

#include <filesystem>
#include <iostream>
#include <memory>

#include "client/commands.h"
#include "client/common/job_argument.h"
#include "client/common/progress.h"
#include "core/error.h"
#include "core/io/job_io.h"
#include "core/render/renderer.h"
#include "core/scene/scene_builder.h"
#include "core/scene/zoo.h"

namespace invr::cli {

namespace {

struct RenderArgs {
  std::string scene;
  std::string output;
  int view = 0;
  int spp = 0;
  int maxDepth = 0;
  std::string estimator;
  std::string sampler;
  int risCandidates = 0;
  int threads = 0;
  long long seed = -1;
  bool aovs = false;
  SceneArgs sceneArgs;
};

void runRender(const RenderArgs& a) {
  std::unique_ptr<tbb::global_control> threads;
  if (a.threads > 0) threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(a.threads));
  AssetResolver assets;
  invr::v1::JobSpec job = jobFromArgument(a.scene, assets, a.sceneArgs);
  auto* r = job.mutable_render();
  if (a.spp != 0) r->set_spp(a.spp);
  if (a.maxDepth != 0) r->set_max_depth(a.maxDepth);
  if (a.risCandidates != 0) r->set_ris_candidates(a.risCandidates);
  if (a.seed >= 0) r->set_seed(uint64_t(a.seed));
  if (a.estimator == "pt") r->set_estimator(invr::v1::ESTIMATOR_PT);
  else if (a.estimator == "ris") r->set_estimator(invr::v1::ESTIMATOR_RIS);
  if (!a.sampler.empty()) r->set_sampler(a.sampler);
  if (a.spp < 0) throw InputError("--spp: must be positive (got " + std::to_string(a.spp) + ")");
  RenderOptions opt = renderOptionsFrom(*r);
  auto scene = buildJobScene(job, assets);
  if (a.view < 0 || size_t(a.view) >= scene->cameras.size())
    throw InputError("--view: " + std::to_string(a.view) + " out of range (scene '" + scene->name + "' has " +
                     std::to_string(scene->cameras.size()) + " views)");
  ProgressBar bar("render " + scene->name);
  RenderResult res = renderView(*scene, a.view, opt, [&](double f) { bar.update(f); });
  bar.finish();
  std::string ext = std::filesystem::path(a.output).extension().string();
  if (a.aovs) {
    if (ext != ".exr") throw InputError("--aovs: needs an .exr output (got '" + a.output + "')");
    Aovs aov = renderAovs(*scene, a.view);
    writeExrLayers(a.output, {{"", {"R", "G", "B"}, res.image},
                              {"albedo", {"R", "G", "B"}, aov.albedo},
                              {"normal", {"X", "Y", "Z"}, aov.normal},
                              {"depth", {"Z"}, aov.depth}});
  } else {
    writeImage(a.output, res.image);
  }
  std::cout << "wrote " << std::filesystem::absolute(a.output).string() << " (" << scene->width << "x" << scene->height
            << ", view " << a.view << ", " << opt.spp << " spp, " << (opt.estimator == LightEstimator::Ris ? "ris" : "pt")
            << ", max depth " << opt.maxDepth << ", " << samplerKindName(opt.sampler) << " sampler, " << res.seconds << " s, "
            << double(res.rays.total()) / res.seconds / 1e6 << " Mrays/s";
  if (res.nonFiniteSamples) std::cout << ", " << res.nonFiniteSamples << " non-finite samples dropped";
  std::cout << ")\n";
}

}  // namespace

void addRenderCommand(CLI::App& app, int& exitCode) {
  auto args = std::make_shared<RenderArgs>();
  auto* cmd = app.add_subcommand("render", "Render one view of a zoo scene, job file or Mitsuba 3 scene to an image");
  cmd->add_option("--scene", args->scene, "zoo scene name (see `invr zoo`), job file (.json) or Mitsuba 3 scene (.xml)")->required();
  cmd->add_option("-o,--output", args->output, "output image (.exr, .png or .hdr)")->required();
  cmd->add_option("--view", args->view, "camera view index")->capture_default_str();
  cmd->add_option("--spp", args->spp, "samples per pixel (default: the job's, else 16)");
  cmd->add_option("--max-depth", args->maxDepth, "path vertices after the camera; 1 = direct illumination");
  cmd->add_option("--estimator", args->estimator, "light sampling: pt (NEE + MIS) or ris (streaming RIS)")
      ->check(CLI::IsMember({"pt", "ris"}));
  cmd->add_option("--sampler", args->sampler, "how a pixel's samples relate: independent or sobol (Owen-scrambled Sobol; default: the job's, else independent)")
      ->check(CLI::IsMember({"independent", "sobol"}));
  cmd->add_option("--ris-candidates", args->risCandidates, "RIS candidates M (default 8)");
  cmd->add_option("--seed", args->seed, "random seed");
  cmd->add_option("--threads", args->threads, "worker threads (default: all cores)");
  cmd->add_flag("--aovs", args->aovs, "also write albedo, normal and depth layers (multi-layer .exr only)");
  addSceneArgs(cmd, args->sceneArgs, false);
  cmd->callback([args, &exitCode] {
    runRender(*args);
    exitCode = 0;
  });
}

void addZooCommand(CLI::App& app, int& exitCode) {
  auto* cmd = app.add_subcommand("zoo", "List the built-in scenes");
  cmd->callback([&exitCode] {
    for (const auto& e : zooEntries()) std::cout << "  " << e.name << std::string(10 - std::min<size_t>(9, e.name.size()), ' ') << e.description << "\n";
    exitCode = 0;
  });
}

}  // namespace invr::cli
