#include "core/geometry/ray_log.h"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <mutex>

namespace invr {

struct RayLog::Impl {
  struct PerThread {
    std::vector<LoggedRay> rays;
    RTCScene lastScene = nullptr;  // retained already: skips the shared set for runs of one BVH
  };
  tbb::enumerable_thread_specific<PerThread> threads;
  std::mutex mutex;
  std::vector<RTCScene> retained;  // kept alive for the replay: BVHs of poses may go before it

  void retain(RTCScene scene) {
    std::lock_guard<std::mutex> lock(mutex);
    if (std::find(retained.begin(), retained.end(), scene) != retained.end()) return;
    rtcRetainScene(scene);
    retained.push_back(scene);
  }
};

RayLog::RayLog() : impl_(std::make_unique<Impl>()) {}

RayLog::~RayLog() {
  for (RTCScene s : impl_->retained) rtcReleaseScene(s);
}

void RayLog::record(RTCScene scene, Vec3 o, Vec3 d, float tnear, float tfar, bool shadow, bool hit) {
  Impl::PerThread& t = impl_->threads.local();
  if (scene != t.lastScene) {
    impl_->retain(scene);
    t.lastScene = scene;
  }
  t.rays.push_back({scene, o, d, tnear, tfar, shadow, hit, inBoundaryPhase()});
}

std::vector<LoggedRay> RayLog::take() {
  std::vector<LoggedRay> all;
  size_t n = 0;
  for (const Impl::PerThread& t : impl_->threads) n += t.rays.size();
  all.reserve(n);
  for (Impl::PerThread& t : impl_->threads) {
    all.insert(all.end(), t.rays.begin(), t.rays.end());
    std::vector<LoggedRay>().swap(t.rays);
  }
  return all;
}

}  // namespace invr
