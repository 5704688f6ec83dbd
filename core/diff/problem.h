// An inverse-rendering problem built from a job: the scene (as ground truth), the parameters to
// recover with their starting point, the gradient settings and the optimiser. Validation errors
// name the job field at fault.
#pragma once

#include <memory>

#include "core/diff/gradient_engine.h"
#include "core/optim/optimizer.h"
#include "core/scene/scene_builder.h"

namespace invr {

struct Problem {
  std::unique_ptr<Scene> scene;
  ParameterRegistry params;
  std::vector<float> truth, initial;
  GradientOptions gradient;
  OptimizerKind optimizer = OptimizerKind::Adam;
  int steps = 100;
  int viewsPerStep = 0;  // 0: all
  int burnIn = 0;
  int targetSpp = 256;
  uint64_t seed = 0;
};

Problem buildProblem(const invr::v1::JobSpec& job, const AssetResolver& assets = {});

// Ground-truth targets: the truth rendered with the forward renderer (direct illumination,
// visibility-aware RIS with 16 candidates, target_spp samples per pixel).
std::vector<Image> renderTargets(Problem& problem);

// Root-mean-square difference between theta and the truth.
double parameterError(const Problem& problem, const std::vector<float>& theta);

// The views of step `step`: a deterministic mini-batch (a seeded shuffle per step) or all views.
std::vector<int> viewsForStep(const Problem& problem, uint64_t step);

}  // namespace invr
