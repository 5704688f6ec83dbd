// The render-time model of time-aware variance losses (Yan et al. 2024, Eq. 33 and 36):
//   t(q) = t_0 + sum_{k>0} t_k prod_{k'<=k} q_k'
// in rays per camera sample, where t_k is the cost of the rays traced at depth k when every
// survival probability is 1. We calibrate it from deterministic ray counts, not wall clocks: a
// pass that traced R_d rays at depth d over N camera samples under survival q has
// E[R_d / N] = t_d prod_{k<d} q_k, so t(q) = sum_d R_d / N and
//   dt/dq_i = sum_d (R_d / N) n_i(d) / q_i,
// n_i(d) being how many of the survival decisions before depth d use q_i (the last value of
// render.survival repeats for deeper bounces).
#pragma once

#include <vector>

#include "core/render/render_options.h"

namespace invr {

struct RenderCost {
  double raysPerSample = 0;        // t
  std::vector<double> dSurvival;   // dt / d survival[i]; empty under throughput roulette
};

// `survival` is the scene's fixed survival per bounce (empty: throughput roulette, whose
// probabilities follow the path and have no parameter; t is then the measured cost alone).
RenderCost renderCostByDepth(const RayStats& rays, const std::vector<float>& survival);

}  // namespace invr
