#include "core/optim/optimizer.h"

#include <cmath>

#include "core/error.h"

namespace invr {

void optimizerStep(OptimizerKind kind, const ParameterRegistry& params, const std::vector<double>& g,
                   std::vector<float>& theta, OptimizerState& st, const LearningRateSchedule& schedule, const AdamSettings& a) {
  if (g.size() != theta.size() || theta.size() != params.size()) throw std::invalid_argument("optimizerStep: size mismatch");
  const double decay = schedule.factor(st.step);
  st.step += 1;
  if (kind == OptimizerKind::Adam && st.m.size() != theta.size()) {
    st.m.assign(theta.size(), 0.0);
    st.v.assign(theta.size(), 0.0);
  }
  const double c1 = 1.0 - std::pow(a.beta1, double(st.step)), c2 = 1.0 - std::pow(a.beta2, double(st.step));
  for (const auto& slot : params.slots())
    for (uint32_t k = 0; k < slot.size; ++k) {
      size_t i = slot.offset + k;
      double step;
      if (kind == OptimizerKind::Adam) {
        st.m[i] = a.beta1 * st.m[i] + (1 - a.beta1) * g[i];
        st.v[i] = a.beta2 * st.v[i] + (1 - a.beta2) * g[i] * g[i];
        step = decay * slot.learningRate * (st.m[i] / c1) / (std::sqrt(st.v[i] / c2) + a.epsilon);
      } else {
        step = decay * slot.learningRate * g[i];
      }
      theta[i] = std::clamp(float(double(theta[i]) - step), slot.lower, slot.upper);
    }
}


}  // namespace invr
