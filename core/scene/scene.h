// The renderer's scene: world-space meshes, materials, lights, views and the Embree BVH.
// Built from the protobuf description by scene_builder.cc; immutable while rendering.
#pragma once

#include <array>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "core/bsdf/bsdf.h"
#include "core/geometry/embree_scene.h"
#include "core/geometry/ray_queue.h"
#include "core/lights/light.h"
#include "core/scene/camera.h"
#include "core/geometry/mesh.h"
#include "core/scene/shape_motion.h"

namespace invr {

struct SurfaceHit {
  Vec3 p;
  Vec3 ng;  // unit geometric normal, from the triangle's winding
  Vec3 ns;  // unit shading normal (interpolated vertex normals, or ng)
  Vec2 uv;
  uint32_t mesh = 0, tri = 0;
  float b1 = 0, b2 = 0, t = 0;
};

// A camera ray's closest hit, traced before its walk (the pass driver traces a tile's camera rays
// together, core/geometry/ray_queue.h); `found` false: the ray left the scene.
struct PrimaryHit {
  SurfaceHit hit;
  bool found = false;
};

// Offsets a ray origin off the surface on the side of direction d (avoids self-intersection
// without a tnear that would miss close geometry).
inline Vec3 offsetOrigin(Vec3 p, Vec3 ng, Vec3 d) {
  float eps = 1e-4f * (1.f + maxComponent(vmax(p, -p)));
  return p + ng * (dot(ng, d) >= 0.f ? eps : -eps);
}

// How the renderer samples, when a job sets it (sampling parameters, Yan et al. 2024): none of it
// changes what a render converges to, only its noise. Empty members keep the default rules.
struct SamplingState {
  // One logit per light: next-event estimation picks light i with softmax(logits)_i. Empty: by power.
  std::vector<float> lightLogits;
  // Russian-roulette survival probability of bounce k = 1, 2, ... (the last value repeats for deeper
  // bounces). Empty: survival by path throughput after RenderOptions' russianRouletteDepth.
  std::vector<float> survival;
  // Per view: light-selection logits per cell of a width x height map over the film
  // (cell-major, lights fastest). A view without a map uses the global rule.
  struct PixelLogits {
    int width = 0, height = 0;
    std::vector<float> logits;
    bool empty() const { return logits.empty(); }
  };
  std::vector<PixelLogits> pixelLogits;
};

class Scene;

// A deformed mesh as one geometry version left it (shape_motion.h's PoseSnapshot): reused ReSTIR
// samples test their support against these vertices, through their own BVH.
struct DeformedGeometry {
  std::vector<Vec3> positions, faceNormals;
  std::vector<Vec3> normals;  // the vertex normals then (smooth meshes), else empty
  EmbreeScene bvh;
};
// Light sampling with the scene's emitter meshes (core/lights/light.h holds the per-light forms).
LightSample sampleLight(const Light& light, const Scene& scene, Vec3 p, Vec2 u2, uint32_t lightIndex = 0);
LightSample evalLightSample(const Scene& scene, const LightSampleRef& ref, Vec3 p);

class Scene {
 public:
  std::string name;
  std::vector<TriangleMesh> meshes;
  std::vector<std::string> meshNames;
  std::vector<int> meshMaterial;  // index into materials
  std::vector<int> meshLight;     // index into lights, -1 if not emissive
  std::vector<Material> materials;
  std::vector<Light> lights;
  std::vector<Camera> cameras;
  int width = 256, height = 256;
  SamplingState sampling;

  // Shapes that move together (ShapeGroup in the scene description) and the point each shape's
  // and group's rotation and scale act about; motion is the optimisable pose (shape_motion.h).
  struct Group {
    std::string name;
    std::vector<uint32_t> meshes;
    Vec3 pivot{0.f};
  };
  std::vector<Group> groups;
  std::vector<int> meshGroup;   // per mesh: index into groups, -1 if none
  std::vector<Vec3> meshPivot;  // per mesh
  ShapeMotion motion;

  Vec3 boundsMin{0.f}, boundsMax{0.f};
  float radius = 1.f;

