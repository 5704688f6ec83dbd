#pragma once

#include <atomic>
#include <cstdint>
#include <vector>

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
  // Checked every 256 samples of a pixel: when it becomes true, renderView throws
  // EvaluationCancelled.
  const std::atomic<bool>* cancel = nullptr;
};

// Rays traced, by purpose (for throughput figures).
struct RayStats {
  uint64_t camera = 0, bounce = 0, shadow = 0;
  uint64_t total() const { return camera + bounce + shadow; }
  RayStats& operator+=(const RayStats& o) { camera += o.camera; bounce += o.bounce; shadow += o.shadow; return *this; }
};

// A ray as the renderer traced it (for `invr bench rays`, which replays them through bare Embree).
struct RayRecord {
  Vec3 o, d;
  float tmax;
  bool shadow;
};

// Per-path instrumentation; both members optional.
struct PathContext {
  RayStats* stats = nullptr;
  std::vector<RayRecord>* record = nullptr;
};

}  // namespace invr
