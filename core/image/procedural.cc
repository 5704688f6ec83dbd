#include "core/image/procedural.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "core/math/rng.h"

namespace invr {

Image makeProceduralImage(const ProceduralSpec& s) {
  if (s.width <= 0 || s.height <= 0 || s.width > 8192 || s.height > 8192)
    throw InputError("procedural image: size must be in 1..8192 (got " + std::to_string(s.width) + "x" + std::to_string(s.height) + ")");
  Image im(s.width, s.height, 3);
  if (s.pattern == "checker") {
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x) im.setRgb(x, y, ((x * 8 / s.width + y * 8 / s.height) & 1) ? s.a : s.b);
  } else if (s.pattern == "gradient") {
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x) {
        float t = (float(x) + 0.5f) / float(s.width);
        im.setRgb(x, y, s.a * (1.f - t) + s.b * t);
      }
  } else if (s.pattern == "painting") {
    // A still life: coloured petals (soft discs) and stems over a warm background. Enough
    // structure in both bright and dark areas to show texture reconstruction error.
    Sampler rng(RngKey{s.seed, 7, 0, 0, 0});
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x) {
        float v = (float(y) + 0.5f) / float(s.height);
        im.setRgb(x, y, s.b * (0.6f + 0.4f * v));
      }
    const Rgb palette[] = {{0.85f, 0.2f, 0.3f}, {0.95f, 0.75f, 0.2f}, {0.3f, 0.35f, 0.85f}, {0.9f, 0.5f, 0.7f}, {0.2f, 0.6f, 0.3f}};
    for (int k = 0; k < 9; ++k) {
      float cx = 0.1f + 0.8f * rng.next1D(), cy = 0.15f + 0.5f * rng.next1D();
      float r = 0.05f + 0.08f * rng.next1D();
      Rgb col = palette[k % 5];
      for (int y = 0; y < s.height; ++y)
        for (int x = 0; x < s.width; ++x) {
          float u = (float(x) + 0.5f) / float(s.width), v = (float(y) + 0.5f) / float(s.height);
          float du = u - cx, dv = v - cy;
          float ang = std::atan2(dv, du);
          float petal = r * (0.75f + 0.25f * std::cos(5.f * ang));  // five-petal outline
          float d = std::sqrt(du * du + dv * dv);
          if (d < petal) im.setRgb(x, y, col * (0.7f + 0.3f * (1.f - d / petal)));
          else if (std::abs(du) < 0.006f && v > cy && v < cy + 0.35f) im.setRgb(x, y, s.a);
        }
    }
  } else if (s.pattern == "backlit_sky") {
    // Dim sky, darker ground, and a bright sun-like lobe at u = 0 (behind a camera looking -z).
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x) {
        float u = (float(x) + 0.5f) / float(s.width), v = (float(y) + 0.5f) / float(s.height);
        float du = std::min(u, 1.f - u), dv = v - 0.42f;
        float lobe = std::exp(-(du * du + dv * dv) / (2.f * 0.03f * 0.03f));
        Rgb sky = v < 0.5f ? s.b * (0.5f + 0.5f * (0.5f - v) * 2.f) : s.b * 0.2f;
        im.setRgb(x, y, sky + s.a * lobe);
      }
  } else if (s.pattern == "sun_sky") {
    // A sky from color_b at the zenith to twice as bright at the horizon, a darker brown ground, and
    // a small sun of colour color_a, 45 degrees high at u = 0.3 (a Gaussian disc of 3.6 degrees).
    const Rgb ground = Rgb(0.9f, 0.75f, 0.55f) * (0.4f * luminance(s.b));
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x) {
        const float u = (float(x) + 0.5f) / float(s.width), v = (float(y) + 0.5f) / float(s.height);
        // Round on the sphere: a step in u spans 2 pi sin(theta), one in v spans pi.
        const float du = 1.414f * (u - 0.3f), dv = v - 0.25f;
        const float sun = std::exp(-(du * du + dv * dv) / (2.f * 0.02f * 0.02f));
        im.setRgb(x, y, (v < 0.5f ? s.b * (1.f + 2.f * v) : ground) + s.a * sun);
      }
  } else if (s.pattern == "bumps") {
    // Smooth hills (a relief's heights): a sum of Gaussians of random place, width and height,
    // scaled so that the lowest texel is b and the highest a.
    Sampler rng(RngKey{s.seed, 11, 0, 0, 0});
    struct Bump {
      float u, v, width, height;
    };
    std::vector<Bump> bumps;
    for (int k = 0; k < 12; ++k) {
      const float u = rng.next1D(), v = rng.next1D(), w = 0.06f + 0.12f * rng.next1D(), h = 0.3f + 0.7f * rng.next1D();
      bumps.push_back({u, v, w, h});
    }
    std::vector<float> t(size_t(s.width) * size_t(s.height));
    float lo = 1e30f, hi = -1e30f;
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x) {
        const float u = (float(x) + 0.5f) / float(s.width), v = (float(y) + 0.5f) / float(s.height);
        float sum = 0;
        for (const Bump& b : bumps) sum += b.height * std::exp(-((u - b.u) * (u - b.u) + (v - b.v) * (v - b.v)) / (2.f * b.width * b.width));
        t[size_t(y) * size_t(s.width) + size_t(x)] = sum;
        lo = std::min(lo, sum);
        hi = std::max(hi, sum);
      }
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x) {
        const float f = (t[size_t(y) * size_t(s.width) + size_t(x)] - lo) / std::max(hi - lo, 1e-20f);
        im.setRgb(x, y, s.b * (1.f - f) + s.a * f);
      }
  } else {
    throw InputError("procedural image: unknown pattern '" + s.pattern + "' (use checker, painting, backlit_sky, sun_sky, gradient or bumps)");
  }
  return im;
}

}  // namespace invr
