#include "core/optim/optimizer.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace invr {

namespace {

// One slot's update in coordinates w (theta itself, or Large Steps' u) with gradient g there.
void stepSlot(OptimizerKind kind, const ParameterSlot& slot, std::vector<double>& w, const std::vector<double>& g, OptimizerState& st,
              double decay, double c1, double c2, const AdamSettings& a) {
  if (kind == OptimizerKind::Sgd) {
    for (uint32_t k = 0; k < slot.size; ++k) w[k] -= decay * slot.learningRate * g[k];
    return;
  }
  double vmax = 0;
  for (uint32_t k = 0; k < slot.size; ++k) {
    const size_t i = slot.offset + k;
    st.m[i] = a.beta1 * st.m[i] + (1 - a.beta1) * g[k];
    st.v[i] = a.beta2 * st.v[i] + (1 - a.beta2) * g[k] * g[k];
    vmax = std::max(vmax, st.v[i]);
  }
  for (uint32_t k = 0; k < slot.size; ++k) {
    const size_t i = slot.offset + k;
    const double v = kind == OptimizerKind::AdamUniform ? vmax : st.v[i];
    w[k] -= decay * slot.learningRate * (st.m[i] / c1) / (std::sqrt(v / c2) + a.epsilon);
  }
}

}  // namespace

void optimizerStep(OptimizerKind kind, const ParameterRegistry& params, const std::vector<double>& g,
                   std::vector<float>& theta, OptimizerState& st, const LearningRateSchedule& schedule, const AdamSettings& a) {
  if (g.size() != theta.size() || theta.size() != params.size()) throw std::invalid_argument("optimizerStep: size mismatch");
  const double decay = schedule.factor(st.step);
  st.step += 1;
  if (kind != OptimizerKind::Sgd && st.m.size() != theta.size()) {
    st.m.assign(theta.size(), 0.0);
    st.v.assign(theta.size(), 0.0);
  }
  const double c1 = 1.0 - std::pow(a.beta1, double(st.step)), c2 = 1.0 - std::pow(a.beta2, double(st.step));
  const auto& slots = params.slots();
  if (st.largeSteps.size() != slots.size()) st.largeSteps.assign(slots.size(), nullptr);
  for (size_t s = 0; s < slots.size(); ++s) {
    const ParameterSlot& slot = slots[s];
    std::vector<double> x(theta.begin() + slot.offset, theta.begin() + slot.offset + slot.size);
    std::vector<double> gx(g.begin() + slot.offset, g.begin() + slot.offset + slot.size);
    if (slot.largeStepsLambda > 0.f) {
      auto& ls = st.largeSteps[s];
      if (!ls) ls = std::make_shared<const LargeSteps>(slot.size / 3, params.vertexEdges(slot), double(slot.largeStepsLambda));
      std::vector<double> u = ls->toU(x);
      stepSlot(kind, slot, u, ls->solve(gx), st, decay, c1, c2, a);
      x = ls->solve(u);
    } else {
      stepSlot(kind, slot, x, gx, st, decay, c1, c2, a);
    }
    for (uint32_t k = 0; k < slot.size; ++k) theta[slot.offset + k] = std::clamp(float(x[k]), slot.lower, slot.upper);
  }
}

}  // namespace invr
