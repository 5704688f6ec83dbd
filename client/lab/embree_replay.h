// Replays recorded rays through bare Embree in each of its modes (single rays, coherent packets of
// 4/8/16, rtcIntersect1M streams), for the benchmarks that measure the renderer against the time
// Embree alone needs for the same rays (`invr-lab bench rays`, `invr-lab bench step`).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/geometry/ray_log.h"

namespace invr::cli {

// Rays of one kind against one BVH, in the order they were traced.
struct RayGroup {
  std::string kind;  // camera, bounce, shadow, boundary
  RTCScene scene = nullptr;
  bool shadow = false;  // occlusion queries
  std::vector<LoggedRay> rays;
};

struct ReplayMode {
  const char* name;
  const char* what;
};
const std::vector<ReplayMode>& replayModes();  // [0] is single rays

// The fastest time so far of every group in every mode: best[group][mode], seconds.
struct ReplayTimes {
  std::vector<std::vector<double>> best;
  // Each group's fastest mode, and the sum of those times: the bound for the rays.
  size_t fastestMode(size_t group) const;
  double boundSeconds() const;
  double modeSeconds(size_t mode) const;  // all groups in one mode
};

// One timed pass over every group in every mode (in parallel over TBB, as the renderer runs),
// keeping the fastest time of each in `times`. Throws if single rays find another number of hits
// than the logged queries did (the BVH changed since), or another mode another number than
// single rays (beyond the 1e-4 of grazing rays that may go either way between traversal
// kernels): it would have measured something else.
void replayOnce(const std::vector<RayGroup>& groups, ReplayTimes& times);

// Splits a log into groups by kind and BVH, each in log order: boundary (traced while a boundary
// term ran), shadow (other occlusion queries), camera (closest hits from one of `eyes`) and bounce
// (the other closest hits). Kinds come in that fixed order; empty groups are left out.
std::vector<RayGroup> groupRays(const std::vector<LoggedRay>& rays, const std::vector<Vec3>& eyes);

// Bare single rays over a list that mixes kinds and BVHs, in its own order (bench rays' "embree").
double replayInOrder(const std::vector<LoggedRay>& rays, uint64_t& hits);

}  // namespace invr::cli
