// Embree 3 acceleration structure: one triangle geometry per mesh (geomID = mesh index).
// Meshes marked dynamic are built for refitting so shape optimisation can move their vertices.
#pragma once

#include <embree3/rtcore.h>

#include <vector>

#include "core/geometry/mesh.h"
#include "core/geometry/ray_observer.h"

namespace invr {

struct RayHit {
  float t;
  uint32_t mesh, tri;
  float b1, b2;  // barycentrics of vertices 1 and 2
};

class EmbreeScene {
 public:
  EmbreeScene();
  ~EmbreeScene();
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  void build(const std::vector<TriangleMesh>& meshes, const std::vector<bool>& dynamic = {});
  // Copies new vertex positions into mesh `mesh` and refits/rebuilds the BVH.
  void updatePositions(uint32_t mesh, const std::vector<Vec3>& positions);

  bool intersect(Vec3 o, Vec3 d, float tmin, float tmax, RayHit& hit) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh;
    rh.ray.org_x = o.x; rh.ray.org_y = o.y; rh.ray.org_z = o.z;
    rh.ray.dir_x = d.x; rh.ray.dir_y = d.y; rh.ray.dir_z = d.z;
    rh.ray.tnear = tmin; rh.ray.tfar = tmax;
    rh.ray.mask = 0xffffffffu; rh.ray.flags = 0; rh.ray.time = 0.f; rh.ray.id = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene_, &ctx, &rh);
    if (observer_) observer_->record(scene_, o, d, tmin, tmax, false, rh.hit.geomID != RTC_INVALID_GEOMETRY_ID);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
    hit = {rh.ray.tfar, rh.hit.geomID, rh.hit.primID, rh.hit.u, rh.hit.v};
    return true;
  }
  bool occluded(Vec3 o, Vec3 d, float tmin, float tmax) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRay r;
    r.org_x = o.x; r.org_y = o.y; r.org_z = o.z;
    r.dir_x = d.x; r.dir_y = d.y; r.dir_z = d.z;
    r.tnear = tmin; r.tfar = tmax;
    r.mask = 0xffffffffu; r.flags = 0; r.time = 0.f; r.id = 0;
    rtcOccluded1(scene_, &ctx, &r);
    const bool blocked = r.tfar < 0.f;  // Embree sets tfar = -inf on a hit
    if (observer_) observer_->record(scene_, o, d, tmin, tmax, true, blocked);
    return blocked;
  }
  // Up to 8 occlusion queries as one packet (rtcOccluded8), for coherent rays such as a shading
  // point's light candidates (one origin). blocked[i] answers ray i as occluded() does, except,
  // rarely, for a ray grazing an edge, which Embree's packet and single-ray kernels may round
  // differently (on cornell: 3 of a 256 spp target's 65,536 pixels moved, by 2e-4 relative).
  static constexpr int kPacket = 8;
  // Up to 8 closest-hit queries over [0, inf) as one coherent packet (rtcIntersect8), for rays
  // that leave one region in nearby directions (a tile's camera rays). found[i] and hits[i] answer
  // ray i as intersect() does, except, rarely, for a ray grazing an edge (as occludedPacket).
  void intersectPacket(int n, const Vec3* o, const Vec3* d, RayHit* hits, bool* found) const;
  void occludedPacket(int n, const Vec3* o, const Vec3* d, const float* tmax, bool* blocked) const;
  // Whether a shading point's shadow rays are faster as packets than one by one in this scene.
  // Measured with invr-lab bench step (ReSTIR, docs/performance.md): packets saved 12-15 % of a
  // step on scenes of 36 and 44 triangles and cost 0-7 % on 2124 and 7400 (rays through
  // foliage or a window frame diverge and stop at different depths). The limit lies between.
  static constexpr size_t kShadowPacketTriangles = 512;
  bool shadowPacketsPay() const { return shadowPacketsPay_; }
  RTCScene handle() const { return scene_; }
  // Hands every later query to `o` (null: to nobody). Set only while no thread traces. Const:
  // watching the rays is not part of the geometry (shared, const BVHs of poses are observed too).
  void observe(RayObserver* o) const { observer_ = o; }
  RayObserver* observer() const { return observer_; }

 private:
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
  mutable RayObserver* observer_ = nullptr;
  std::vector<RTCGeometry> geoms_;
  bool shadowPacketsPay_ = false;
};

}  // namespace invr
