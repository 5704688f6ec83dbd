// An optional log of every ray traced through any EmbreeScene, for `invr-lab bench step`, which
// replays a gradient step's rays through bare Embree to measure the step against its ray-tracing
// bound. Off unless a RayLog is active (alive and not stopped): tracing then pays one relaxed
// atomic load per ray.
#pragma once

#include <embree3/rtcore.h>

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/math/vec.h"

namespace invr {

struct LoggedRay {
  RTCScene scene;  // the BVH it was traced against (retained by the log while the log lives)
  Vec3 o, d;
  float tnear, tfar;
  bool shadow;    // an occlusion query (rtcOccluded1), else a closest hit (rtcIntersect1)
  bool hit;       // what the query found (blocked, or a surface hit)
  bool boundary;  // traced while a boundary term ran (RayLog::BoundaryPhase)
};

class RayLog {
 public:
  // Becomes the active log; at most one at a time (throws std::logic_error otherwise). Create,
  // stop and destroy logs only while no thread traces (between parallel loops).
  RayLog();
  ~RayLog();
  RayLog(const RayLog&) = delete;
  RayLog& operator=(const RayLog&) = delete;

  // Stops recording (no longer the active log) but keeps the BVHs it saw alive for a replay.
  void stop();
  // Every thread's rays, each thread's in the order it traced them; empties the log.
  std::vector<LoggedRay> take();

  static RayLog* active() { return active_.load(std::memory_order_relaxed); }
  void record(RTCScene scene, Vec3 o, Vec3 d, float tnear, float tfar, bool shadow, bool hit);

  // Marks the rays traced while it lives as the boundary terms' (the engine runs its phases one
  // after another, so a process-wide flag is enough; it matters only while a log is active).
  class BoundaryPhase {
   public:
    BoundaryPhase() { boundary_.store(true, std::memory_order_relaxed); }
    ~BoundaryPhase() { boundary_.store(false, std::memory_order_relaxed); }
    BoundaryPhase(const BoundaryPhase&) = delete;
    BoundaryPhase& operator=(const BoundaryPhase&) = delete;
  };

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  static std::atomic<RayLog*> active_;
  static std::atomic<bool> boundary_;
};

}  // namespace invr
