#include "core/optim/equal_time.h"

#include <chrono>
#include <cmath>

#include "core/diff/gradient_stats.h"
#include "core/error.h"
#include "core/stopwatch.h"

namespace invr {

namespace {

// The RMS of `error` over the steps in the last quarter of a budget of `total` seconds, or steps
// when `bySteps`.
double tailError(const std::vector<EqualTimePoint>& history, double total, bool bySteps, double EqualTimePoint::*error) {
  double sum = 0;
  size_t n = 0;
  for (const EqualTimePoint& pt : history) {
    if (!(pt.*error >= 0)) return pt.*error;
    const double spent = bySteps ? double(pt.step) : pt.seconds;
    if (pt.step > 0 && spent >= 0.75 * total) sum += pt.*error * pt.*error, ++n;
  }
  return n ? std::sqrt(sum / double(n)) : history.back().*error;
}

}  // namespace

double tailParameterError(const std::vector<EqualTimePoint>& history, const EqualTimeOptions& budget) {
  const bool bySteps = budget.steps > 0;
  return tailError(history, bySteps ? double(budget.steps) : budget.seconds, bySteps, &EqualTimePoint::parameterError);
}

double tailShapeError(const std::vector<EqualTimePoint>& history, const EqualTimeOptions& budget) {
  const bool bySteps = budget.steps > 0;
  return tailError(history, bySteps ? double(budget.steps) : budget.seconds, bySteps, &EqualTimePoint::shapeError);
}

double tailParameterError(const std::vector<EqualTimePoint>& history, double budgetSeconds) {
  return tailError(history, budgetSeconds, false, &EqualTimePoint::parameterError);
}

double tailShapeError(const std::vector<EqualTimePoint>& history, double budgetSeconds) {
  return tailError(history, budgetSeconds, false, &EqualTimePoint::shapeError);
}

ConvergenceRow convergenceRow(const std::string& method, const EqualTimePoint& pt) {
  ConvergenceRow r;
  r.method = method;
  r.step = uint64_t(pt.step);
  r.seconds = pt.seconds;
  r.loss = pt.loss;
  r.paramError = pt.parameterError;
  r.imageError = pt.imageError;
  if (pt.shapeError >= 0) r.shapeError = pt.shapeError;
  r.stats = pt.stats;
  return r;
}

EqualTimeRun runEqualTime(Problem& p, const std::vector<Image>& targets, const GradientOptions& options,
                          const EqualTimeOptions& budget, ImageErrorMeter* meter,
                          const std::function<void(const EqualTimePoint&)>& onPoint) {
  if (budget.steps < 0) throw InputError("equal-time run: the budget in steps must be positive");
  if (budget.steps == 0 && !(budget.seconds > 0)) throw InputError("equal-time run: the budget must be positive seconds");
  LocalEvaluator evaluate(p, targets, options);
  // The burn-in (ReSTIR's render-only steps) is part of the method's cost; the problem's own
  // burn-in length does not apply to other methods.
  LoopState begin;
  begin.theta = p.initial;
  OptimizationLoop loop(p, std::move(begin), options.method == GradientMethod::Restir ? p.burnIn : 0, 0);
  EqualTimeRun out;
  out.theta = p.initial;
  double used = 0;  // seconds of budget spent
  auto record = [&](EqualTimePoint pt) {
    out.history.push_back(pt);
    if (onPoint) onPoint(pt);
  };
  EqualTimePoint start;
  start.parameterError = p.groundTruthKnown() ? parameterError(p, out.theta) : std::numeric_limits<double>::quiet_NaN();
  start.shapeError = shapeError(p, out.theta);
  if (meter) start.imageError = meter->measure(out.theta);
  record(start);
  const int checkpoints = std::max(1, budget.imageErrorCheckpoints);
  int nextCheckpoint = 1;
  // The fraction of the budget spent: steps taken, or seconds used.
  auto spent = [&] { return budget.steps > 0 ? double(loop.state().step) / double(budget.steps) : used / budget.seconds; };
  while (loop.burningIn() || spent() < 1.0) {
    std::optional<GradientResult> g;
    Stopwatch clock;
    try {
      g = loop.next(std::ref(evaluate));
    } catch (const InputError& diverged) {
      out.failure = diverged.what();  // the loop kept the last good parameters
      break;
    }
    used += clock.seconds();
    if (!g) continue;  // burn-in
    out.theta = loop.state().theta;
    out.nonFiniteSamples += droppedSamples(g->stats);
    out.secondsStage1 += g->stats.seconds_stage1();
    EqualTimePoint pt;
    pt.step = int(loop.state().step);
    pt.seconds = used;
    pt.loss = g->stats.loss();
    pt.stats = g->stats;
    pt.parameterError = p.groundTruthKnown() ? parameterError(p, out.theta) : std::numeric_limits<double>::quiet_NaN();
    pt.shapeError = shapeError(p, out.theta);  // like the image error, measured off the clock
    const double fraction = spent();
    if (meter && (fraction >= 1.0 || fraction >= double(nextCheckpoint) / checkpoints)) {
      pt.imageError = meter->measure(out.theta);
      while (fraction >= double(nextCheckpoint) / checkpoints) ++nextCheckpoint;
    }
    record(pt);
  }
  out.theta = loop.state().theta;
  if (!out.failure.empty() && meter && !std::isfinite(out.history.back().imageError))
    out.history.back().imageError = meter->measure(out.theta);
  p.params.write(out.theta, *p.scene);
  return out;
}

}  // namespace invr
