// The one optimization loop: evaluate -> sum the shards in shard order -> divergence check ->
// optimiser step -> the caller's checkpoint. The in-process run (local_run.h), the equal-time
// runner (equal_time.h) and the server's job runner all step through it, so they do the same
// arithmetic in the same order and give bit-identical parameters. Where the shards are evaluated
// (in this process, or on workers) is the caller's business.
#pragma once

#include <functional>
#include <optional>
#include <vector>

#include "core/job/problem.h"
#include "core/optim/optimizer.h"

namespace invr {

// A parameter beyond this magnitude means the optimisation diverged.
inline constexpr float kDivergenceLimit = 1e30f;

// Throws InputError if the loss is non-finite or a parameter is non-finite or beyond
// kDivergenceLimit, naming the step and the parameter.
void checkDivergence(const Problem& problem, uint64_t step, double loss, const std::vector<float>& theta);

// Adds one shard's gradient, loss, drops and timings to the step's total (the order is the
// caller's: shard order).
void accumulateShard(GradientResult& total, const GradientResult& shard);

// Where the loop stands: everything a checkpoint holds.
struct LoopState {
  std::vector<float> theta;
  OptimizerState optimizer;
  uint64_t counter = 0;  // evaluations done (burn-in included): indexes the random streams
  uint64_t step = 0;     // gradient steps done
};

class OptimizationLoop {
 public:
  // Evaluates evaluation `e` at theta: one result per shard, in shard order (nullopt for a shard
  // with no view in the batch).
  using Evaluate = std::function<std::vector<std::optional<GradientResult>>(const Evaluation& e, const std::vector<float>& theta)>;

  // burnIn: render-only evaluations before the first step; steps: gradient steps (0: no limit, the
  // caller stops). Starts from `start` (a checkpoint, or the problem's initial values).
  OptimizationLoop(const Problem& problem, LoopState start, int burnIn, int steps);

  bool done() const { return steps_ > 0 && state_.step >= uint64_t(steps_); }
  bool burningIn() const { return state_.counter < uint64_t(burnIn_); }
  // Runs the next evaluation. During burn-in returns nullopt; otherwise the step's summed result,
  // after the update. On divergence throws InputError and keeps the last good state.
  std::optional<GradientResult> next(const Evaluate& evaluate);
  const LoopState& state() const { return state_; }
  int burnIn() const { return burnIn_; }

 private:
  const Problem& problem_;
  LoopState state_;
  int burnIn_, steps_;
};

// The in-process evaluator: the problem's shards one after another, each with its own session,
// on one engine. It is the only writer of the scene's parameters, between passes.
class LocalEvaluator {
 public:
  LocalEvaluator(Problem& problem, const std::vector<Image>& targets, const GradientOptions& options);
  std::vector<std::optional<GradientResult>> operator()(const Evaluation& e, const std::vector<float>& theta);
  GradientEngine& engine() { return engine_; }

 private:
  Problem& problem_;
  GradientEngine engine_;
  std::vector<EngineSession> sessions_;  // one reservoir chain pair per shard
};

}  // namespace invr