  // Computes bounds, face normals, light areas and the light-selection distribution, and builds
  // the BVH (unless `accelerate` is false: a scene that is only validated or planned, never traced).
  void finalize(bool accelerate = true);
  // Whether the BVH was built: rays can be traced.
  bool accelerated() const { return accelerated_; }
  // Recomputes light power and the light-selection distribution (after emission changed).
  void updateLightSelection();
  // Moves a mesh's vertices (shape optimisation): refits the BVH and updates face normals.
  // Light areas are recomputed by calling finalize() when an emitter moves.
  void updateMeshPositions(uint32_t mesh, std::vector<Vec3> positions);

  // Moves the listed meshes (those with optimised motion) to the pose `motion` holds: vertices and
  // normals from their rest pose, face normals, BVH refit (the first call rebuilds the BVH with
  // refit-friendly flags), geometry version; and recomputes their velocity fields. Meshes whose
  // motion did not change since the last call keep their vertices.
  void applyShapeMotion(const std::vector<uint32_t>& optimisedMeshes);
  // Moves a mesh vertex by vertex (vertex parameters): positions, face normals, vertex normals
  // when the mesh has them (recomputed, computeSmoothNormals with `normalWeld`, as Mitsuba does
  // when a mesh with normals moves), BVH refit (the first call rebuilds it with refit-friendly
  // flags and marks the mesh moving and deforming; a smooth mesh's material then shades by its
  // geometric side, as under applyShapeMotion), geometry version. A call that changes no position
  // changes nothing.
  void deformMesh(uint32_t mesh, const std::vector<Vec3>& positions, const std::vector<uint32_t>* normalWeld = nullptr);
  // Replaces a mesh's geometry (a vertex parameter's start mesh, or its truth while targets are
  // rendered): face normals, BVH rebuilt, geometry version. Not for emitters or rigidly moving meshes.
  void replaceMesh(uint32_t mesh, TriangleMesh geometry);

  // Incremented whenever vertices move, so caches of surface positions know to re-place.
  uint64_t geometryVersion() const { return geometryVersion_; }

  // Optimisable camera poses (cameras/<view>/translation|rotation, core/diff/param_camera.cc): per
  // view a rigid motion of the camera as described (its rest pose) about its eye: the eye moves by
  // the translation, the look frame turns by the rotation (Euler degrees, x then y then z). Empty
  // until a camera parameter writes it.
  std::vector<RigidMotion> cameraMotion;
  // Places the cameras at rest -> cameraMotion (the rest poses are captured on the first call,
  // which also makes smooth meshes shade by their geometric side, as moving ones do) and
  // recomputes their velocity fields; counts a camera version when one moved.
  void applyCameraMotion();
  // dp/dtheta_k of a point p carried with view v's camera, k a RigidMotion component 0-5 (per
  // degree for rotations): the velocity field dA/dtheta_k A^-1 of its motion A.
  Vec3 cameraPointVelocity(int view, int k, Vec3 p) const;
  // Incremented whenever a camera moves (0: every camera as described).
  uint64_t cameraVersion() const { return cameraVersion_; }

  // Unit geometric normal of a triangle (from its winding), precomputed: cheaper than a cross
  // product and a square root on every hit.
  Vec3 faceNormal(uint32_t mesh, uint32_t tri) const { return meshes[mesh].faceNormals[tri]; }

