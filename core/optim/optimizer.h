// Gradient-descent updates with per-parameter learning rates and bound clamping. The state
// (moments, step count) is plain data so the server can checkpoint it.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/diff/parameters.h"
#include "core/job/optimizer_settings.h"
#include "core/optim/large_steps.h"

namespace invr {

struct OptimizerState {
  std::vector<double> m, v;  // Adam moments (of u = (I + lambda L) x for Large Steps parameters)
  uint64_t step = 0;
  // Per slot: the Large Steps factor of a vertex parameter with lambda > 0, built on first use
  // (derived from the mesh, so a restored checkpoint rebuilds it; shared by copies of the state).
  std::vector<std::shared_ptr<const LargeSteps>> largeSteps;
};

// Applies one update to theta in place (then clamps to each slot's bounds). A vertex parameter
// with Large Steps' lambda > 0 is updated in u = (I + lambda L) x: its gradient is taken there by
// one solve (dL/du = (I + lambda L)^-1 dL/dx), Adam steps u, and x solves (I + lambda L) x = u.
void optimizerStep(OptimizerKind kind, const ParameterRegistry& params, const std::vector<double>& gradient,
                   std::vector<float>& theta, OptimizerState& state, const LearningRateSchedule& schedule = {},
                   const AdamSettings& adam = {});

}  // namespace invr
