#pragma once

#include <atomic>
#include <cstdint>
#include <vector>

#include "core/math/rng.h"
#include "core/math/vec.h"

namespace invr {

enum class LightEstimator {
  NeeMis,  // one light sample (chosen by power) + BSDF sampling, combined with the power heuristic
  Ris,     // streaming RIS over M light candidates (Wang et al. 2023, Alg. 1)
};

struct RenderOptions {
  int spp = 16;
  int maxDepth = 1;  // path vertices after the camera; 1 = direct illumination
  LightEstimator estimator = LightEstimator::NeeMis;
  int risCandidates = 8;
  bool risVisibilityInTarget = false;
  int russianRouletteDepth = 3;
  uint64_t seed = 0;
  SamplerKind sampler = SamplerKind::Independent;  // how a pixel's samples relate (rng.h)
  // Checked every 256 samples of a pixel: when it becomes true, renderView throws
  // EvaluationCancelled.
  const std::atomic<bool>* cancel = nullptr;
  // A crop window: pixels [x0, x1) x [y0, y1) are rendered, the rest of the image stays black;
  // empty (the default) renders the whole film. A pixel's value does not depend on the window
  // (its samples are keyed by its own index), so finite differences can be taken over just the
  // pixels a parameter moves.
  struct Window {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    bool empty() const { return x1 <= x0 || y1 <= y0; }
  } window;
};

// Longest walk any setting allows (max_depth is validated against it).
inline constexpr int kMaxWalkDepth = 64;

// Rays traced, by purpose (for throughput figures), and by the path depth they were traced at
// (the ray that reaches vertex d plus the shadow rays of vertex d; path walks only). The per-depth
// counts calibrate the render-time model of variance-aware jobs (Yan et al. 2024, Eq. 36).
struct RayStats {
  uint64_t camera = 0, bounce = 0, shadow = 0;
  uint64_t byDepth[kMaxWalkDepth + 1] = {};
  uint64_t total() const { return camera + bounce + shadow; }
  RayStats& operator+=(const RayStats& o) {
    camera += o.camera;
    bounce += o.bounce;
    shadow += o.shadow;
    for (int d = 0; d <= kMaxWalkDepth; ++d) byDepth[d] += o.byDepth[d];
    return *this;
  }
};

// Per-path instrumentation (optional). The rays themselves: core/geometry/ray_log.h.
struct PathContext {
  RayStats* stats = nullptr;
};

}  // namespace invr
