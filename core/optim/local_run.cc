#include "core/optim/local_run.h"

#include <chrono>
#include <cmath>

#include "core/error.h"

namespace invr {

LocalRunResult runLocally(Problem& p, const std::function<void(const StepReport&)>& onStep) {
  LocalRunResult out;
  out.targets = renderTargets(p);
  GradientEngine engine(*p.scene, p.params, out.targets, p.gradient);
  EngineSession session;
  out.theta = p.initial;
  OptimizerState state;
  auto t0 = std::chrono::steady_clock::now();
  uint64_t counter = 0;  // random streams: burn-in and gradient steps never share a step index
  for (int b = 0; b < p.burnIn; ++b) {
    GradientRequest r;
    r.views = viewsForStep(p, counter);
    r.step = counter++;
    r.seed = p.seed;
    r.renderOnly = true;
    engine.evaluate(out.theta, r, session);
  }
  for (int s = 1; s <= p.steps; ++s) {
    GradientRequest r;
    r.views = viewsForStep(p, counter);
    r.step = counter++;
    r.seed = p.seed;
    GradientResult g = engine.evaluate(out.theta, r, session);
    if (!std::isfinite(g.stats.loss)) throw InputError("step " + std::to_string(s) + ": the loss is not finite (diverged)");
    optimizerStep(p.optimizer, p.params, g.gradient, out.theta, state);
    // Non-finite samples are dropped before they reach the loss, so divergence shows in the
    // parameters: non-finite, or beyond any physical value.
    for (const auto& slot : p.params.slots())
      for (uint32_t k = 0; k < slot.size; ++k) {
        float v = out.theta[slot.offset + k];
        if (!std::isfinite(v) || std::abs(v) > kDivergenceLimit)
          throw InputError("step " + std::to_string(s) + ": parameter '" + slot.name + "' reached " + std::to_string(v) +
                           " (diverged; lower its learning rate)");
      }
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
