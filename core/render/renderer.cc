#include "core/render/renderer.h"

#include <tbb/blocked_range.h>
#include <tbb/blocked_range2d.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>

#include "core/error.h"
#include "core/math/rng.h"
#include "core/io/job_io.h"
#include "core/render/path_tracer.h"
#include "core/stopwatch.h"

namespace invr {

RenderResult renderView(const Scene& scene, int view, const RenderOptions& opt,
                        const std::function<void(double)>& progress) {
  if (view < 0 || size_t(view) >= scene.cameras.size())
    throw InputError("view " + std::to_string(view) + " out of range (scene has " + std::to_string(scene.cameras.size()) + " views)");
  if (opt.spp <= 0) throw InputError("spp must be positive (got " + std::to_string(opt.spp) + ")");
  if (!scene.accelerated()) throw std::logic_error("renderView: the scene was built for validation only (no BVH)");
  const Stopwatch clock;
  const int W = scene.width, H = scene.height;
  const Camera& cam = scene.cameras[size_t(view)];
  RenderResult res;
  res.image = Image(W, H, 3);
  tbb::combinable<RayStats> stats;
  tbb::combinable<uint64_t> nonFinite([] { return uint64_t(0); });
  constexpr int kTile = 16;
  int x0 = 0, y0 = 0, x1 = W, y1 = H;
  if (!opt.window.empty()) {
    x0 = std::clamp(opt.window.x0, 0, W), x1 = std::clamp(opt.window.x1, x0, W);
    y0 = std::clamp(opt.window.y0, 0, H), y1 = std::clamp(opt.window.y1, y0, H);
  }
  std::atomic<size_t> pixelsDone{0};
  std::mutex progressMutex;

  std::atomic<bool> cancelled{false};
  tbb::parallel_for(tbb::blocked_range2d<int>(y0, y1, kTile, x0, x1, kTile), [&](const tbb::blocked_range2d<int>& r) {
    if (cancelled.load(std::memory_order_relaxed) || (opt.cancel && opt.cancel->load(std::memory_order_relaxed))) {
      cancelled = true;
      return;
    }
    RayStats& st = stats.local();
    uint64_t& bad = nonFinite.local();
    PathContext ctx{&st};
    // The range's camera rays are queued in the order their samples are taken (pixel by pixel,
    // sample by sample), traced together as packets (core/geometry/ray_queue.h), then walked in
    // that order; each sampler's first draw (the film position) is taken when its ray is queued,
    // so the walk continues the same stream.
    CameraRayQueue queue;
    Sampler samplers[CameraRayQueue::kCapacity];
    int queuedX[CameraRayQueue::kCapacity], queuedY[CameraRayQueue::kCapacity], queuedSample[CameraRayQueue::kCapacity];
    const int rx0 = r.cols().begin(), rx1 = r.cols().end(), ry1 = r.rows().end();
    int nextX = rx0, nextY = r.rows().begin(), nextSample = 0;  // the next camera sample to queue
    uint64_t pixelHash = 0;                                      // its pixel's
    double acc[3] = {0, 0, 0};                                   // the pixel being walked
    uint64_t taken = 0;
    while (nextY < ry1) {
      // Every 256 camera samples: TBB hands out chunks far larger than a tile, and one pixel at a
      // target's spp can be a second of work under a sanitizer.
      if ((taken++ & 3) == 0 && opt.cancel && opt.cancel->load(std::memory_order_relaxed)) {
        cancelled = true;
        return;
      }
      queue.clear();
      int n = 0;
      while (nextY < ry1 && !queue.full()) {
        if (nextSample == 0) pixelHash = RngKey{opt.seed, 0, uint64_t(view), uint64_t(nextY) * uint64_t(W) + uint64_t(nextX), 0}.pixelHash();
        samplers[n] = Sampler::forSample(opt.sampler, pixelHash, uint64_t(nextSample));
        const Vec2 film = samplers[n].next2D();
        queuedX[n] = nextX, queuedY[n] = nextY, queuedSample[n] = nextSample;
        queue.push(cam.eye, cam.direction(float(nextX) + film.x, float(nextY) + film.y, W, H));
        ++n;
        if (++nextSample < opt.spp) continue;
        nextSample = 0;
        if (++nextX == rx1) nextX = rx0, ++nextY;
      }
      queue.trace(scene.accel);
      for (int i = 0; i < n; ++i) {
        const PrimaryHit primary = scene.primaryHit(queue, i);
        Rgb L = pathRadiance(scene, queue.origin(i), queue.direction(i), samplers[i], opt, &ctx, &primary);
        if (!isFinite(L)) {
          ++bad;
        } else {
          acc[0] += L.x; acc[1] += L.y; acc[2] += L.z;
        }
        if (queuedSample[i] + 1 < opt.spp) continue;
        res.image.setRgb(queuedX[i], queuedY[i], Rgb(float(acc[0] / opt.spp), float(acc[1] / opt.spp), float(acc[2] / opt.spp)));
        acc[0] = acc[1] = acc[2] = 0;
      }
    }
    size_t done = pixelsDone.fetch_add(r.rows().size() * r.cols().size()) + r.rows().size() * r.cols().size();
    if (progress) {
      std::lock_guard lock(progressMutex);
      progress(double(done) / (double(x1 - x0) * double(y1 - y0)));
    }
  });
  if (cancelled) throw EvaluationCancelled{};
  stats.combine_each([&](const RayStats& s) { res.rays += s; });
  nonFinite.combine_each([&](uint64_t n) { res.nonFiniteSamples += n; });
  res.seconds = clock.seconds();
  return res;
}

Aovs renderAovs(const Scene& scene, int view) {
  if (view < 0 || size_t(view) >= scene.cameras.size()) throw InputError("view " + std::to_string(view) + " out of range");
  const int W = scene.width, H = scene.height;
  const Camera& cam = scene.cameras[size_t(view)];
  Aovs out{Image(W, H, 3), Image(W, H, 3), Image(W, H, 1)};
  tbb::parallel_for(tbb::blocked_range<int>(0, H), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y)
      for (int x = 0; x < W; ++x) {
        SurfaceHit hit;
        if (!scene.intersect(cam.eye, cam.direction(float(x) + 0.5f, float(y) + 0.5f, W, H), hit)) continue;
        Bsdf b = scene.materials[size_t(scene.meshMaterial[hit.mesh])].at(hit.uv);
        Rgb albedo = b.kind == BsdfKind::Diffuse || b.kind == BsdfKind::RoughPlastic ? b.albedo
                     : b.kind == BsdfKind::Mirror                                     ? b.reflectance
                                                                                      : Rgb(1.f);
        out.albedo.setRgb(x, y, albedo);
        out.normal.setRgb(x, y, hit.ns);
        out.depth.at(x, y, 0) = hit.t;
      }
  });
  return out;
}

RenderOptions renderOptionsFrom(const invr::v1::RenderSettings& r) {
  validateRenderSettings(r);
  RenderOptions o;
  o.spp = r.spp() > 0 ? r.spp() : 16;
  o.maxDepth = r.max_depth() > 0 ? r.max_depth() : 1;
  o.estimator = r.estimator() == invr::v1::ESTIMATOR_RIS ? LightEstimator::Ris : LightEstimator::NeeMis;
  o.risCandidates = r.ris_candidates() > 0 ? r.ris_candidates() : 8;
  o.risVisibilityInTarget = r.ris_visibility_in_target();
  o.russianRouletteDepth = r.russian_roulette_depth() > 0 ? r.russian_roulette_depth() : 3;
  o.seed = r.seed();
  o.sampler = samplerKindFromName(r.sampler(), "render.sampler");
  return o;
}

}  // namespace invr
