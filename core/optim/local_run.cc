#include "core/optim/local_run.h"

#include "core/diff/gradient_stats.h"
#include "core/optim/smoothed_loss.h"
#include "core/stopwatch.h"

namespace invr {

LocalRunResult runLocally(Problem& p, const std::function<void(const StepReport&)>& onStep, const std::function<void(int, int)>& onTarget) {
  LocalRunResult out;
  Stopwatch clock;
  const int views = int(p.scene->cameras.size());
  for (int v = 0; v < views; ++v) {
    out.targets.push_back(renderTarget(p, v));
    if (onTarget) onTarget(v + 1, views);
  }
  out.targetSeconds = clock.seconds();
  LocalEvaluator evaluate(p, out.targets, p.gradient);
  LoopState start;
  start.theta = p.initial;
  OptimizationLoop loop(p, std::move(start), p.burnIn, p.steps);
  SmoothedLoss imageLoss;
  while (!loop.done()) {
    auto g = loop.next(std::ref(evaluate));
    if (!g) continue;  // burn-in
    StepReport rep;
    rep.step = loop.state().step;
    rep.seconds = clock.seconds();
    rep.loss = g->stats.loss();
    rep.imageLoss = imageLoss.add(g->stats.primal_loss());
    rep.parameterError = parameterError(p, loop.state().theta);
    rep.shapeError = shapeError(p, loop.state().theta);
    rep.nonFinite = droppedSamples(g->stats);
    rep.stats = g->stats;
    out.history.push_back(rep);
    rep.theta = &loop.state().theta;
    if (onStep) onStep(rep);
  }
  out.theta = loop.state().theta;
  p.params.write(out.theta, *p.scene);
  return out;
}

}  // namespace invr
