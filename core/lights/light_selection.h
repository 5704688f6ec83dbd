// Which light next-event estimation samples, and the adjoints of that choice's probability.
// Two rules: by power (the default; the probability depends on every light's intensity), or a
// softmax over logits (sampling parameters a job can optimise, Yan et al. 2024 §6: "light
// selection probabilities"). The variance estimators need d log pmf_i for the score of each choice;
// a walk accumulates one coefficient per light and the adjoints here expand them in O(lights).
#pragma once

#include <span>
#include <vector>

#include "core/lights/light.h"

namespace invr {

// softmax(logits): the selection pmf of a logits rule. Stable for any finite logits.
std::vector<float> softmax(std::span<const float> logits);

// sum_i coef_i * d log pmf_i / d logit_k, for every k, added into out[k]:
// d log pmf_i / d logit_k = [i == k] - pmf_k, so the sum is coef_k - pmf_k * sum_i coef_i.
void addSoftmaxLogPmfAdjoint(std::span<const float> pmf, std::span<const double> coef, std::span<double> out);

// Power per unit luminance of the light's radiance or intensity: lightPower is linear in it, so
// d power / d value_c = luminanceWeights()_c * this (0 for image environments, never optimised).
float lightPowerPerLuminance(const Light& light, float sceneRadius);

// Power-based rule, pmf_i = P_i / sum P: sum_i coef_i * d log pmf_i / d value_{k,c} for light k's
// radiance or intensity channel c is luminanceWeights()_c * unit_k * (coef_k / P_k - sum coef / sum P)
// with unit_k = lightPowerPerLuminance. Returns that per channel for light k.
Rgb powerLogPmfAdjoint(const Light& light, float sceneRadius, float power, double totalPower, double coefLight, double coefSum);

}  // namespace invr
