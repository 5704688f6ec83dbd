// The interface every interior estimator implements (Wang et al. 2023's interior term, Eq. 12-13:
// the derivative of what a camera sample sees at fixed visibility). One estimator per file:
//   pt_estimator.cc      one light sample + BSDF sampling with MIS, any path length   (baseline B.1)
//   ris_estimator.cc     streaming RIS over M candidates, direct illumination         (baseline B.2)
//   restir_estimator.cc  RIS + reuse of the previous step's reservoirs (Alg. 3-4)
// Each traces the shared walk (core/render/path_walk.h) with its own direct-light strategy, and
// differentiates it with the adjoint visitor (core/diff/path_adjoint.h). The pass driver
// (pass_driver.h) owns pixels, random streams, non-finite drops and gradient reduction; an
// estimator sees one camera sample at a time and may be called from many threads at once.
#pragma once

#include <memory>

#include "core/diff/gradient_options.h"
#include "core/diff/gradient_sink.h"
#include "core/diff/parameters.h"
#include "core/diff/variance_visitor.h"
#include "core/restir/reservoir_store.h"

namespace invr {

// One camera sample as the pass driver hands it over.
struct CameraSampleInput {
  int x = 0, y = 0;
  uint64_t pixel = 0;
  int slot = 0;  // which of the pixel's spp reservoir slots the sample reads hints from
  Vec3 o, d;     // the camera ray
  const PrimaryHit* primary = nullptr;  // its closest hit, when the driver traced it already
};

// Per-thread counters an estimator adds to.
struct SampleCounters {
  RayStats rays;
  RestirCounters restir;
};

class InteriorEstimator {
 public:
  virtual ~InteriorEstimator() = default;
  // Traces one camera sample and returns its radiance. With `grad` set, adds adjoint * d/dtheta of
  // that radiance to it. `reservoir` (null unless the pass keeps reservoirs) receives what the
  // sample leaves for the next step; the driver has marked it empty (mesh = UINT32_MAX) before.
  virtual Rgb sample(const CameraSampleInput& in, Sampler& sampler, SampleCounters& counters, Rgb adjoint, PathGradient* grad,
                     StoredReservoir* reservoir) const = 0;
  // The variance pass (Yan et al. 2024): traces one sample and adds its weighted variance
  // derivative (variance_visitor.h) to `grad`. Only estimators whose every random decision has a
  // known density implement it (PT); the others are refused when the job is built.
  virtual Rgb varianceSample(const CameraSampleInput& in, Sampler& sampler, SampleCounters& counters, const VarianceWeights& weights,
                             PathGradient& grad) const {
    (void)in, (void)sampler, (void)counters, (void)weights, (void)grad;
    throw std::logic_error("this estimator has no variance derivatives");
  }
  // Whether the samples of a pixel may be stratified together (the sobol sampler). Not when the
  // estimator resamples them together later (ReSTIR's reservoirs): resampling with MIS weights
  // that depend on the other inputs is unbiased for independent inputs only. (Measured: with
  // stratified ReSTIR an area light's intensity derivative came out 1.6 % below finite
  // differences over five seed sets, against 0.6 % independent and 1.0 % for RIS either way; the
  // tests cannot separate that from noise, so the theory decides.)
  virtual bool stratifiable() const { return true; }
};

// What an estimator is built from, once per pass (one view).
struct EstimatorSetup {
  const Scene& scene;
  const ParameterRegistry& params;
  const GradientOptions& options;
  int view = 0;
  int spp = 1;                                // samples per pixel of the pass (reservoir slots per pixel)
  const ReservoirStore* previous = nullptr;  // reservoirs to reuse (ReSTIR; null or empty: plain RIS)
};

std::unique_ptr<InteriorEstimator> makePtEstimator(const EstimatorSetup& setup);
std::unique_ptr<InteriorEstimator> makeRisEstimator(const EstimatorSetup& setup);
std::unique_ptr<InteriorEstimator> makeRestirEstimator(const EstimatorSetup& setup);

}  // namespace invr
