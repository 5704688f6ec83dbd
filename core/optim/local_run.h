// Runs an inverse problem in this process: burn-in, then gradient steps with the optimiser, with a
// callback per step. The service runs the same steps with the gradient farmed out to workers;
// this is also the reference it is compared against.
#pragma once

#include <functional>

#include "core/diff/problem.h"

namespace invr {

struct StepReport {
  uint64_t step = 0;       // 1-based gradient step
  double seconds = 0;      // since the run started (burn-in included)
  double loss = 0;
  double parameterError = 0;
  uint64_t nonFinite = 0;
  GradientStats stats;
};

struct LocalRunResult {
  std::vector<float> theta;
  std::vector<StepReport> history;
  std::vector<Image> targets;
};

// A parameter beyond this magnitude means the optimisation diverged.
inline constexpr float kDivergenceLimit = 1e30f;

// Adds one shard's gradient and loss to the step's total (the order is the caller's: shard order).
void accumulateShard(GradientResult& total, const GradientResult& shard);

// Throws InputError if the loss is non-finite or a parameter is non-finite or beyond
// kDivergenceLimit, naming the step and the parameter.
void checkDivergence(const Problem& problem, uint64_t step, double loss, const std::vector<float>& theta);

// Evaluates every shard's part of evaluation `e` at theta (sessions: one per shard) and sums them
// in shard order, with the shards' timings and reservoir statistics.
GradientResult evaluateShards(const Problem& problem, GradientEngine& engine, std::vector<EngineSession>& sessions,
                              const std::vector<float>& theta, const Evaluation& e);

// Throws InputError if the loss becomes non-finite or a parameter non-finite or beyond
// kDivergenceLimit (divergence), naming the step and the parameter.
LocalRunResult runLocally(Problem& problem, const std::function<void(const StepReport&)>& onStep = {});

}  // namespace invr
