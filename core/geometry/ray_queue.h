// Rays gathered, then traced together in Embree's fastest mode for their kind (issue 60's ray
// queue). Camera rays leave one eye through neighbouring pixels: coherent 8-wide packets are
// their fastest mode on this machine (`invr-lab bench step` reports each kind's best mode, and
// names packet8 for camera rays). The pass driver fills a queue with a tile's camera rays in
// the order their samples are taken, traces it, and hands each sample its first hit.
#pragma once

#include "core/geometry/embree_scene.h"

namespace invr {

class CameraRayQueue {
 public:
  static constexpr int kCapacity = 64;  // 8 packets: a few rows of a tile at 1 spp

  void clear() { size_ = 0; }
  int size() const { return size_; }
  bool full() const { return size_ == kCapacity; }
  // Queues a ray from o along d over [0, inf); returns its index. The queue must not be full.
  int push(Vec3 o, Vec3 d) {
    o_[size_] = o;
    d_[size_] = d;
    return size_++;
  }
  // Closest hits of every queued ray, in packets of 8 consecutive rays.
  void trace(const EmbreeScene& accel) {
    for (int first = 0; first < size_; first += EmbreeScene::kPacket) {
      const int n = size_ - first < EmbreeScene::kPacket ? size_ - first : EmbreeScene::kPacket;
      accel.intersectPacket(n, o_ + first, d_ + first, hits_ + first, found_ + first);
    }
  }
  bool found(int i) const { return found_[i]; }
  const RayHit& hit(int i) const { return hits_[i]; }
  Vec3 origin(int i) const { return o_[i]; }
  Vec3 direction(int i) const { return d_[i]; }

 private:
  int size_ = 0;
  Vec3 o_[kCapacity], d_[kCapacity];
  RayHit hits_[kCapacity];
  bool found_[kCapacity];
};

}  // namespace invr
