// How a job's parameters are updated: the optimiser, its constants and the learning-rate
// schedule (the update itself is core/optim/optimizer.h).
#pragma once

#include <cstdint>
#include <string>

namespace invr {

// AdamUniform: Adam with one second-moment scale per parameter, the largest over its values
// (Nicolet et al. 2021; Mitsuba's Adam(uniform=True)): a vertex parameter then moves all its
// vertices at one rate instead of normalising each vertex's step on its own.
enum class OptimizerKind { Adam, Sgd, AdamUniform };
OptimizerKind optimizerKindFromName(const std::string& name);  // throws InputError
const char* optimizerKindName(OptimizerKind kind);

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

}  // namespace invr
