#include "core/optim/equal_time.h"

#include <chrono>
#include <cmath>

#include "core/error.h"

namespace invr {

void writeEqualTimeCsvRow(std::ostream& out, const std::string& method, const EqualTimePoint& pt) {
  auto cell = [&](double v) {
    if (std::isfinite(v)) out << v;
  };
  out << method << "," << pt.step << "," << pt.seconds << ",";
  cell(pt.loss);
  out << ",";
  cell(pt.parameterError);
  out << ",";
  cell(pt.imageError);
  out << "\n";
}

EqualTimeRun runEqualTime(Problem& p, const std::vector<Image>& targets, const GradientOptions& options,
                          const EqualTimeOptions& budget, ImageErrorMeter* meter,
                          const std::function<void(const EqualTimePoint&)>& onPoint) {
  if (!(budget.seconds > 0)) throw InputError("equal-time run: the budget must be positive seconds");
  using Clock = std::chrono::steady_clock;
  GradientEngine engine(*p.scene, p.params, targets, options);
  std::vector<EngineSession> sessions(p.shards.size());
  EqualTimeRun out;
  out.theta = p.initial;
  OptimizerState state;
  double used = 0;  // seconds of budget spent
  auto timed = [&](auto&& f) {
    auto t0 = Clock::now();
    f();
    used += std::chrono::duration<double>(Clock::now() - t0).count();
  };
  auto record = [&](EqualTimePoint pt) {
    out.history.push_back(pt);
    if (onPoint) onPoint(pt);
  };
  EqualTimePoint start;
  start.parameterError = p.groundTruthKnown() ? parameterError(p, out.theta) : std::numeric_limits<double>::quiet_NaN();
  if (meter) start.imageError = meter->measure(out.theta);
  record(start);
  uint64_t counter = 0;
  // The burn-in (ReSTIR's render-only steps) is part of the method's cost.
  int burn = options.method == GradientMethod::Restir ? p.burnIn : 0;
  for (; counter < uint64_t(burn); ++counter) {
    Evaluation e = evaluationAt(p, counter);
    e.renderOnly = true;
    timed([&] { evaluateShards(p, engine, sessions, out.theta, e); });
  }
  const int checkpoints = std::max(1, budget.imageErrorCheckpoints);
  int nextCheckpoint = 1;
  for (int step = 1; used < budget.seconds; ++step, ++counter) {
    Evaluation e = evaluationAt(p, counter);
    e.renderOnly = false;  // the problem's own burn-in length does not apply to this method
    GradientResult g;
    std::vector<float> previous = out.theta;
    timed([&] {
      g = evaluateShards(p, engine, sessions, out.theta, e);
      optimizerStep(p.optimizer, p.params, g.gradient, out.theta, state, p.schedule);
    });
    try {
      checkDivergence(p, uint64_t(step), g.stats.loss, out.theta);
    } catch (const InputError& diverged) {
      out.failure = diverged.what();
      out.theta = std::move(previous);
      break;
    }
    out.nonFiniteSamples += g.stats.nonFiniteSamples;
    out.secondsStage1 += g.stats.secondsStage1;
    EqualTimePoint pt;
    pt.step = step;
    pt.seconds = used;
    pt.loss = g.stats.loss;
    pt.parameterError = p.groundTruthKnown() ? parameterError(p, out.theta) : std::numeric_limits<double>::quiet_NaN();
    bool last = used >= budget.seconds;
    if (meter && (last || used >= budget.seconds * nextCheckpoint / checkpoints)) {
      pt.imageError = meter->measure(out.theta);
      while (used >= budget.seconds * nextCheckpoint / checkpoints) ++nextCheckpoint;
    }
    record(pt);
  }
  if (!out.failure.empty() && meter && !std::isfinite(out.history.back().imageError))
    out.history.back().imageError = meter->measure(out.theta);
  p.params.write(out.theta, *p.scene);
  return out;
}

}  // namespace invr
