// invr bench ...: benchmarks that print their figures (ratios measured in one run).
#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <iostream>
#include <memory>

#include "client/lab/bench_report.h"
#include "client/lab/lab_commands.h"
#include "core/error.h"
#include "core/render/renderer.h"
#include "core/scene/scene_builder.h"
#include "core/scene/zoo.h"
#include "core/stopwatch.h"

namespace invr::cli {

namespace {

struct RaysArgs {
  std::string scene = "cornell";
  int resolution = 256;
  int spp = 4;
  int repeats = 5;
  bool json = false;
};

double seconds(std::chrono::steady_clock::time_point t0) { return Stopwatch(t0).seconds(); }

// Replays the renderer's own rays through bare rtcIntersect1 / rtcOccluded1, in parallel with the
// same TBB scheduler the renderer uses. Returns seconds.
double replayRays(const Scene& scene, const std::vector<RayRecord>& rays, uint64_t& hits) {
  RTCScene handle = scene.accel.handle();
  std::atomic<uint64_t> hitCount{0};
  auto t0 = std::chrono::steady_clock::now();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    uint64_t local = 0;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const RayRecord& rr = rays[i];
      if (rr.shadow) {
        RTCRay ray{rr.o.x, rr.o.y, rr.o.z, 0.f, rr.d.x, rr.d.y, rr.d.z, 0.f, rr.tmax, 0xffffffffu, 0, 0};
        rtcOccluded1(handle, &ctx, &ray);
        local += ray.tfar < 0.f;
      } else {
        RTCRayHit rh;
        rh.ray = RTCRay{rr.o.x, rr.o.y, rr.o.z, 0.f, rr.d.x, rr.d.y, rr.d.z, 0.f, rr.tmax, 0xffffffffu, 0, 0};
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(handle, &ctx, &rh);
        local += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
      }
    }
    hitCount += local;
  });
  double s = seconds(t0);
  hits = hitCount;
  return s;
}

void runBenchRays(const RaysArgs& a) {
  if (a.resolution <= 0 || a.spp <= 0 || a.repeats <= 0) throw InputError("bench rays: --resolution, --spp and --repeats must be positive");
  auto spec = zooScene(a.scene);
  spec.mutable_film()->set_width(a.resolution);
  spec.mutable_film()->set_height(a.resolution);
  auto scene = buildScene(spec);
  RenderOptions opt;
  opt.spp = a.spp;
  opt.maxDepth = 1;  // direct illumination, NEE + MIS
  std::vector<RayRecord> rays;
  RenderResult recorded = renderView(*scene, 0, opt, {}, &rays);
  // Interleave the two measurements and keep each one's best run: the machine is shared.
  double bestRenderer = 1e30, bestEmbree = 1e30;
  uint64_t rendererRays = 0, hits = 0;
  for (int i = 0; i < a.repeats; ++i) {
    RenderResult r = renderView(*scene, 0, opt);
    bestRenderer = std::min(bestRenderer, r.seconds);
    rendererRays = r.rays.total();
    bestEmbree = std::min(bestEmbree, replayRays(*scene, rays, hits));
  }
  if (rendererRays != rays.size()) throw std::runtime_error("bench rays: ray count changed between runs");
  double embreeRate = double(rays.size()) / bestEmbree, rendererRate = double(rendererRays) / bestRenderer;
  BenchReport rep("rays");
  rep.text("scene", a.scene);
  rep.number("resolution", a.resolution);
  rep.number("spp", a.spp);
  rep.number("rays_per_run", double(rays.size()));
  rep.number("shadow_rays_per_run", double(recorded.rays.shadow));
  rep.number("embree_rays_per_s", embreeRate, "rays/s (bare rtcIntersect1 + rtcOccluded1)");
  rep.number("renderer_rays_per_s", rendererRate, "rays/s (direct illumination, NEE + MIS, shading included)");
  rep.number("ratio", rendererRate / embreeRate, "(renderer / bare Embree; target >= 0.5)");
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
}

}  // namespace invr::cli
