// A job's gradient steps in this process, as an in-process job evaluates them (LocalEvaluator):
// one engine, a reservoir session per shard of the views, every shard with views in the batch one
// after another, their statistics summed. bench step and bench scale time these steps.
#pragma once

#include <vector>

#include "core/diff/gradient_engine.h"
#include "core/diff/gradient_stats.h"
#include "core/job/problem.h"

namespace invr::cli {

struct StepEngine {
  const Problem& p;
  GradientEngine engine;
  std::vector<EngineSession> sessions;
  StepEngine(const Problem& problem, const std::vector<Image>& targets)
      : p(problem), engine(*problem.scene, problem.params, targets, problem.gradient), sessions(problem.shards.size()) {}
  v1::GradientStats evaluate(uint64_t counter) {
    const Evaluation e = evaluationAt(p, counter);
    v1::GradientStats total;
    for (size_t s = 0; s < p.shards.size(); ++s) {
      const GradientRequest r = shardRequest(p, e, s);
      if (!r.views.empty()) addGradientStats(total, engine.evaluate(r, sessions[s]).stats);
    }
    return total;
  }
};

// The evaluation counter of a measured step: the job's burn-in (ReSTIR's render-only steps),
// then `warmup` gradient steps.
inline uint64_t measuredCounter(const Problem& p, int warmup) { return uint64_t(p.burnIn) + uint64_t(warmup); }

}  // namespace invr::cli
