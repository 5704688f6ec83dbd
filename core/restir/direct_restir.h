// Our estimator: streaming RIS plus reuse of the previous gradient step's reservoirs
// (Wang et al. 2023, Alg. 3-4), for direct illumination at one shading point.
#pragma once

#include "core/render/direct_light.h"
#include "core/restir/reservoir_store.h"

namespace invr {

struct RestirSettings {
  int candidates = 8;             // M of the fresh streaming RIS
  bool visibilityInTarget = true; // Eq. 14 (with V) or Eq. 17 (without)
  int neighbours = 1;             // reservoirs reused from the previous step
  float radius = 0.05f;           // search radius (world units; the engine sets it from radiusFraction)
  float normalDot = 0.9f;         // reject neighbours whose normal differs more
  float mCap = 16.f;              // confidence cap on each reused reservoir (2 x M by default)
  // Test a reused sample's support in the geometry it was created in (unbiased while geometry
  // moves, §3.2); false: in the current geometry (the paper's multi-view shortcut).
  bool supportInCreatedGeometry = true;
};

struct RestirCounters {
  uint64_t neighboursUsed = 0, shadingPoints = 0;
  double sumM = 0;
};

// Samples one path. `combined` receives the reservoir to store for the next step (W = 0 when the
// target at its sample is zero). `prev` may be null or empty (then this is plain RIS).
// `hints` say where to look for neighbours first (see ReservoirStore::neighbours).
bool sampleDirectRestir(const Scene& scene, const ShadingPoint& sp, Sampler& sampler, const RestirSettings& settings,
                        const ReservoirStore* prev, PathContext* ctx, DirectPath& out, Reservoir& combined,
                        RestirCounters* counters = nullptr, const NeighbourHints* hints = nullptr,
                        uint8_t* deltaKnown = nullptr, uint8_t* deltaVisible = nullptr);

}  // namespace invr
