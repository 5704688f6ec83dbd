// Equal-time optimisation: the evaluation suite's and `invr-lab bench reconstruct`'s loop. A method
// gets a wall-clock budget (its burn-in counts against it) and takes as many steps as fit; the
// image error is measured at a few checkpoints with the clock stopped, so measuring costs no
// method any of its budget.
#pragma once

#include <functional>
#include <limits>
#include <optional>
#include <string>

#include "core/optim/image_error.h"
#include "core/optim/local_run.h"
#include "core/optim/results_io.h"

namespace invr {

struct EqualTimeOptions {
  double seconds = 60;
  // > 0: the budget is this many gradient steps instead of `seconds` (fixed iteration counts, as
  // Wang et al. 2023's Table 1); burn-in steps are not counted.
  int steps = 0;
  int imageErrorCheckpoints = 8;  // evenly spaced in the budget, plus the start and the end
};

struct EqualTimePoint {
  int step = 0;          // 0: the initial parameters
  double seconds = 0;    // budget used so far (measurement excluded)
  double loss = std::numeric_limits<double>::quiet_NaN();  // NaN at step 0
  double parameterError = 0;
  double shapeError = -1;  // jobs with a vertex parameter and a known truth mesh (problem.h's shapeError)
  double imageError = std::numeric_limits<double>::quiet_NaN();  // NaN between checkpoints
  std::optional<invr::v1::GradientStats> stats;  // the step's (none at step 0)
};

struct EqualTimeRun {
  std::vector<float> theta;
  std::vector<EqualTimePoint> history;
  uint64_t nonFiniteSamples = 0;
  double secondsStage1 = 0;
  // Set when the run diverged (checkDivergence's message); theta and history end at the last
  // good step, so a comparison can report the failure and go on.
  std::string failure;
};

// The convergence CSV's row of a point (results_io.h).
ConvergenceRow convergenceRow(const std::string& method, const EqualTimePoint& point);

// Where a run settled: the RMS parameter error over the last quarter of `budgetSeconds`. A run at
// its noise floor keeps moving, so its final value is one draw from that floor. Falls back to the
// final value when no step fell in that quarter, and keeps the -1 of jobs without ground truth.
double tailParameterError(const std::vector<EqualTimePoint>& history, double budgetSeconds);
// The same for the shape error (-1 for jobs without one).
double tailShapeError(const std::vector<EqualTimePoint>& history, double budgetSeconds);
// The same over the last quarter of a budget in steps or seconds (EqualTimeOptions::steps).
double tailParameterError(const std::vector<EqualTimePoint>& history, const EqualTimeOptions& budget);
double tailShapeError(const std::vector<EqualTimePoint>& history, const EqualTimeOptions& budget);

// Optimises problem.initial with `options` (the problem's own gradient settings are ignored)
// until the budget (seconds, or steps) is spent. `meter` may be null (no image error). `onPoint` sees every point.
EqualTimeRun runEqualTime(Problem& problem, const std::vector<Image>& targets, const GradientOptions& options,
                          const EqualTimeOptions& budget, ImageErrorMeter* meter,
                          const std::function<void(const EqualTimePoint&)>& onPoint = {});

}  // namespace invr