  bool intersect(Vec3 o, Vec3 d, SurfaceHit& hit, float tmax = std::numeric_limits<float>::infinity()) const;
  // The surface point an Embree hit names (what intersect() gives for it).
  SurfaceHit surfaceOf(const RayHit& rh) const {
    SurfaceHit h = surfaceAt(rh.mesh, rh.tri, rh.b1, rh.b2);
    h.t = rh.t;
    return h;
  }
  // What queued camera ray i found, once the queue was traced against `accel`.
  PrimaryHit primaryHit(const CameraRayQueue& queue, int i) const {
    PrimaryHit p;
    p.found = queue.found(i);
    if (p.found) p.hit = surfaceOf(queue.hit(i));
    return p;
  }
  // The surface point with barycentrics (b1, b2) on a triangle, in the current geometry: how
  // reservoirs anchored to surfaces follow them when vertices move.
  SurfaceHit surfaceAt(uint32_t mesh, uint32_t tri, float b1, float b2) const;
  // Shadow rays. Both ends are pushed off their surfaces (the light point along its own normal)
  // so neither the receiver nor the emitter can occlude the segment between them.
  static Vec3 shadowOrigin(Vec3 p, Vec3 ng, Vec3 towards) { return offsetOrigin(p, ng, towards); }
  bool occludedSegment(Vec3 o, Vec3 target, Vec3& dir, float& tmax) const {
    Vec3 d = target - o;
    float len = length(d);
    if (!(len > 0.f)) return false;
    dir = d / len;
    tmax = len;
    return accel.occluded(o, dir, 0.f, tmax);
  }
  bool occludedDirection(Vec3 o, Vec3 d) const {
    return accel.occluded(o, d, 0.f, std::numeric_limits<float>::infinity());
  }

  // The geometry as it is now, for tests in that geometry after it moved on (pose(), then the
  // overloads below taking it). Meshes not in the snapshot (static ones) are as they are now.
  PoseSnapshot pose() const;
  SurfaceHit surfaceAt(const PoseSnapshot& pose, uint32_t mesh, uint32_t tri, float b1, float b2) const;
  // Whether the segment o -> target (or the ray o + t d) was blocked in `pose`: the static meshes
  // through the current BVH (moving ones skipped), each moving mesh through a BVH of its rest pose
  // with the ray taken back from `pose`.
  bool occludedSegment(const PoseSnapshot& pose, Vec3 o, Vec3 target) const;
  bool occludedDirection(const PoseSnapshot& pose, Vec3 o, Vec3 d) const;

  const Distribution1D& lightSelection() const { return lightSelect_; }
  // Whether selection is by power (no light logits), and each light's power under that rule.
  bool selectsByPower() const { return sampling.lightLogits.size() != lights.size(); }
  float selectionPower(size_t light) const { return power_[light]; }
  double selectionPowerTotal() const { return powerTotal_; }
  const std::vector<uint32_t>& infiniteLights() const { return infiniteLights_; }
  // An area light's emitter mesh; null for other lights.
  const TriangleMesh* emitterOf(const Light& l) const { return l.kind == LightKind::Area ? &meshes[l.mesh] : nullptr; }

  EmbreeScene accel;

  // Hands every ray traced through this scene's BVHs (the current one, the rest poses of moving
  // meshes, the deformed poses kept for support tests, and those built later) to `o`; null
  // detaches. Call only while no thread traces.
  void observeRays(RayObserver* o);
  RayObserver* rayObserver() const { return accel.observer(); }

 private:
  void computeFaceNormals(uint32_t mesh);

  Distribution1D lightSelect_;
  std::vector<float> power_;
  double powerTotal_ = 0;
  std::vector<uint32_t> infiniteLights_;
  std::vector<bool> dynamicMeshes_;
  std::vector<std::unique_ptr<EmbreeScene>> restAccel_;  // per moving mesh: its rest pose
  // Per deformed mesh: its geometry at the version pose() last recorded (shared by snapshots).
  mutable std::vector<std::shared_ptr<const DeformedGeometry>> deformedCache_;
  mutable std::mutex deformedMutex_;
  bool occludedByStatic(Vec3 o, Vec3 d, float tmax) const;
  uint64_t geometryVersion_ = 0;
  std::vector<Camera> cameraRest_;
  std::vector<RigidMotion> cameraApplied_;
  std::vector<std::array<Affine3d, 6>> cameraVelocity_;
  uint64_t cameraVersion_ = 0;
  bool accelerated_ = false;
};

inline LightSample sampleLight(const Light& light, const Scene& scene, Vec3 p, Vec2 u2, uint32_t lightIndex) {
  return sampleLight(light, scene.emitterOf(light), p, u2, lightIndex);
}
inline LightSample evalLightSample(const Scene& scene, const LightSampleRef& ref, Vec3 p) {
  const Light& light = scene.lights[ref.light];
  return evalLightSample(light, scene.emitterOf(light), ref, p);
}

}  // namespace invr
