// Sampling-density adjoints (what variance derivatives need, Yan et al. 2024 §4.2) against central
// differences of the densities they differentiate. Deterministic: relative 1e-3 (plus an absolute
// floor where a derivative is near zero). The densities are float code with cancellation inside
// (GGX's c^2 (a^2 - 1) + 1), so h is large (5 % of the value) and the difference is Richardson-
// extrapolated from h and h/2: truncation O(h^4), rounding far below 1e-3.
#include <gtest/gtest.h>

#include "core/bsdf/bsdf.h"
#include "core/math/rng.h"

namespace invr {
namespace {

constexpr double kRel = 1e-3;

// Richardson-extrapolated central difference of f at x.
template <class F>
double derivative(F f, float x) {
  auto central = [&](float h) { return (double(f(x + h)) - double(f(x - h))) / (double(x + h) - double(x - h)); };
  const float h = 0.05f * x;
  return (4.0 * central(0.5f * h) - central(h)) / 3.0;
}

void expectClose(double analytic, double fd, double scale, const char* what) {
  EXPECT_NEAR(analytic, fd, kRel * std::max(std::abs(fd), 1e-2 * scale)) << what;
}

// Directions covering grazing, normal and below-horizon reflections.
std::vector<std::pair<Vec3, Vec3>> directionPairs() {
  std::vector<std::pair<Vec3, Vec3>> out;
  Sampler s(RngKey{42, 0, 0, 0, 0});
  for (int i = 0; i < 40; ++i) {
    Vec3 wo = sampleCosineHemisphere(Vec2(s.next1D(), s.next1D()));
    Vec3 wi = normalize(Vec3(s.next1D() * 2 - 1, s.next1D() * 2 - 1, s.next1D() * 1.4f - 0.4f));
    if (wo.z < 0.05f) continue;
    out.push_back({wo, wi});
  }
  return out;
}

TEST(PdfAdjoint, GgxReflectionDensityWithRespectToAlpha) {
  // From alpha 0.1: below it the float primal near the peak (D ~ 1 / (pi alpha^2)) loses the
  // digits a 1e-3 comparison needs.
  for (float alpha : {0.1f, 0.2f, 0.5f, 0.9f})
    for (auto [wo, wi] : directionPairs()) {
      double fd = derivative([&](float a) { return ggx::pdfReflect(wo, wi, a); }, alpha);
      expectClose(ggx::dPdfReflect_dAlpha(wo, wi, alpha), fd, ggx::pdfReflect(wo, wi, alpha) / alpha, "ggx");
    }
}

TEST(PdfAdjoint, RoughConductorSampledDensity) {
  for (float alpha : {0.1f, 0.4f, 0.8f})
    for (auto [wo, wi] : directionPairs()) {
      double fd = derivative([&](float a) { return rough_conductor::sampledPdf(a, wo, wi).pdf; }, alpha);
      PdfDerivatives d = rough_conductor::sampledPdf(alpha, wo, wi);
      expectClose(d.dAlpha, fd, d.pdf / alpha, "conductor");
    }
}

// Rough plastic's mixture: alpha moves the specular lobe, the albedo the lobe choice.
TEST(PdfAdjoint, RoughPlasticMixtureDensity) {
  int albedoChecked = 0;
  for (float alpha : {0.1f, 0.4f})
    for (Rgb albedo : {Rgb(0.1f, 0.08f, 0.05f), Rgb(0.5f, 0.3f, 0.2f), Rgb(0.05f, 0.02f, 0.01f)})
      for (auto [wo, wi] : directionPairs()) {
        PdfDerivatives d = rough_plastic::sampledPdf(albedo, alpha, 1.5f, wo, wi);
        double fd = derivative([&](float a) { return rough_plastic::sampledPdf(albedo, a, 1.5f, wo, wi).pdf; }, alpha);
        expectClose(d.dAlpha, fd, d.pdf / alpha, "plastic alpha");
        for (int c = 0; c < 3; ++c) {
          auto withChannel = [&](float v) {
            Rgb a = albedo;
            a[c] = v;
            return a;
          };
          // The lobe probability is clamped to [0.1, 0.9]: skip points within h of a clamp.
          auto ps = [&](Rgb a) { return rough_plastic::specularProbability(a, 1.5f, wo); };
          const float ha = 0.05f * albedo[c];
          if (ps(withChannel(albedo[c] + ha)) <= 0.1f || ps(withChannel(albedo[c] + ha)) >= 0.9f || ps(withChannel(albedo[c] - ha)) <= 0.1f ||
              ps(withChannel(albedo[c] - ha)) >= 0.9f)
            continue;
          double fdA = derivative([&](float v) { return rough_plastic::sampledPdf(withChannel(v), alpha, 1.5f, wo, wi).pdf; }, albedo[c]);
          expectClose(d.dAlbedo[c], fdA, d.pdf / albedo[c], "plastic albedo");
          ++albedoChecked;
        }
      }
  EXPECT_GT(albedoChecked, 50) << "the albedo derivative was barely exercised (every point clamped)";
}

// The whole-sphere density agrees with pdf() above the horizon and keeps the specular lobe's
// density below it (what sample() draws there before rejecting it).
TEST(PdfAdjoint, SampledDensityMatchesPdfAboveTheHorizon) {
  Bsdf b;
  b.kind = BsdfKind::RoughPlastic;
  b.albedo = Rgb(0.4f, 0.3f, 0.2f);
  b.alpha = 0.3f;
  for (auto [wo, wi] : directionPairs()) {
    if (wi.z > 0.f) EXPECT_NEAR(b.sampledPdf(wo, wi).pdf, b.pdf(wo, wi), 1e-5f * (1.f + b.pdf(wo, wi)));
    else EXPECT_EQ(b.pdf(wo, wi), 0.f);
  }
}

}  // namespace
}  // namespace invr
