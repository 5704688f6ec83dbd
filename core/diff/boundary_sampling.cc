#include "core/diff/boundary_sampling.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <mutex>

#include "core/error.h"

namespace invr {

FilmCrossing radianceJump(const Scene& scene, const InteriorEstimator& estimator, const Camera& cam, FilmPoint x, Vec2 n, double eps,
                          const Sampler& sampler, SampleCounters& counters) {
  const int W = scene.width, H = scene.height;
  FilmCrossing c;
  c.px = std::clamp(int(x.x), 0, W - 1);
  c.py = std::clamp(int(x.y), 0, H - 1);
  Rgb side[2];
  for (int k = 0; k < 2; ++k) {
    const double sign = k == 0 ? -1.0 : 1.0;
    CameraSampleInput in;
    in.x = c.px;
    in.y = c.py;
    in.pixel = uint64_t(c.py) * uint64_t(W) + uint64_t(c.px);
    in.o = cam.eye;
    in.d = filmDirectionPrecise(cam, x.x + sign * eps * double(n.x), x.y + sign * eps * double(n.y), W, H);
    Sampler sideSampler = sampler.fork(0);  // common random numbers for the two sides
    side[k] = estimator.sample(in, sideSampler, counters, Rgb(0.f), nullptr, nullptr);
  }
  c.jump = side[0] - side[1];
  return c;
}

void runBoundarySamples(int samples, GradientScratchPool& scratchPool, std::vector<double>& gradient, const std::atomic<bool>* cancel,
                        BoundaryPassStats& st, const std::function<void(int, SampleCounters&, PathGradient&)>& body,
                        PixelDerivativeSink* pixels) {
  if (samples <= 0) return;
  constexpr int kChunk = 64;
  const int chunks = (samples + kChunk - 1) / kChunk;
  std::vector<TileGradient> tiles(static_cast<size_t>(chunks));
  // A derivative image: each chunk's (pixel, derivative) in sample order, added in chunk order.
  std::vector<std::vector<std::pair<uint64_t, double>>> chunkPixels(pixels ? size_t(chunks) : 0);
  std::mutex mergeMutex;
  std::atomic<bool> cancelled{false};
  tbb::parallel_for(tbb::blocked_range<int>(0, chunks), [&](const tbb::blocked_range<int>& range) {
    SampleCounters counters;
    uint64_t dropped = 0;
    PathGradient grad;
    GradientScratch& scratch = scratchPool.local();
    for (int chunk = range.begin(); chunk < range.end(); ++chunk) {
      if (cancelled.load(std::memory_order_relaxed) || (cancel && cancel->load(std::memory_order_relaxed))) {
        cancelled = true;
        break;
      }
      for (int i = chunk * kChunk; i < std::min(samples, (chunk + 1) * kChunk); ++i) {
        body(i, counters, grad);
        if (!grad.finiteFrom(0)) {
          ++dropped;
          grad.clear();
          continue;
        }
        if (pixels) {
          const double d = grad.sumOf(pixels->index);
          INVR_INVARIANT(d == 0.0 || grad.pixel() < pixels->image.size(), "a boundary sample's derivative names no film pixel");
          if (d != 0.0) chunkPixels[size_t(chunk)].emplace_back(grad.pixel(), d);
        }
        scratch.commit(grad);
      }
      scratch.flush(tiles[size_t(chunk)]);
    }
    std::lock_guard lock(mergeMutex);
    st.rays += counters.rays;
    st.dropped += dropped;
  });
  if (cancelled) throw EvaluationCancelled{};
  for (auto& t : tiles) t.reduceInto(gradient);
  for (const auto& chunk : chunkPixels)
    for (const auto& [pixel, d] : chunk) pixels->image[size_t(pixel)] += d;
  st.samples = uint64_t(samples);
}

}  // namespace invr
