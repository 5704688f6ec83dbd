// Runs an inverse problem in this process: burn-in, then gradient steps through the optimization
// loop, with a callback per step. The service runs the same loop with the gradient farmed out to
// workers; this is also the reference it is compared against.
#pragma once

#include <functional>

#include "core/optim/optimization_loop.h"

namespace invr {

struct StepReport {
  uint64_t step = 0;       // 1-based gradient step
  double seconds = 0;      // since the run started (burn-in included)
  double loss = 0;         // unbiased (two independent renders)
  double imageLoss = 0;    // smoothed one-render loss (smoothed_loss.h)
  double parameterError = 0;
  double shapeError = -1;  // jobs with vertex parameters (problem.h's shapeError)
  uint64_t nonFinite = 0;
  invr::v1::GradientStats stats;
  const std::vector<float>* theta = nullptr;  // the parameters after the step; valid during the callback only
};

struct LocalRunResult {
  double targetSeconds = 0;  // rendering the targets, before the first step
  std::vector<float> theta;
  std::vector<StepReport> history;
  std::vector<Image> targets;
};

// Throws InputError if the loss becomes non-finite or a parameter non-finite or beyond
// kDivergenceLimit (divergence), naming the step and the parameter.
// StepReport.seconds counts from the start, the targets' rendering included. `onTarget(view,
// views)` is called as each target view is rendered.
LocalRunResult runLocally(Problem& problem, const std::function<void(const StepReport&)>& onStep = {},
                          const std::function<void(int, int)>& onTarget = {});

}  // namespace invr
