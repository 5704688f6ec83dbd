#include "core/optim/local_run.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "core/error.h"

namespace invr {

void accumulateShard(GradientResult& total, const GradientResult& shard) {
  if (total.gradient.empty()) total.gradient.assign(shard.gradient.size(), 0.0);
  // Callers check shapes first (the server checks every worker's result); this is the last line.
  if (shard.gradient.size() != total.gradient.size())
    throw std::logic_error("accumulateShard: a gradient of " + std::to_string(shard.gradient.size()) + " values added to one of " +
                           std::to_string(total.gradient.size()));
  for (size_t i = 0; i < shard.gradient.size(); ++i) total.gradient[i] += shard.gradient[i];
  total.stats.loss += shard.stats.loss;
  total.stats.nonFiniteSamples += shard.stats.nonFiniteSamples;
}

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

// Shards are evaluated one after another and summed in shard order: the service does the same
// arithmetic with the shards on workers, so both give bit-identical parameters.
GradientResult evaluateShards(const Problem& p, GradientEngine& engine, std::vector<EngineSession>& sessions,
                              const std::vector<float>& theta, const Evaluation& e) {
  GradientResult total;
  for (size_t s = 0; s < p.shards.size(); ++s) {
    GradientRequest r = shardRequest(p, e, s);
    if (r.views.empty()) continue;
    GradientResult g = engine.evaluate(theta, r, sessions.at(s));
    accumulateShard(total, g);
    total.stats.secondsPrimal += g.stats.secondsPrimal;
    total.stats.secondsDerivative += g.stats.secondsDerivative;
    total.stats.secondsReservoirUpdate += g.stats.secondsReservoirUpdate;
    total.stats.secondsStage1 += g.stats.secondsStage1;
    total.stats.reservoirs += g.stats.reservoirs;
    total.stats.meanM = g.stats.meanM;
    total.stats.meanNeighbours = g.stats.meanNeighbours;
  }
  if (total.gradient.empty()) total.gradient.assign(p.params.size(), 0.0);
  return total;
}

LocalRunResult runLocally(Problem& p, const std::function<void(const StepReport&)>& onStep) {
  LocalRunResult out;
  out.targets = renderTargets(p);
  GradientEngine engine(*p.scene, p.params, out.targets, p.gradient);
  std::vector<EngineSession> sessions(p.shards.size());  // one reservoir chain pair per shard
  out.theta = p.initial;
  OptimizerState state;
  auto t0 = std::chrono::steady_clock::now();
  auto evaluateAll = [&](const Evaluation& e) { return evaluateShards(p, engine, sessions, out.theta, e); };
  uint64_t counter = 0;
  for (; counter < uint64_t(p.burnIn); ++counter) evaluateAll(evaluationAt(p, counter));
  for (int s = 1; s <= p.steps; ++s, ++counter) {
    GradientResult g = evaluateAll(evaluationAt(p, counter));
    if (!std::isfinite(g.stats.loss)) checkDivergence(p, uint64_t(s), g.stats.loss, out.theta);
    optimizerStep(p.optimizer, p.params, g.gradient, out.theta, state, p.schedule);
    checkDivergence(p, uint64_t(s), g.stats.loss, out.theta);
    StepReport rep;
    rep.step = uint64_t(s);
    rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    rep.loss = g.stats.loss;
    rep.parameterError = parameterError(p, out.theta);
    rep.nonFinite = g.stats.nonFiniteSamples;
    rep.stats = g.stats;
    out.history.push_back(rep);
    if (onStep) onStep(rep);
  }
  p.params.write(out.theta, *p.scene);
  return out;
}

}  // namespace invr
