#include "core/lights/light_selection.h"

#include <algorithm>
#include <cmath>

namespace invr {

std::vector<float> softmax(std::span<const float> logits) {
  std::vector<float> p(logits.size());
  if (logits.empty()) return p;
  const float top = *std::max_element(logits.begin(), logits.end());
  double sum = 0;
  for (size_t i = 0; i < logits.size(); ++i) sum += (p[i] = float(std::exp(double(logits[i] - top))));
  for (float& x : p) x = float(double(x) / sum);
  return p;
}

void addSoftmaxLogPmfAdjoint(std::span<const float> pmf, std::span<const double> coef, std::span<double> out) {
  double total = 0;
  for (double c : coef) total += c;
  for (size_t k = 0; k < pmf.size(); ++k) out[k] += coef[k] - double(pmf[k]) * total;
}

float lightPowerPerLuminance(const Light& light, float sceneRadius) {
  if (light.kind == LightKind::Environment) return 0.f;
  Light unit = light;
  unit.radiance = unit.intensity = Rgb(1.f);  // luminance 1
  return lightPower(unit, sceneRadius);
}

Rgb powerLogPmfAdjoint(const Light& light, float sceneRadius, float power, double totalPower, double coefLight, double coefSum) {
  if (!(totalPower > 0)) return Rgb(0.f);
  double unit = lightPowerPerLuminance(light, sceneRadius);
  double s = unit * ((power > 0.f ? coefLight / double(power) : 0.0) - coefSum / totalPower);
  return luminanceWeights() * float(s);
}

}  // namespace invr
