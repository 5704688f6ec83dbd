#include "core/diff/pass_driver.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <mutex>

#include "core/error.h"

namespace invr {

struct GradientScratchPool::Impl {
  tbb::enumerable_thread_specific<GradientScratch> local;
};
GradientScratchPool::GradientScratchPool(size_t parameters) : impl_(new Impl{tbb::enumerable_thread_specific<GradientScratch>(GradientScratch(parameters))}) {}
GradientScratchPool::~GradientScratchPool() = default;
GradientScratch& GradientScratchPool::local() { return impl_->local.local(); }

namespace {

// Squared norm of one sample's derivative, entries of the same parameter summed first.
double squaredNorm(std::vector<std::pair<uint32_t, float>> entries) {
  std::sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  double sq = 0, run = 0;
  for (size_t i = 0; i < entries.size(); ++i) {
    run += double(entries[i].second);
    if (i + 1 == entries.size() || entries[i + 1].first != entries[i].first) {
      sq += run * run;
      run = 0;
    }
  }
  return sq;
}

}  // namespace

PassOutput runPass(const Scene& scene, const InteriorEstimator& estimator, const PassSpec& spec, GradientScratchPool& scratchPool,
                   std::vector<double>* gradient) {
  const int W = scene.width, H = scene.height;
  const int spp = spec.spp;
  const Camera& cam = scene.cameras[size_t(spec.view)];
  const bool variance = spec.kind == PassKind::Variance;
  // Both add weighted derivatives into the gradient.
  const bool derivative = spec.kind == PassKind::Derivative || variance, stage1 = spec.kind == PassKind::Stage1;
  if (derivative && (!gradient || !spec.adjoint)) throw std::logic_error("runPass: a derivative pass needs an adjoint and a gradient");
  if (variance && !spec.mean) throw std::logic_error("runPass: a variance pass needs the primal render");
  constexpr int kTile = 16;
  const int tilesX = (W + kTile - 1) / kTile, tilesY = (H + kTile - 1) / kTile;
  std::vector<TileGradient> tiles(derivative ? size_t(tilesX) * size_t(tilesY) : 0);
  PassOutput res;
  res.image = Image(W, H, 3);
  if (stage1) res.derivSq.assign(size_t(W) * size_t(H), 0.f);
  const bool squares = variance || spec.squares;
  if (squares) res.secondMoment = Image(W, H, 3);
  std::mutex mergeMutex;
  std::atomic<bool> cancelled{false};
  const SamplerKind samplerKind = estimator.stratifiable() ? spec.sampler : SamplerKind::Independent;

  tbb::parallel_for(tbb::blocked_range<int>(0, tilesX * tilesY), [&](const tbb::blocked_range<int>& range) {
    SampleCounters counters;
    SampleDrops drops;
    PathGradient pixelGrad;  // every kept sample of the current pixel
    GradientScratch* scratch = derivative ? &scratchPool.local() : nullptr;
    // The camera wavefront: a tile's pixels in order, their camera samples queued in the order they
    // are taken (pixel by pixel, sample by sample), traced together as packets, then shaded in
    // that order. Each sample's sampler is created and its film position drawn when it is queued:
    // the same first draw as before, so the walk continues the same stream.
    struct TilePixel {
      int x, y;
      uint64_t pixel, hash;
      int samples;
      StoredReservoir* slots;
    };
    struct Queued {
      int pixel = 0;  // index into the tile's pixels
      int sample = 0;
      Sampler sampler;
    };
    TilePixel pixels[kTile * kTile];
    CameraRayQueue queue;
    Queued queued[CameraRayQueue::kCapacity];
    // The pixel being shaded (its samples may straddle two batches).
    Rgb adjoint(0.f);
    double acc[3] = {0, 0, 0}, acc2[3] = {0, 0, 0};
    int kept = 0;
    VarianceWeights vw;
    for (int tile = range.begin(); tile < range.end(); ++tile) {
      // Cancellation is checked per 16x16 tile (TBB's chunks hold many tiles).
      if (cancelled.load(std::memory_order_relaxed) || (spec.cancel && spec.cancel->load(std::memory_order_relaxed))) {
        cancelled = true;
        break;
      }
      const int tx = tile % tilesX, ty = tile / tilesX;
      int count = 0;
      for (int y = ty * kTile; y < std::min(H, (ty + 1) * kTile); ++y)
        for (int x = tx * kTile; x < std::min(W, (tx + 1) * kTile); ++x) {
          const uint64_t pixel = uint64_t(y) * uint64_t(W) + uint64_t(x);
          StoredReservoir* slots = spec.reservoirs ? spec.reservoirs + size_t(pixel) * size_t(spp) : nullptr;
          if (slots)  // every slot is written: the buffer is recycled from an older step
            for (int s = 0; s < spp; ++s) slots[s].mesh = UINT32_MAX;
          if (spec.batch && !spec.batch->contains(size_t(pixel))) continue;  // not in this mini-batch
          // A pixel drawn c times into the mini-batch gets c times the samples, each on a stream of
          // its own (see PixelBatch); only the first draw's reservoirs are stored.
          const int samples = spp * int(spec.batch ? spec.batch->draws[size_t(pixel)] : 1u);
          if (samples <= 0) continue;
          pixels[count++] = {x, y, pixel, RngKey{spec.stream, spec.step, uint64_t(spec.view), pixel, 0}.pixelHash(), samples, slots};
        }
      int nextPixel = 0, nextSample = 0;  // the next camera sample to queue
      while (nextPixel < count) {
        queue.clear();
        int n = 0;
        while (nextPixel < count && !queue.full()) {
          const TilePixel& tp = pixels[nextPixel];
          Queued* q = &queued[n++];
          *q = Queued{nextPixel, nextSample, Sampler::forSample(samplerKind, tp.hash, uint64_t(nextSample))};
          const Vec2 film = q->sampler.next2D();  // y drawn first: the independent streams' order before 2D draws
          queue.push(cam.eye, cam.direction(float(tp.x) + film.y, float(tp.y) + film.x, W, H));
          if (++nextSample == tp.samples) {
            nextSample = 0;
            ++nextPixel;
          }
        }
        queue.trace(scene.accel);
        for (int i = 0; i < n; ++i) {
          const TilePixel& tp = pixels[queued[i].pixel];
          const int sample = queued[i].sample;
          const int x = tp.x, y = tp.y;
          if (sample == 0) {  // a new pixel
            adjoint = derivative ? spec.adjoint->rgb(x, y) / float(tp.samples) : stage1 ? Rgb(1.f) : Rgb(0.f);
            acc[0] = acc[1] = acc[2] = 0;
            acc2[0] = acc2[1] = acc2[2] = 0;
            kept = 0;
            if (variance) {
              vw.mean = spec.mean->rgb(x, y);
              vw.adjoint = adjoint;
              vw.detached = spec.detached;
            }
          }
          PathGradient* grad = derivative || stage1 ? &pixelGrad : nullptr;
          const PrimaryHit primary = scene.primaryHit(queue, i);
          CameraSampleInput in;
          in.x = x;
          in.y = y;
          in.pixel = tp.pixel;
          in.slot = sample % spp;
          in.o = queue.origin(i);
          in.d = queue.direction(i);
          in.primary = &primary;
          Sampler& sampler = queued[i].sampler;
          const size_t mark = pixelGrad.size();
          Rgb v = variance ? estimator.varianceSample(in, sampler, counters, vw, pixelGrad)
                           : estimator.sample(in, sampler, counters, adjoint, grad, tp.slots && sample < spp ? &tp.slots[in.slot] : nullptr);
          if (!isFinite(v) || (grad && !pixelGrad.finiteFrom(mark))) {
            ++(spec.kind == PassKind::Primal ? drops.primal : variance ? drops.variance : derivative ? drops.derivative : drops.stage1);
            pixelGrad.truncate(mark);
          } else {
            ++kept;
            acc[0] += v.x; acc[1] += v.y; acc[2] += v.z;
            if (squares) {
              acc2[0] += double(v.x) * v.x; acc2[1] += double(v.y) * v.y; acc2[2] += double(v.z) * v.z;
            }
            if (stage1) {  // one sample's squared derivative norm (one sample per cell)
              res.derivSq[size_t(tp.pixel)] += float(squaredNorm(pixelGrad.entries()));
              pixelGrad.clear();
            }
          }
          if (sample + 1 < tp.samples) continue;
          // The pixel's last sample.
          if (kept > 0) res.image.setRgb(x, y, Rgb(float(acc[0] / kept), float(acc[1] / kept), float(acc[2] / kept)));
          if (kept > 0 && squares) res.secondMoment.setRgb(x, y, Rgb(float(acc2[0] / kept), float(acc2[1] / kept), float(acc2[2] / kept)));
          // The adjoint was split over all samples; the kept ones carry the whole pixel.
          const float carry = kept > 0 ? float(tp.samples) / float(kept) : 0.f;
          if (derivative && spec.pixels) spec.pixels->image[size_t(tp.pixel)] += double(carry) * pixelGrad.sumOf(spec.pixels->index);
          if (derivative) scratch->commit(pixelGrad, carry);
          INVR_INVARIANT(pixelGrad.size() == 0, "a pixel's derivatives outlived it");
          for (int s = 0; tp.slots && s < spp; ++s)
            INVR_INVARIANT(tp.slots[s].mesh == UINT32_MAX || tp.slots[s].mesh < scene.meshes.size(), "a reservoir slot holds no valid anchor");
        }
      }
      if (derivative) scratch->flush(tiles[size_t(tile)]);
    }
    std::lock_guard lock(mergeMutex);  // integer counters: order does not matter
    res.rays += counters.rays;
    res.drops += drops;
    res.restir.neighboursUsed += counters.restir.neighboursUsed;
    res.restir.shadingPoints += counters.restir.shadingPoints;
    res.restir.sumM += counters.restir.sumM;
  });
  if (cancelled) throw EvaluationCancelled{};
  if (derivative)
    for (auto& t : tiles) t.reduceInto(*gradient);  // fixed tile order: deterministic for any thread count
  return res;
}

}  // namespace invr
