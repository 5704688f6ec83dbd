// The gradient of an image loss for material and light parameters (the interior term of Wang et
// al. 2023, Eq. 12-13), with one of the interior estimators of interior_estimator.h:
//   pt      one light sample (by power) + BSDF sampling with MIS, any path length  (baseline B.1)
//   ris     streaming RIS over M candidates                                       (baseline B.2)
//   restir  RIS + reuse of the previous step's reservoirs (Alg. 3-4, 7-8)
//
// Each step runs two independent passes: a primal pass renders I (for dL/dI) and a derivative
// pass samples fresh paths and backpropagates dL/dI through them (radiative backpropagation,
// Eq. 16: pdfs, visibility and RIS weights detached). Independence makes the product
// dL/dI * dI/dtheta unbiased for the L2 losses, and the two renders give an unbiased loss,
// (I1 - T)(I2 - T). With restir the two passes keep separate reservoir chains for the same reason;
// "forward only" uses ReSTIR in the primal pass and plain RIS in the derivative pass.
//
// The scene is read-only here: whoever owns it writes theta before evaluate() and never during.
#pragma once

#include <atomic>
#include <map>
#include <memory>
#include <vector>

#include "core/diff/gradient_options.h"
#include "core/geometry/edge_topology.h"
#include "core/diff/boundary_state.h"
#include "core/diff/parameters.h"
#include "core/diff/sample_drops.h"
#include "invr/v1/stats.pb.h"

namespace invr {

// The random streams of the engine's own passes (pixel samplers and boundary terms name theirs).
inline constexpr StreamId kPrimalStream{1};       // primal pass of a gradient step
inline constexpr StreamId kDerivativeStream{2};   // derivative pass (independent of the primal one)
inline constexpr StreamId kVarianceStream{10};    // variance pass of a variance-aware step (Yan et al. 2024)
inline constexpr StreamId kVarianceMapStream{11}; // the per-pixel variance maps of a variance-aware job's results

struct GradientRequest {
  std::vector<int> views;  // the mini-batch
  uint64_t step = 0;
  uint64_t seed = 0;
  bool renderOnly = false;   // burn-in (§7): advance the reservoirs, no loss or gradient
  // Views in the whole mini-batch when `views` is one shard of it (the loss is a mean over the
  // batch's views, so shard gradients add up); 0 means views.size().
  int batchViews = 0;
  // The request holds every view whose reservoirs live in the session (lets Alg. 8 skip its
  // visibility test); false is always safe.
  bool allSessionViews = false;
  // Checked per 16x16 tile of every pass: when it becomes true, evaluate() throws
  // EvaluationCancelled.
  const std::atomic<bool>* cancel = nullptr;
  // Set: a derivative image instead of a loss gradient (`invr-lab bench derivative-images`). The
  // request holds one view; dL/dI is 1/3 in every pixel and channel, so the sink receives, per
  // pixel, d(mean of the pixel's channels)/d theta_index from the derivative pass and every
  // boundary term (the result's gradient holds their sums). No primal pass, no loss, no targets,
  // every pixel (no mini-batch); ReSTIR advances the derivative pass's reservoir chain as a step
  // does. The sink's image is (re)sized to the film and zeroed here.
  PixelDerivativeSink* derivativeImage = nullptr;
  // With derivativeImage: dL/dI per pixel and channel instead of 1/3 (the sink then holds each
  // pixel's samples weighted by it; tests check that every sample lands where it is weighed).
  const Image* derivativeWeights = nullptr;
};


struct GradientResult {
  std::vector<double> gradient;  // d loss / d theta, one entry per parameter value
  invr::v1::GradientStats stats;  // what the evaluation computed (proto/invr/v1/stats.proto)
  std::vector<Image> renders;    // primal image per requested view
  std::vector<Image> variances;  // variance-aware jobs: per requested view, the per-pixel variance estimate
};

// Per-job state that survives between steps (the worker's session cache): reservoir chains.
struct EngineSession {
  ReservoirStore primal, derivative;
  BoundaryStateSlots boundary;  // what each boundary term keeps, by its name (edge reservoirs: Alg. 6)
  std::map<int, PixelMap> pixelMaps;  // per view: the pixel-sampling probabilities
  std::map<int, Stage1> stage1History;  // per view: the stage-1 moments the maps are built from
};

class GradientScratchPool;

class GradientEngine {
 public:
  // targets[v] is the image view v should reproduce (may be empty for views never requested).
  // The options are a job's, validated with the scene and parameters when it was built
  // (validateGradientJob): the engine keeps invariants only.
  GradientEngine(const Scene& scene, const ParameterRegistry& params, std::vector<Image> targets, GradientOptions options);
  ~GradientEngine();

  // Estimates the gradient at the parameters the scene holds now.
  GradientResult evaluate(const GradientRequest& request, EngineSession& session);
  const GradientOptions& options() const { return opt_; }
  // Stage 1 of pixel sampling for one view, on its own (benchmarks build reference maps from many).
  Stage1 measureStage1(int view, const GradientRequest& request);
  // The per-pixel variance of one camera sample of the job's estimator at the current parameters
  // (sampling parameters included), from `spp` >= 2 independent samples per pixel with Bessel's
  // correction (Yan et al. 2024, Eq. 9). A result map of variance-aware jobs.
  Image sampleVarianceMap(int view, int spp, uint64_t seed, const std::atomic<bool>* cancel = nullptr);

  // The boundary terms this engine runs (shape parameters), in run order.
  const std::vector<const BoundaryTermKind*>& boundaryTerms() const { return boundaryTerms_; }

 private:
  struct Step;  // one evaluation's working state (gradient_engine.cc)
  // The phases of evaluate(), in order.
  void prepareReservoirs(Step& s);
  void drawPixelBatches(Step& s);
  void primalPass(Step& s);
  void derivativePass(Step& s);
  void boundaryPasses(Step& s);
  void variancePass(Step& s);
  void storeReservoirs(Step& s);
  Stage1 runStage1(int view, const GradientRequest& req, SampleDrops& drops);
  // The loss mask of a view (opt_.lossMasks), or null when it has none.
  const std::vector<float>* maskOf(int view) const {
    return size_t(view) < opt_.lossMasks.size() && !opt_.lossMasks[size_t(view)].empty() ? &opt_.lossMasks[size_t(view)] : nullptr;
  }

  const Scene& scene_;
  const ParameterRegistry& params_;
  std::vector<Image> targets_;
  GradientOptions opt_;
  std::unique_ptr<GradientScratchPool> scratch_;
  std::vector<EdgeTopology> topology_;  // per mesh, when shape parameters move any (rigid motion keeps it valid)
  std::vector<const BoundaryTermKind*> boundaryTerms_;
};

// True if the surface point p is inside camera's frustum and not occluded from it.
bool visibleFromCamera(const Scene& scene, const Camera& camera, Vec3 p, Vec3 n);

}  // namespace invr
