// A log of every ray traced through the scenes it observes, for `invr-lab bench step`, which
// replays a gradient step's rays through bare Embree to measure the step against its ray-tracing
// bound. Attach it with Scene::observeRays (or EmbreeScene::observe) and detach it before reading.
#pragma once

#include <embree3/rtcore.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "core/geometry/ray_observer.h"
#include "core/math/vec.h"

namespace invr {

struct LoggedRay {
  RTCScene scene;  // the BVH it was traced against (retained by the log while the log lives)
  Vec3 o, d;
  float tnear, tfar;
  bool shadow;    // an occlusion query (rtcOccluded1), else a closest hit (rtcIntersect1)
  bool hit;       // what the query found (blocked, or a surface hit)
  bool boundary;  // traced while a boundary term ran (RayObserver::BoundaryPhase)
};

class RayLog final : public RayObserver {
 public:
  RayLog();
  ~RayLog() override;
  RayLog(const RayLog&) = delete;
  RayLog& operator=(const RayLog&) = delete;

  // Every thread's rays, each thread's in the order it traced them; empties the log. Call while
  // no thread traces through an observed scene. The BVHs the rays name stay alive as long as the
  // log does (a pose's BVH may go before the replay).
  std::vector<LoggedRay> take();

  void record(RTCScene scene, Vec3 o, Vec3 d, float tnear, float tfar, bool shadow, bool hit) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace invr
