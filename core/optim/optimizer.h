// Gradient-descent updates with per-parameter learning rates and bound clamping. The state
// (moments, step count) is plain data so the server can checkpoint it.
#pragma once

#include <string>
#include <vector>

#include "core/diff/parameters.h"
#include "core/job/optimizer_settings.h"

namespace invr {

struct OptimizerState {
  std::vector<double> m, v;  // Adam moments
  uint64_t step = 0;
};

// Applies one update to theta in place (then clamps to each slot's bounds).
void optimizerStep(OptimizerKind kind, const ParameterRegistry& params, const std::vector<double>& gradient,
                   std::vector<float>& theta, OptimizerState& state, const LearningRateSchedule& schedule = {},
                   const AdamSettings& adam = {});

}  // namespace invr
