// invr-lab bench ...: benchmarks that print their figures (ratios measured in one run).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <functional>
#include <iostream>
#include <memory>

#include "client/common/bench_report.h"
#include "client/lab/embree_replay.h"
#include "client/lab/lab_commands.h"
#include "core/error.h"
#include "core/render/renderer.h"
#include "core/scene/scene_builder.h"
#include "core/scene/zoo.h"

namespace invr::cli {

namespace {

struct RaysArgs {
  std::string scene = "cornell";
  int resolution = 256;
  int spp = 4;
  int repeats = 5;
  bool json = false;
};

void runBenchRays(const RaysArgs& a) {
  if (a.resolution <= 0 || a.spp <= 0 || a.repeats <= 0) throw InputError("bench rays: --resolution, --spp and --repeats must be positive");
  auto spec = zooScene(a.scene);
  spec.mutable_film()->set_width(a.resolution);
  spec.mutable_film()->set_height(a.resolution);
  auto scene = buildScene(spec);
  RenderOptions opt;
  opt.spp = a.spp;
  opt.maxDepth = 1;  // direct illumination, NEE + MIS
  std::vector<LoggedRay> rays;
  RenderResult recorded;
  {
    RayLog log;
    scene->observeRays(&log);
    recorded = renderView(*scene, 0, opt);
    scene->observeRays(nullptr);
    rays = log.take();
  }
  // Embree's modes on the same rays, split by kind (camera, bounce, shadow), each kind's rays in
  // render order: single rays, packets of 4, 8 and 16, streams. The renderer and the replays are
  // interleaved and each keeps its best run: the machine is shared.
  const std::vector<RayGroup> groups = groupRays(rays, {scene->cameras[0].eye});
  const std::vector<ReplayMode>& modes = replayModes();
  ReplayTimes times;
  double bestRenderer = 1e30, bestEmbree = 1e30;
  uint64_t rendererRays = 0, hits = 0;
  for (int i = 0; i < a.repeats; ++i) {
    RenderResult r = renderView(*scene, 0, opt);
    bestRenderer = std::min(bestRenderer, r.seconds);
    rendererRays = r.rays.total();
    bestEmbree = std::min(bestEmbree, replayInOrder(rays, hits));
    replayOnce(groups, times);
  }
  // The log holds every Embree query the render made: exactly the rays the renderer counts.
  if (rendererRays != rays.size() || recorded.rays.total() != rays.size())
    throw std::runtime_error("bench rays: the renderer counted " + std::to_string(rendererRays) + " rays, the log holds " + std::to_string(rays.size()));
  double embreeRate = double(rays.size()) / bestEmbree, rendererRate = double(rendererRays) / bestRenderer;
  BenchReport rep("rays");
  rep.text("scene", a.scene);
  rep.number("resolution", a.resolution);
  rep.number("spp", a.spp);
  rep.number("rays_per_run", double(rays.size()));
  rep.number("shadow_rays_per_run", double(recorded.rays.shadow));
  rep.number("camera_rays_per_run", double(recorded.rays.camera));
  rep.number("bounce_rays_per_run", double(recorded.rays.bounce));
  rep.number("embree_rays_per_s", embreeRate, "rays/s (bare rtcIntersect1 + rtcOccluded1, in render order)");
  rep.number("renderer_rays_per_s", rendererRate, "rays/s (direct illumination, NEE + MIS, shading included)");
  rep.number("ratio", rendererRate / embreeRate, "(renderer / bare Embree single rays; target >= 0.8)");
  // Each mode over all kinds, and each kind's fastest mode; the bound takes the fastest per kind.
  for (size_t m = 0; m < modes.size(); ++m)
    rep.number(std::string("embree_") + modes[m].name + "_rays_per_s", double(rays.size()) / times.modeSeconds(m),
               std::string("rays/s (") + modes[m].what + ", by kind)");
  for (size_t g = 0; g < groups.size(); ++g) rep.text("embree_best_mode_" + groups[g].kind, modes[times.fastestMode(g)].name);
  rep.number("embree_best_rays_per_s", double(rays.size()) / times.boundSeconds(), "rays/s (each kind in its fastest mode)");
  rep.number("ratio_best", rendererRate * times.boundSeconds() / double(rays.size()), "(renderer / Embree at its best on the same rays)");
  rep.print(a.json);
}

}  // namespace

void addBenchCommand(CLI::App& app, int& exitCode) {
  auto* bench = app.add_subcommand("bench", "Benchmarks (print figures; --json for one JSON object)");
  bench->require_subcommand(1);
  auto args = std::make_shared<RaysArgs>();
  auto* rays = bench->add_subcommand("rays", "Renderer ray throughput against a bare Embree loop on the same rays");
  rays->add_option("--scene", args->scene, "zoo scene")->capture_default_str();
  rays->add_option("--resolution", args->resolution, "square image size")->capture_default_str();
  rays->add_option("--spp", args->spp, "samples per pixel")->capture_default_str();
  rays->add_option("--repeats", args->repeats, "timed runs of each (best kept)")->capture_default_str();
  rays->add_flag("--json", args->json, "print one JSON object");
  rays->callback([args, &exitCode] {
    runBenchRays(*args);
    exitCode = 0;
  });
  addBenchGradientCommands(*bench, exitCode);
  addBenchServiceCommand(*bench, exitCode);
  addBenchFakeWorkerCommand(*bench, exitCode);
  addBenchPixelCommand(*bench, exitCode);
  addBenchVarianceCommand(*bench, exitCode);
  addBenchSamplerCommand(*bench, exitCode);
  addBenchStepCommand(*bench, exitCode);
  addBenchScaleCommand(*bench, exitCode);
  addBenchGradientVectorCommand(*bench, exitCode);
  addBenchDerivativeImagesCommand(*bench, exitCode);
}

}  // namespace invr::cli
