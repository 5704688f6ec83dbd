#include "core/diff/variance_options.h"

#include <cmath>

#include "core/error.h"

namespace invr {

VarianceOptions parseVarianceOptions(const invr::v1::OptimizationSpec& o) {
  const VarianceOptions defaults;
  VarianceOptions vo;
  if (!o.has_variance()) return vo;
  auto fail = [](const std::string& field, const std::string& why) { throw InputError("optimization.variance" + field + ": " + why); };
  const auto& v = o.variance();
  vo.enabled = true;
  if (v.has_weight() && !(std::isfinite(v.weight()) && v.weight() >= 0)) fail(".weight", "must be a finite number >= 0");
  vo.weight = v.has_weight() ? v.weight() : defaults.weight;
  if (!(std::isfinite(v.samples()) && v.samples() >= 0)) fail(".samples", "must be a positive number (K, samples per pixel)");
  vo.samples = v.samples() > 0 ? v.samples() : defaults.samples;
  if (v.estimator() != "" && v.estimator() != "unbiased" && v.estimator() != "detached")
    fail(".estimator", "unknown estimator '" + v.estimator() + "' (use unbiased or detached)");
  vo.detached = v.estimator() == "detached";
  if (v.spp() < 0 || v.spp() > 4096) fail(".spp", "must be in 1..4096 (got " + std::to_string(v.spp()) + ")");
  vo.spp = v.spp() > 0 ? v.spp() : defaults.spp;
  if (v.cost_model() != "" && v.cost_model() != "none" && v.cost_model() != "depth")
    fail(".cost_model", "unknown cost model '" + v.cost_model() + "' (use none or depth)");
  vo.cost = v.cost_model() == "depth" ? VarianceCost::Depth : VarianceCost::None;
  if (vo.cost == VarianceCost::Depth && v.samples() != 0)
    fail(".samples", "has no meaning with cost_model depth: the loss is bias + weight * t * V (Eq. 33); leave samples unset");
  return vo;
}

}  // namespace invr
