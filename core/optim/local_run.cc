#include "core/optim/local_run.h"

#include "core/diff/gradient_stats.h"
#include "core/stopwatch.h"

namespace invr {

LocalRunResult runLocally(Problem& p, const std::function<void(const StepReport&)>& onStep) {
  LocalRunResult out;
  out.targets = renderTargets(p);
  LocalEvaluator evaluate(p, out.targets, p.gradient);
  LoopState start;
  start.theta = p.initial;
  OptimizationLoop loop(p, std::move(start), p.burnIn, p.steps);
  Stopwatch clock;
  while (!loop.done()) {
    auto g = loop.next(std::ref(evaluate));
    if (!g) continue;  // burn-in
    StepReport rep;
    rep.step = loop.state().step;
    rep.seconds = clock.seconds();
    rep.loss = g->stats.loss();
    rep.parameterError = parameterError(p, loop.state().theta);
    rep.shapeError = shapeError(p, loop.state().theta);
    rep.nonFinite = droppedSamples(g->stats);
    rep.stats = g->stats;
    out.history.push_back(rep);
    if (onStep) onStep(rep);
  }
  out.theta = loop.state().theta;
  p.params.write(out.theta, *p.scene);
  return out;
}

}  // namespace invr
