// Variance-aware losses (Yan et al. 2024, Eq. 26-33; docs/variance.md): L = L_bias + (weight /
// samples) * V, with V the per-pixel variance of one sample of the job's estimator (mean over
// pixels and channels, like the loss). A variance pass of `spp` samples per pixel estimates V's
// derivative (variance_visitor.h). With the depth cost model the loss is time-aware (Eq. 33):
// L* = L_bias + weight * t * V, with t the render cost per camera sample in rays (render_cost.h),
// and `samples` unused.
#pragma once

#include "invr/v1/job.pb.h"

namespace invr {

enum class VarianceCost { None, Depth };

struct VarianceOptions {
  bool enabled = false;
  VarianceCost cost = VarianceCost::None;
  double weight = 1.0;   // lambda (lambda* with the depth cost model)
  double samples = 1.0;  // K: samples per pixel of the render whose variance is weighed
  bool detached = false; // the detached baseline (Weier et al. 2021) instead of the unbiased estimator
  int spp = 1;           // training spp of the variance pass
};

// optimization.variance (enabled when the job has it). Throws InputError naming the field.
VarianceOptions parseVarianceOptions(const invr::v1::OptimizationSpec& optimization);

}  // namespace invr
