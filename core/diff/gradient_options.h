// How the gradient engine estimates a step: the interior estimator (PT, RIS or ReSTIR), its
// sample counts, the loss and which pixels a step traces.
#pragma once

#include <algorithm>
#include <string>
#include <vector>

#include "core/diff/loss.h"
#include "core/diff/pixel_sampler.h"
#include "core/restir/direct_restir.h"

namespace invr {

enum class GradientMethod { Pt, Ris, Restir };
GradientMethod gradientMethodFromName(const std::string& name);  // throws InputError
const char* gradientMethodName(GradientMethod m);

// Variance-aware losses (Yan et al. 2024, Eq. 26-33): L = L_bias + (weight / samples) * V, with V the
// per-pixel variance of one sample of the job's estimator (mean over pixels and channels, like the
// loss). A variance pass of `spp` samples per pixel estimates V's derivative (variance_visitor.h).
// With the depth cost model the loss is time-aware (Eq. 33): L* = L_bias + weight * t * V, with t
// the render cost per camera sample in rays (render_cost.h), and `samples` unused.
enum class VarianceCost { None, Depth };

struct VarianceOptions {
  bool enabled = false;
  VarianceCost cost = VarianceCost::None;
  double weight = 1.0;   // lambda (lambda* with the depth cost model)
  double samples = 1.0;  // K: samples per pixel of the render whose variance is weighed
  bool detached = false; // the detached baseline (Weier et al. 2021) instead of the unbiased estimator
  int spp = 1;           // training spp of the variance pass
};

// Shape parameters: the boundary terms of their derivatives (Wang et al. 2023, §5-6;
// docs/differentiable-rendering.md). primary/secondary switch the terms off for ablations.
struct BoundaryOptions {
  bool primary = true;    // silhouette and crease edges of moving meshes seen by the camera
  bool secondary = true;  // shadow borders of point, spot, area and environment lights
  int samples = 0;        // edge samples per term, view and step; 0: a quarter of the film's pixels, at least 256
  int lightPoints = 16;   // light points (area lights) and directions (environments) per pass whose shadow borders are sampled
  // ReSTIR: test the support of reused samples in the current geometry (the paper's multi-view
  // shortcut, §3.2), which is biased once geometry moves. Default: in the geometry each sample was
  // created in (unbiased; the reservoir store keeps the moving meshes' poses for that).
  bool multiViewShortcut = false;
  // Area lights' shadow borders: sampled edge point first with the light point by RIS (Alg. 6;
  // restir reuses edge reservoirs across steps) or light points first (area_shadow_boundary.h).
  enum class AreaSampling { EdgeFirst, LightPoints };
  AreaSampling areaSampling = AreaSampling::EdgeFirst;
  bool edgeImportance = true;  // restir: edges sampled from the previous step's edge reservoirs (Eq. 27)
  // restir: previous-step edge reservoirs merged per sample (Alg. 6). 0: they steer edge importance
  // only; merging measured no gain (docs/differentiable-rendering.md).
  int edgeNeighbours = 0;
  int samplesFor(int width, int height) const { return samples > 0 ? samples : std::max(256, width * height / 4); }
};

struct GradientOptions {
  GradientMethod method = GradientMethod::Restir;
  RestirSettings restir;      // candidates and visibility also apply to ris
  // Neighbour search radius in pixels: at a shading point at distance t the world radius is
  // radiusPixels * t * 2 tan(fov/2) / height, so reuse stays local whatever the scene's scale.
  float radiusPixels = 3.f;
  bool forwardOnly = false;   // restir in the primal pass only
  bool preserveOccluded = true;  // keep reservoirs no view of the batch sees (Alg. 8)
  // Look for ReSTIR neighbours among last step's pixels first when last step rendered the view
  // (see ReSTIR's estimator); false always searches the kd-tree (tests and benchmarks of that path).
  bool pixelNeighbours = true;
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
};

}  // namespace invr
