// How the gradient engine estimates a step: the interior estimator (PT, RIS or ReSTIR), its
// sample counts, the loss and which pixels a step traces, and the options of the pixel samplers,
// the variance pass and the boundary terms (each parsed beside its own code). The defaults here
// are a job's defaults.
#pragma once

#include <algorithm>
#include <string>
#include <vector>

#include "core/diff/boundary_term.h"
#include "core/diff/loss.h"
#include "core/diff/pixel_sampler.h"
#include "core/diff/variance_options.h"
#include "core/restir/direct_restir.h"
#include "invr/v1/job.pb.h"

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
  bool derivativeOnly = false; // restir in the derivative pass only, RIS primal (a lab ablation: bench reconstruct)
  // The derivative pass draws the primal pass's random numbers (Wang et al. 2023, Alg. 4: the
  // primal image and the derivative from the same sample; bench reconstruct --correlated-primal).
  // Its dL/dI then correlates with the derivative, which biases an L2 gradient by their covariance.
  // A lab ablation: jobs keep the passes independent.
  bool correlatedPrimal = false;
  bool preserveOccluded = true;  // keep reservoirs no view of the batch sees (Alg. 8)
  // Look for ReSTIR neighbours among last step's pixels first when last step rendered the view
  // (see ReSTIR's estimator); false always searches the kd-tree (tests and benchmarks of that path).
  bool pixelNeighbours = true;
  // How a pixel's samples relate in every render and pass of the job (rng.h): independent or
  // sobol.
  SamplerKind sampler = SamplerKind::Independent;
  int sppPrimal = 1;
  int sppGradient = 1;
  LossKind loss = LossKind::L2;
  // Path vertices after the camera. 1: direct illumination with the method's light sampling;
  // > 1: path tracing with NEE + MIS at every vertex (method pt).
  int maxDepth = 1;
  int russianRouletteDepth = 3;
  PixelSamplingOptions pixels;  // which pixels a step traces (all, or a mini-batch)
  // Per view (indexed by view; missing or empty: unmasked), per pixel loss weights from the job's
  // target masks, normalised to mean 1 over the film so the loss is the masked pixels' mean.
  std::vector<std::vector<float>> lossMasks;
  VarianceOptions variance;
  BoundaryOptions boundary;  // used when shape parameters are optimised
  // Smooth meshes under vertex parameters: the interior term through their recomputed vertex
  // normals (ParameterRegistry::foldNormalAdjoints). Always on in jobs; tests turn it off to
  // measure its share of a derivative.
  bool vertexNormalTerm = true;
};

// Every field of optimization that sets the gradient options (the loss masks excepted: they are
// images, read by the job's builder), for a film of width x height. Throws InputError naming the
// field at fault for a value out of range; combinations that need the scene and the parameters
// are checked by validateGradientJob (gradient_job_check.h).
GradientOptions parseGradientOptions(const invr::v1::OptimizationSpec& optimization, int width, int height);

}  // namespace invr
