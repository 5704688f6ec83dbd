// Gradient-descent updates with per-parameter learning rates and bound clamping. The state
// (moments, step count) is plain data so the server can checkpoint it.
#pragma once

#include <string>
#include <vector>

#include "core/diff/parameters.h"

namespace invr {

enum class OptimizerKind { Adam, Sgd };

struct OptimizerState {
  std::vector<double> m, v;  // Adam moments
  uint64_t step = 0;
};

struct AdamSettings {
  double beta1 = 0.9, beta2 = 0.999, epsilon = 1e-8;
};

// Learning-rate decay by step: the t-th update (t = 0, 1, ...) uses lr * h / (h + t), half the rate
// after h steps; h = 0 keeps every rate constant. With noisy gradients a constant rate leaves the
// parameters swinging around the optimum by an amount set by the rate, whatever the noise;
// a decaying rate lets them settle, by an amount set by the gradient noise.
struct LearningRateSchedule {
  double halfLifeSteps = 0;
  double factor(uint64_t t) const { return halfLifeSteps > 0 ? halfLifeSteps / (halfLifeSteps + double(t)) : 1.0; }
};

// Applies one update to theta in place (then clamps to each slot's bounds).
void optimizerStep(OptimizerKind kind, const ParameterRegistry& params, const std::vector<double>& gradient,
                   std::vector<float>& theta, OptimizerState& state, const LearningRateSchedule& schedule = {},
                   const AdamSettings& adam = {});

OptimizerKind optimizerKindFromName(const std::string& name);  // throws InputError

}  // namespace invr
