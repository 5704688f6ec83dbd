// Image-space pixel sampling for mini-batch gradients (Yan et al. 2025). A step draws N pixel
// samples per view from probabilities p_j and weights pixel j by count_j / (N p_j), so the
// mini-batch gradient equals the full-image gradient in expectation whatever p is, as long as
// every p_j > 0: a defensive mixture with uniform guarantees that even where the stage-1 estimate
// is unreliable (caustics). Each sampler is one file that registers itself:
//
//   all       every pixel, every step (no mini-batch)                              pixel_sampler.cc
//   uniform   p_j = 1 / P                                                          pixel_sampler.cc
//   loss_grad p_j ~ |dL/dI_j|                        (Su & Gkioulekas 2024)      loss_grad_sampler.cc
//   adaptive  p_j ~ sqrt(p_j1 p_j2) (Eq. 12): p_j1 from (dL/dI_j)^2, p_j2 from the per-path sum of
//             squared parameter derivatives (Eq. 16); over D resolution levels (Eq. 18)  adaptive_sampler.cc
//
// Stage 1 (the maps) runs on a sparse grid of pixels with one sample each, every `refreshEvery`
// steps; its values are upsampled and smoothed with an edge-aware (cross-bilateral) filter guided
// by the first-hit normal and albedo before they become probabilities.
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/math/rng.h"
#include "core/diff/sample_drops.h"
#include "core/math/sampling.h"
#include "invr/v1/job.pb.h"

