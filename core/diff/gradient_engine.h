// The gradient of an image loss for material and light parameters under direct illumination
// (the interior term of Wang et al. 2023, Eq. 12-13), with one of three light-sampling strategies:
//   pt      one light sample (by power) + BSDF sampling with MIS     (baseline B.1)
//   ris     streaming RIS over M candidates                         (baseline B.2)
//   restir  RIS + reuse of the previous step's reservoirs (Alg. 3-4, 7-8)
//
// Each step runs two independent passes: a primal pass renders I (for the loss and dL/dI) and a
// derivative pass samples fresh paths and backpropagates dL/dI through them (radiative
// backpropagation, Eq. 16: pdfs, visibility and RIS weights detached). Independence makes the
// product dL/dI * dI/dtheta unbiased for the L2 losses. With restir the two passes keep separate
// reservoir chains for the same reason; "forward only" uses ReSTIR in the primal pass and plain RIS
// in the derivative pass.
#pragma once

#include <atomic>
#include <map>
#include <memory>
#include <vector>

#include "core/diff/loss.h"
#include "core/diff/parameters.h"
#include "core/diff/pixel_sampler.h"
#include "core/restir/direct_restir.h"

namespace invr {

enum class GradientMethod { Pt, Ris, Restir };
GradientMethod gradientMethodFromName(const std::string& name);  // throws InputError
const char* gradientMethodName(GradientMethod m);

struct GradientOptions {
  GradientMethod method = GradientMethod::Restir;
  RestirSettings restir;      // candidates and visibility also apply to ris
  // Neighbour search radius in pixels: at a shading point at distance t the world radius is
  // radiusPixels * t * 2 tan(fov/2) / height, so reuse stays local whatever the scene's scale.
  float radiusPixels = 3.f;
  bool forwardOnly = false;   // restir in the primal pass only
  bool preserveOccluded = true;  // keep reservoirs no view of the batch sees (Alg. 8)
  // Look for ReSTIR neighbours among last step's pixels first when last step rendered the view
  // (see runPass); false always searches the kd-tree (tests and benchmarks of that path).
  bool pixelNeighbours = true;
  int sppPrimal = 1;
  int sppGradient = 1;
  LossKind loss = LossKind::L2;
  // Path vertices after the camera. 1: direct illumination with the method's light sampling;
  // > 1: path tracing with NEE + MIS at every vertex, differentiated by path replay (method pt).
  int maxDepth = 1;
  PixelSamplingOptions pixels;  // which pixels a step traces (all, or a mini-batch)
};

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
};


struct GradientStats {
  double loss = 0.0;
  std::vector<double> viewLoss;
  double secondsPrimal = 0, secondsDerivative = 0, secondsReservoirUpdate = 0;
  double secondsStage1 = 0;   // pixel-sampling maps (when refreshed this step)
  uint64_t pixelsTraced = 0;  // distinct pixels traced by the primal pass
  uint64_t nonFiniteSamples = 0;  // primal samples and derivative paths dropped
  size_t reservoirs = 0, reservoirsPreserved = 0;
  double meanNeighbours = 0, meanM = 0;
  int kdTreesBuilt = 0;  // ReSTIR chains that needed their kd-tree this step (0-2)
  RayStats rays;
};

struct GradientResult {
  std::vector<double> gradient;  // d loss / d theta, one entry per parameter value
  GradientStats stats;
  std::vector<Image> renders;    // primal image per requested view
};

// Per-job state that survives between steps (the worker's session cache): reservoir chains.
struct EngineSession {
  ReservoirStore primal, derivative;
  std::map<int, PixelMap> pixelMaps;  // per view: the pixel-sampling probabilities
};

class GradientEngine {
 public:
  // targets[v] is the image view v should reproduce (may be empty for views never requested).
  GradientEngine(Scene& scene, const ParameterRegistry& params, std::vector<Image> targets, GradientOptions options);
  ~GradientEngine();

  // Writes theta into the scene, then estimates the gradient at it.
  GradientResult evaluate(const std::vector<float>& theta, const GradientRequest& request, EngineSession& session);
  const GradientOptions& options() const { return opt_; }
  // Stage 1 of pixel sampling for one view, on its own (benchmarks build reference maps from many).
  Stage1 measureStage1(int view, const GradientRequest& request) { return runStage1(view, request); }

 private:
  struct PassResult;
  PassResult runPass(int view, int pass, const GradientRequest& req, const ReservoirStore* prev,
                     StoredReservoir* store, const Image* adjoint, std::vector<double>* gradient,
                     const PixelBatch* batch = nullptr, std::vector<float>* derivSq = nullptr);
  // Stage 1 of pixel sampling for one view: one path per cell of a sparse grid, primal and
  // derivative, plus first-hit guides (see pixel_sampler.h).
  Stage1 runStage1(int view, const GradientRequest& req);

  Scene& scene_;
  const ParameterRegistry& params_;
  std::vector<Image> targets_;
  GradientOptions opt_;
  struct Scratch;
  std::unique_ptr<Scratch> scratch_;
};

// True if the surface point p is inside camera's frustum and not occluded from it.
bool visibleFromCamera(const Scene& scene, const Camera& camera, Vec3 p, Vec3 n);

}  // namespace invr
