// What sees every query an EmbreeScene answers while it observes that scene
// (EmbreeScene::observe, Scene::observeRays): `invr-lab bench step`'s ray log. Attached to the
// scenes it watches rather than process-wide, so two engines in one process (the service's
// scenes, tests) never see each other's rays; tracing pays one pointer test per ray when nothing
// observes.
#pragma once

#include <embree3/rtcore.h>

#include <atomic>

#include "core/math/vec.h"

namespace invr {

class RayObserver {
 public:
  virtual ~RayObserver() = default;
  // Called on the tracing thread, once per ray (a packet's rays one by one, in lane order).
  virtual void record(RTCScene scene, Vec3 o, Vec3 d, float tnear, float tfar, bool shadow, bool hit) = 0;

  // Marks the rays traced while it lives as the boundary terms' (the engine runs its phases one
  // after another, so a flag per observer is enough). Does nothing without an observer.
  class BoundaryPhase {
   public:
    explicit BoundaryPhase(RayObserver* o) : o_(o) {
      if (o_) o_->boundary_.store(true, std::memory_order_relaxed);
    }
    ~BoundaryPhase() {
      if (o_) o_->boundary_.store(false, std::memory_order_relaxed);
    }
    BoundaryPhase(const BoundaryPhase&) = delete;
    BoundaryPhase& operator=(const BoundaryPhase&) = delete;

   private:
    RayObserver* o_;
  };

 protected:
  bool inBoundaryPhase() const { return boundary_.load(std::memory_order_relaxed); }

 private:
  std::atomic<bool> boundary_{false};
};

}  // namespace invr