namespace invr {

inline constexpr StreamId kStage1PrimalStream{3};      // stage 1: dL/dI on the sparse grid
inline constexpr StreamId kStage1DerivativeStream{4};  // stage 1: squared parameter derivatives
inline constexpr StreamId kPixelBatchStream{6};        // which pixels a step traces

class PixelSampler;
// The registered sampler of that name; throws InputError listing the names there are.
const PixelSampler& pixelSampler(const std::string& name);
// Every registered sampler, in the order they are listed (all, uniform, then the stage-1 maps).
const std::vector<const PixelSampler*>& pixelSamplers();

struct PixelSamplingOptions {
  const PixelSampler* sampler = &pixelSampler("all");
  int samplesPerView = 0;     // N: pixel samples drawn per view and step (0: a quarter of the pixels)
  float defensive = 0.2f;     // weight of the uniform component of the mixture
  int refreshEvery = 20;      // steps between stage-1 refreshes
  int stage1Stride = 2;       // stage 1 traces every stride-th pixel in x and y
  int levels = 4;             // D of Eq. 18 (adaptive)
  int stage1History = 1;      // stage-1 passes the maps average (accumulateStage1's window)
  int samplesFor(size_t pixels) const { return samplesPerView > 0 ? samplesPerView : std::max<int>(1, int(pixels / 4)); }
};

// optimization.pixel_sampler, pixel_samples, pixel_defensive and pixel_refresh for a film of
// `filmPixels`. Throws InputError naming the field.
PixelSamplingOptions parsePixelSamplingOptions(const invr::v1::OptimizationSpec& optimization, int filmPixels);

// Stage-1 measurements on the sparse grid (gw x gh cells, cell (i, j) at pixel
// (i*stride + stride/2, j*stride + stride/2)), and the guides for the edge-aware upsampling.
// Cells hold moments, means over the `passes` stage-1 passes folded in (one sample per cell and
// pass): samplers that square dL/dI need its mean square, not the square of its mean, which the
// noise would cancel from.
struct Stage1 {
  int gw = 0, gh = 0, stride = 1;
  std::vector<float> adjointAbs;  // per cell, 3 channels: mean |dL/dI| at the cell's pixel
  std::vector<float> adjointSq;   // per cell, 3 channels: mean (dL/dI)^2
  std::vector<float> derivSq;     // per cell: mean sum over the path's parameter derivatives squared
  std::vector<float> guide;       // full resolution, 6 per pixel: first-hit normal and albedo
  int width = 0, height = 0;
  int passes = 0;
};

// Folds a fresh pass (passes == 1) into `history`: a running mean over the first `window` passes,
// then an exponential mean giving the newest pass 1/window. The guide is the fresh pass's (the
// scene may have moved). A history of another grid, or none, restarts from the fresh pass.
void accumulateStage1(Stage1& history, const Stage1& fresh, int window);

// Per-view probabilities at full resolution (sum to 1, all > 0), ready to draw from, and when
// they were computed.
struct PixelMap {
  std::vector<float> p;
  Distribution1D dist;
  uint64_t computedAt = 0;
  bool valid() const { return !p.empty(); }
  void setProbabilities(std::vector<float> probabilities) {
    p = std::move(probabilities);
    dist = Distribution1D(p);
  }
};

// Cell values -> full-resolution non-negative map: nearest-cell upsampling, then a 5x5
// cross-bilateral filter guided by `guide` (edges of normals and albedo are kept).
std::vector<float> upsampleEdgeAware(const Stage1& s, const std::vector<float>& cells);

// The defensive mixture: (1 - defensive) * map / sum(map) + defensive / P. A map with no mass
// (all zero, non-finite) falls back to uniform.
std::vector<float> defensiveMixture(const std::vector<float>& map, float defensive, uint64_t* nonFinite = nullptr);

// A way of choosing a step's pixels. Samplers whose probabilities come from stage 1 return its
// per-cell values; the defensive mixture and the upsampling are shared (buildPixelMap).
class PixelSampler {
 public:
  virtual ~PixelSampler() = default;
  virtual const char* name() const = 0;
  // False: every pixel, every step (no mini-batch, no weights).
  virtual bool miniBatch() const { return true; }
  // True: probabilities from stage-1 statistics, refreshed every refreshEvery steps.
  virtual bool usesStage1() const { return false; }
  // Unnormalised probability per stage-1 cell (samplers that use stage 1).
  virtual std::vector<float> cellValues(const Stage1& s, const PixelSamplingOptions& o) const {
    (void)s, (void)o;
    return {};
  }
  // What the plan says it draws by (after "pixels: <name>").
  virtual std::string describe(const PixelSamplingOptions& o) const = 0;
  // Reads the sampler's own message of optimization.pixel_samplers (present only when this is the
  // job's sampler) into o, over the job-wide values already there. Throws InputError naming the
  // field. Default: the sampler has no options of its own.
  virtual void parseOptions(const invr::v1::PixelSamplerSpecs& specs, int filmPixels, PixelSamplingOptions& o) const {
    (void)specs, (void)filmPixels, (void)o;
  }
};

// The fields stage-1 samplers share (samples, defensive, refresh, stage1_stride) from their own
// message `field` (the field's name under optimization.pixel_samplers), over o's job-wide values.
template <class Spec>
void parseStage1SamplerSpec(const Spec& spec, const std::string& field, PixelSamplingOptions& o, int filmPixels);

// Registers a sampler; a file defines one at namespace scope. `order` places it in pixelSamplers().
// Throws std::logic_error for a name already registered.
struct RegisterPixelSampler {
  RegisterPixelSampler(int order, std::unique_ptr<PixelSampler> sampler);
};

std::vector<float> lossGradMap(const Stage1& s);                // loss_grad_sampler.cc
std::vector<float> adaptiveMap(const Stage1& s, int levels);    // adaptive_sampler.cc

// ", maps from the last K stage-1 passes" when the maps keep a history (for describe()).
std::string stage1HistoryNote(const PixelSamplingOptions& o);

// The sampler's probabilities from a stage-1 measurement (uniform ones for samplers without).
PixelMap buildPixelMap(const PixelSamplingOptions& o, const Stage1& s, uint64_t step, SampleDrops* drops = nullptr);

// A mini-batch of one view: per pixel, how many of the N draws chose it and its weight
// count_j / (N p_j) (both zero for pixels not drawn). Every draw gets paths of its own (Alg. 1
// traces a camera ray per drawn index): a pixel drawn c times is traced c times as often. Tracing
// it once and weighting by c instead would add the p-independent term sum_j Var(g_j), the
// full-image estimator's own path variance, which dilutes any sampler's gain (and penalises
// concentrated ones, whose pixels are drawn repeatedly).
struct PixelBatch {
  std::vector<float> weight;
  std::vector<uint32_t> draws;
  bool contains(size_t pixel) const { return draws[pixel] != 0; }
};

// Draws N pixel samples from the map with counter-based randomness.
PixelBatch drawPixelBatch(const PixelMap& map, int n, RngKey key);

}  // namespace invr
