#include "core/optim/optimization_loop.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "core/diff/gradient_stats.h"
#include "core/error.h"

namespace invr {

namespace {
std::string shortNumber(float v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", double(v));
  return b;
}
}  // namespace

void checkDivergence(const Problem& p, uint64_t step, double loss, const std::vector<float>& theta) {
  if (!std::isfinite(loss)) throw InputError("step " + std::to_string(step) + ": the loss is not finite (diverged)");
  // Non-finite samples are dropped before they reach the loss, so divergence shows in the
  // parameters: non-finite, or beyond any physical value.
  for (const auto& slot : p.params.slots())
    for (uint32_t k = 0; k < slot.size; ++k) {
      float v = theta[slot.offset + k];
      if (!std::isfinite(v) || std::abs(v) > kDivergenceLimit)
        throw InputError("step " + std::to_string(step) + ": parameter '" + slot.name + "' reached " + shortNumber(v) +
                         " (diverged; lower its learning rate)");
    }
}

void accumulateShard(GradientResult& total, const GradientResult& shard) {
  if (total.gradient.empty()) total.gradient.assign(shard.gradient.size(), 0.0);
  // Callers check shapes first (the server checks every worker's result); this is the last line.
  if (shard.gradient.size() != total.gradient.size())
    throw std::logic_error("accumulateShard: a gradient of " + std::to_string(shard.gradient.size()) + " values added to one of " +
                           std::to_string(total.gradient.size()));
  for (size_t i = 0; i < shard.gradient.size(); ++i) total.gradient[i] += shard.gradient[i];
  addGradientStats(total.stats, shard.stats);
}

OptimizationLoop::OptimizationLoop(const Problem& problem, LoopState start, int burnIn, int steps)
    : problem_(problem), state_(std::move(start)), burnIn_(burnIn), steps_(steps) {
  if (state_.theta.size() != problem.params.size())
    throw InputError("optimization: " + std::to_string(state_.theta.size()) + " parameter values given, the job has " +
                     std::to_string(problem.params.size()));
}

std::optional<GradientResult> OptimizationLoop::next(const Evaluate& evaluate) {
  Evaluation e = evaluationAt(problem_, state_.counter);
  e.renderOnly = burningIn();
  auto shards = evaluate(e, state_.theta);
  ++state_.counter;
  if (e.renderOnly) return std::nullopt;
  GradientResult sum;
  for (auto& s : shards)  // shard order: the same sums in process and on workers
    if (s) accumulateShard(sum, *s);
  if (sum.gradient.empty()) sum.gradient.assign(problem_.params.size(), 0.0);
  const uint64_t step = state_.step + 1;
  checkDivergence(problem_, step, sum.stats.loss(), state_.theta);
  std::vector<float> theta = state_.theta;
  OptimizerState opt = state_.optimizer;
  optimizerStep(problem_.optimizer, problem_.params, sum.gradient, theta, opt, problem_.schedule);
  checkDivergence(problem_, step, sum.stats.loss(), theta);
  state_.theta = std::move(theta);
  state_.optimizer = std::move(opt);
  state_.step = step;
  return sum;
}

LocalEvaluator::LocalEvaluator(Problem& problem, const std::vector<Image>& targets, const GradientOptions& options)
    : problem_(problem), engine_(*problem.scene, problem.params, targets, options), sessions_(problem.shards.size()) {}

std::vector<std::optional<GradientResult>> LocalEvaluator::operator()(const Evaluation& e, const std::vector<float>& theta) {
  problem_.params.write(theta, *problem_.scene);  // between passes: nothing renders now
  std::vector<std::optional<GradientResult>> out(problem_.shards.size());
  for (size_t s = 0; s < problem_.shards.size(); ++s) {
    GradientRequest r = shardRequest(problem_, e, s);
    if (r.views.empty()) continue;
    out[s] = engine_.evaluate(r, sessions_[s]);
  }
  return out;
}

}  // namespace invr
