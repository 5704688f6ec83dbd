// Environment-map importance sampling: the pdf of each sample matches environmentPdf, the pdf
// integrates to one over the sphere, and E[L/pdf] equals the exact integral of the radiance.
#include <gtest/gtest.h>

#include "core/image/procedural.h"
#include "core/lights/light.h"
#include "test_util.h"

namespace invr {
namespace {

Light makeEnv() {
  Light l;
  l.kind = LightKind::Environment;
  ProceduralSpec spec{"backlit_sky", 64, 32, Rgb(30.f, 20.f, 10.f), Rgb(0.3f, 0.4f, 0.5f), 0};
  l.envImage = std::make_shared<Image>(makeProceduralImage(spec));
  buildEnvironmentDistribution(l);
  return l;
}

TEST(EnvironmentLight, DirectionMappingRoundTrips) {
  for (float u : {0.1f, 0.3f, 0.77f})
    for (float v : {0.2f, 0.5f, 0.9f}) {
      Vec2 back = directionToLatLong(latLongToDirection({u, v}));
      EXPECT_NEAR(back.x, u, 1e-5f);
      EXPECT_NEAR(back.y, v, 1e-5f);
    }
  EXPECT_NEAR(latLongToDirection({0.5f, 0.5f}).z, -1.f, 1e-6f);  // u = 0.5 looks along -z
  EXPECT_NEAR(latLongToDirection({0.5f, 0.f}).y, 1.f, 1e-6f);    // v = 0 is up
}

TEST(EnvironmentLight, SampledPdfMatchesPdfFunction) {
  Light l = makeEnv();
  Scene none;
  Sampler s(RngKey{21});
  for (int i = 0; i < 5000; ++i) {
    LightSample ls = sampleLight(l, none, Vec3(0.f), {s.next1D(), s.next1D()});
    if (!(ls.pdf > 0.f)) continue;
    float p = environmentPdf(l, ls.wi);
    ASSERT_NEAR(ls.pdf, p, 1e-3f * p);
    Rgb L = environmentRadiance(l, ls.wi);
    ASSERT_EQ(ls.radiance, L);
  }
}

TEST(EnvironmentLight, PdfIntegratesToOneAndEstimatorIsUnbiased) {
  Light l = makeEnv();
  const Image& im = *l.envImage;
  // Exact integrals over texels: solid angle of texel row y is dphi * (cos theta0 - cos theta1).
  double pdfIntegral = 0, radianceIntegral = 0;
  for (int y = 0; y < im.height(); ++y) {
    double t0 = M_PI * y / im.height(), t1 = M_PI * (y + 1) / im.height();
    double omega = (2 * M_PI / im.width()) * (std::cos(t0) - std::cos(t1));
    for (int x = 0; x < im.width(); ++x) {
      Vec3 w = latLongToDirection({(x + 0.5f) / im.width(), (y + 0.5f) / im.height()});
      radianceIntegral += luminance(im.rgb(x, y)) * omega;
      // The pdf is constant per texel in (u, v), not in direction; integrate it finely in theta.
      const int sub = 16;
      for (int k = 0; k < sub; ++k) {
        double ta = t0 + (t1 - t0) * k / sub, tb = t0 + (t1 - t0) * (k + 1) / sub;
        Vec3 wk = latLongToDirection({(x + 0.5f) / im.width(), float((0.5 * (ta + tb)) / M_PI)});
        pdfIntegral += environmentPdf(l, wk) * (2 * M_PI / im.width()) * (std::cos(ta) - std::cos(tb));
      }
      (void)w;
    }
  }
  EXPECT_NEAR(pdfIntegral, 1.0, 1e-3);
  Scene none;
  test::MeanSE est;
  Sampler s(RngKey{22});
  for (int i = 0; i < 100000; ++i) {
    LightSample ls = sampleLight(l, none, Vec3(0.f), {s.next1D(), s.next1D()});
    est.add(ls.pdf > 0.f ? luminance(ls.radiance) / ls.pdf : 0.0);
  }
  est.mean *= test::mutation();
  EXPECT_NEAR(est.mean, radianceIntegral, test::kSigmas * est.se() + 1e-4 * radianceIntegral);
  test::expectPower("E[L / pdf] against the integral", est.se() + 1e-4 * radianceIntegral / test::kSigmas, radianceIntegral);
}

}  // namespace
}  // namespace invr
