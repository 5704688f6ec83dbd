// The pass driver: one pass of an interior estimator over one view's pixels (all, or a pixel
// mini-batch). It owns what every estimator shares: the random stream of each camera sample
// (keyed by (stream, step, view, pixel, sample)), pixel averaging, the dropping and counting of
// non-finite samples (SampleDrops), the per-tile gradient accumulation reduced in tile order (the
// same sums for any thread count), where reservoirs are written, and cancellation.
#pragma once

#include <atomic>
#include <memory>
#include <vector>

#include "core/diff/interior_estimator.h"
#include "core/diff/pixel_sampler.h"
#include "core/diff/sample_drops.h"
#include "core/image/image.h"

namespace invr {

// What a pass does with derivatives.
enum class PassKind {
  Primal,       // radiance only
  Derivative,   // radiance, and adjoint * d/dtheta summed into the gradient
  Stage1,       // radiance, and per pixel the squared norm of one sample's d/dtheta (adjoint 1)
  Variance,     // radiance and its square, and the weighted variance derivative (Yan et al. 2024)
};

struct PassSpec {
  PassKind kind = PassKind::Primal;
  int view = 0;
  uint64_t stream = 0;  // streamSeed(job seed, which pass): passes never share random numbers
  uint64_t step = 0;
  int spp = 1;
  SamplerKind sampler = SamplerKind::Independent;  // how a pixel's samples relate (rng.h)
  const PixelBatch* batch = nullptr;  // null: every pixel once
  const Image* adjoint = nullptr;     // Derivative: dL/dI per pixel and channel; Variance: dL/dV
  const Image* mean = nullptr;        // Variance: an independent estimate of each pixel (the primal render)
  bool detached = false;              // Variance: the detached baseline (variance_visitor.h)
  bool squares = false;               // Primal: also the mean of the squared samples (secondMoment)
  StoredReservoir* reservoirs = nullptr;  // one slot per pixel sample (first draw), or null
  const std::atomic<bool>* cancel = nullptr;  // checked per 16x16 tile; raised: EvaluationCancelled
  PixelDerivativeSink* pixels = nullptr;      // Derivative: also each pixel's derivative of one value (a derivative image)
};

struct PassOutput {
  Image image;                 // the pass's radiance estimate per pixel (pixels outside the batch: 0)
  std::vector<float> derivSq;  // Stage1: per pixel
  Image secondMoment;          // Variance (and Primal with squares): the mean of the squared samples per pixel and channel
  SampleDrops drops;
  RayStats rays;
  RestirCounters restir;
};

// Per-thread dense accumulators, kept across passes (no allocation per pass).
class GradientScratchPool {
 public:
  explicit GradientScratchPool(size_t parameters);
  ~GradientScratchPool();
  GradientScratch& local();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Runs one pass. Derivative passes add into `gradient` (sized to the parameter count).
PassOutput runPass(const Scene& scene, const InteriorEstimator& estimator, const PassSpec& spec, GradientScratchPool& scratch,
                   std::vector<double>* gradient = nullptr);

}  // namespace invr
