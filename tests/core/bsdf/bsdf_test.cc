// BSDF sampling against evaluation: the pdf integrates to at most one, sample() draws from pdf()
// (chi-square test on a sphere histogram), and every sample's weight equals eval / pdf.
#include "core/bsdf/bsdf.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "core/math/rng.h"
#include "test_util.h"

namespace invr {
namespace {

struct Case {
  std::string name;
  Bsdf bsdf;
};

std::vector<Case> cases() {
  std::vector<Case> out;
  Bsdf d;
  d.kind = BsdfKind::Diffuse;
  d.albedo = Rgb(0.8f, 0.5f, 0.2f);
  out.push_back({"diffuse", d});
  for (float a : {0.2f, 0.5f, 0.9f}) {
    Bsdf c;
    c.kind = BsdfKind::RoughConductor;
    c.alpha = a;
    c.eta = Rgb(0.2f, 0.9f, 1.1f);
    c.k = Rgb(3.9f, 2.4f, 2.2f);
    out.push_back({"conductor_a" + std::to_string(a), c});
    Bsdf p;
    p.kind = BsdfKind::RoughPlastic;
    p.alpha = a;
    p.albedo = Rgb(0.6f, 0.3f, 0.7f);
    p.ior = 1.5f;
    out.push_back({"plastic_a" + std::to_string(a), p});
  }
  return out;
}

Vec3 dirFromAngle(float thetaDeg) {
  float t = thetaDeg * kPi / 180.f;
  return {std::sin(t) * 0.6f, std::sin(t) * 0.8f, std::cos(t)};
}

// Integral of pdf over a (cos theta, phi) cell by midpoint quadrature (d omega = dcos dphi).
double cellIntegral(const Bsdf& b, Vec3 wo, double c0, double c1, double p0, double p1, int sub) {
  double sum = 0;
  for (int i = 0; i < sub; ++i)
    for (int j = 0; j < sub; ++j) {
      double c = c0 + (c1 - c0) * (i + 0.5) / sub, p = p0 + (p1 - p0) * (j + 0.5) / sub;
      double s = std::sqrt(std::max(0.0, 1 - c * c));
      sum += b.pdf(wo, Vec3(float(s * std::cos(p)), float(s * std::sin(p)), float(c)));
    }
  return sum * (c1 - c0) * (p1 - p0) / (sub * sub);
}

// Upper quantile of chi-square with k dof at tail probability ~1e-4 (Wilson-Hilferty, z = 3.72).
double chi2Threshold(int k) {
  double z = 3.72, a = 2.0 / (9.0 * k);
  return k * std::pow(1 - a + z * std::sqrt(a), 3);
}

TEST(Bsdf, PdfIntegratesToAtMostOne) {
  for (const auto& c : cases())
    for (float theta : {10.f, 45.f, 80.f}) {
      Vec3 wo = dirFromAngle(theta);
      double integral = 0;
      const int nc = 400, np = 400;
      for (int i = 0; i < nc; ++i)
        for (int j = 0; j < np; ++j)
          integral += cellIntegral(c.bsdf, wo, -1 + 2.0 * i / nc, -1 + 2.0 * (i + 1) / nc, 2 * M_PI * j / np,
                                   2 * M_PI * (j + 1) / np, 2);
      // Quadrature error on these smooth lobes is < 0.5 %; the diffuse lobe must integrate to one.
      EXPECT_LE(integral, 1.005) << c.name << " theta " << theta;
      if (c.bsdf.kind == BsdfKind::Diffuse) EXPECT_NEAR(integral, 1.0, 0.005) << c.name;
      else EXPECT_GE(integral, 0.5) << c.name << " theta " << theta;  // some mass may fall below the horizon
    }
}

TEST(Bsdf, SampleWeightAndPdfMatchEval) {
  for (const auto& c : cases())
    for (float theta : {10.f, 45.f, 80.f}) {
      Vec3 wo = dirFromAngle(theta);
      Sampler s(RngKey{11, 0, 0, uint64_t(theta)});
      for (int i = 0; i < 2000; ++i) {
        auto bs = c.bsdf.sample(wo, s.next1D(), {s.next1D(), s.next1D()});
        if (!bs) continue;
        float pdf = c.bsdf.pdf(wo, bs->wi);
        ASSERT_NEAR(bs->pdf, pdf, 2e-3f * pdf + 1e-6f) << c.name;
        Rgb expected = c.bsdf.eval(wo, bs->wi) / pdf;
        for (int k = 0; k < 3; ++k) ASSERT_NEAR(bs->weight[k], expected[k], 2e-3f * expected[k] + 1e-6f) << c.name;
      }
    }
}

TEST(Bsdf, SamplingMatchesPdfChiSquare) {
  const int nTheta = 20, nPhi = 40, n = 200000;
  for (const auto& c : cases())
    for (float theta : {30.f, 70.f}) {
      Vec3 wo = dirFromAngle(theta);
      std::vector<double> observed(nTheta * nPhi, 0), expected(nTheta * nPhi, 0);
      Sampler s(RngKey{12, 0, 0, uint64_t(theta)});
      for (int i = 0; i < n; ++i) {
        auto bs = c.bsdf.sample(wo, s.next1D(), {s.next1D(), s.next1D()});
        if (!bs) continue;
        int ci = std::clamp(int((bs->wi.z + 1) * 0.5 * nTheta), 0, nTheta - 1);
        double phi = std::atan2(bs->wi.y, bs->wi.x);
        if (phi < 0) phi += 2 * M_PI;
        int pj = std::clamp(int(phi / (2 * M_PI) * nPhi), 0, nPhi - 1);
        // INVR_TEST_MUTATE: a sampler that many times too often above 60 degrees from the pole.
        observed[size_t(ci * nPhi + pj)] += ci >= 3 * nTheta / 4 ? test::mutation() : 1.0;
      }
      for (int i = 0; i < nTheta; ++i)
        for (int j = 0; j < nPhi; ++j)
          expected[size_t(i * nPhi + j)] = n * cellIntegral(c.bsdf, wo, -1 + 2.0 * i / nTheta, -1 + 2.0 * (i + 1) / nTheta,
                                                            2 * M_PI * j / nPhi, 2 * M_PI * (j + 1) / nPhi, 12);
      // Pool cells with fewer than 5 expected samples (chi-square needs them reasonably large).
      double chi2 = 0, pooledObs = 0, pooledExp = 0;
      int dof = 0;
      for (size_t k = 0; k < observed.size(); ++k) {
        if (expected[k] < 5) { pooledObs += observed[k]; pooledExp += expected[k]; continue; }
        chi2 += (observed[k] - expected[k]) * (observed[k] - expected[k]) / expected[k];
        ++dof;
      }
      if (pooledExp >= 5) { chi2 += (pooledObs - pooledExp) * (pooledObs - pooledExp) / pooledExp; ++dof; }
      else EXPECT_LT(pooledObs, 5 + 5 * std::sqrt(5.0)) << c.name << ": samples where the pdf says there are none";
      EXPECT_LT(chi2, chi2Threshold(dof - 1)) << c.name << " theta " << theta << " dof " << dof;
      // Power: a sampler off by a relative delta over cells holding a tenth of the probability adds
      // about delta^2 n / 10 to chi2 (on top of its expected dof - 1): the smallest delta that
      // crosses the threshold.
      test::expectPowerOf(std::string(c.name) + " theta " + std::to_string(int(theta)) + ", an error over a tenth of the probability",
                          std::sqrt(std::max(0.0, chi2Threshold(dof - 1) - (dof - 1)) / (0.1 * n)));
    }
}

TEST(Bsdf, AlbedoAtMostOne) {
  // E[weight] is the directional albedo; a passive surface reflects at most what arrives.
  for (const auto& c : cases())
    for (float theta : {0.f, 60.f, 85.f}) {
      Vec3 wo = dirFromAngle(theta);
      test::MeanSE m;
      Sampler s(RngKey{13, 0, 0, uint64_t(theta)});
      for (int i = 0; i < 50000; ++i) {
        auto bs = c.bsdf.sample(wo, s.next1D(), {s.next1D(), s.next1D()});
        m.add(bs ? maxComponent(bs->weight) : 0.0);
      }
      EXPECT_LE(m.mean, 1.0 + test::kSigmas * m.se()) << c.name << " theta " << theta;
      // A bound, not an estimate: an albedo 10 % over one would show.
      test::expectPower(std::string(c.name) + " theta " + std::to_string(int(theta)) + ", albedo <= 1", m.se(), 1.0);
    }
}

// Adjoints next to their primals: d eval / d albedo and d eval / d alpha against central
// differences of eval (deterministic; the tolerance covers float rounding in eval).
TEST(Bsdf, DerivativesMatchFiniteDifferences) {
  for (const auto& c : cases())
    for (float theta : {15.f, 50.f, 75.f}) {
      Vec3 wo = dirFromAngle(theta);
      Sampler s(RngKey{14, 0, 0, uint64_t(theta)});
      for (int i = 0; i < 200; ++i) {
        Vec3 wi = sampleCosineHemisphere({s.next1D(), s.next1D()});
        if (wi.z < 0.05f) continue;
        BsdfDerivatives d = c.bsdf.evalDerivatives(wo, wi);
        const float h = 1e-3f;
        Bsdf plus = c.bsdf, minus = c.bsdf;
        plus.alpha += h;
        minus.alpha -= h;
        Rgb fdAlpha = (plus.eval(wo, wi) - minus.eval(wo, wi)) / (2 * h);
        for (int k = 0; k < 3; ++k) {
          float tol = 5e-3f * std::abs(fdAlpha[k]) + 1e-4f;
          ASSERT_NEAR(d.dAlpha[k], c.bsdf.kind == BsdfKind::Diffuse ? 0.f : fdAlpha[k], tol) << c.name;
          Bsdf pa = c.bsdf, ma = c.bsdf;
          pa.albedo[k] += h;
          ma.albedo[k] -= h;
          float fdAlbedo = (pa.eval(wo, wi)[k] - ma.eval(wo, wi)[k]) / (2 * h);
          ASSERT_NEAR(d.dAlbedo[k], fdAlbedo, 2e-3f * std::abs(fdAlbedo) + 1e-5f) << c.name;
        }
      }
    }
}

TEST(Bsdf, DeltaLobes) {
  Bsdf m;
  m.kind = BsdfKind::Mirror;
  m.reflectance = Rgb(0.9f);
  Vec3 wo = normalize(Vec3(0.3f, -0.2f, 0.9f));
  auto s = m.sample(wo, 0.5f, {0.5f, 0.5f});
  ASSERT_TRUE(s);
  EXPECT_TRUE(s->delta);
  EXPECT_NEAR(s->wi.x, -wo.x, 1e-6f);
  EXPECT_NEAR(s->wi.z, wo.z, 1e-6f);
  EXPECT_TRUE(isBlack(m.eval(wo, s->wi)));

  // Glass: reflection chosen with probability F, refraction obeys Snell's law, weight 1/eta^2.
  Bsdf g;
  g.kind = BsdfKind::Dielectric;
  g.ior = 1.5f;
  float F = fresnelDielectric(wo.z, 1.5f);
  auto r = g.sample(wo, 0.5f * F, {0, 0});
  auto t = g.sample(wo, 0.5f * (1 + F), {0, 0});
  ASSERT_TRUE(r && t);
  EXPECT_FALSE(r->transmitted);
  EXPECT_TRUE(t->transmitted);
  float sinI = std::sqrt(1 - wo.z * wo.z), sinT = std::sqrt(1 - t->wi.z * t->wi.z);
  EXPECT_NEAR(sinI, 1.5f * sinT, 1e-5f);
  EXPECT_LT(t->wi.z, 0.f);
  EXPECT_NEAR(t->weight.x, 1.f / 2.25f, 1e-6f);
  // Total internal reflection from inside at a grazing angle.
  Vec3 inside = normalize(Vec3(0.9f, 0.f, -0.2f));
  auto tir = g.sample(inside, 0.999f, {0, 0});
  ASSERT_TRUE(tir);
  EXPECT_FALSE(tir->transmitted);
}

}  // namespace
}  // namespace invr
