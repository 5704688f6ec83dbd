// Optimisable rigid motion of shapes (Wang et al. 2023 optimise poses and shapes): each shape, and
// each group of shapes, has a translation, an Euler rotation in degrees (x, then y, then z) and a
// uniform scale, both about a pivot:
//     p  ->  pivot + scale * R(rotation) * (p - pivot) + translation.
// A shape in a group moves by its own motion first, then by the group's. Vertices are recomputed
// from the positions the shape had when it first moved (its rest pose), so motion never drifts.
//
// Derivatives are velocity fields: for motion component k, the affine map D_k with
// dp/dtheta_k = D_k(p) for any point p on the moving surface (exact: the motion is affine in the
// rest point, and D_k = dA/dtheta_k * A^-1). Computed in double from the parameters themselves.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/math/affine.h"

namespace invr {

struct RigidMotion {
  static constexpr int kComponents = 7;  // translation x, y, z; rotation x, y, z (degrees); scale
  Vec3 translation{0.f};
  Vec3 rotationDegrees{0.f};
  float scale = 1.f;
  bool operator==(const RigidMotion& o) const {
    return translation.x == o.translation.x && translation.y == o.translation.y && translation.z == o.translation.z &&
           rotationDegrees.x == o.rotationDegrees.x && rotationDegrees.y == o.rotationDegrees.y &&
           rotationDegrees.z == o.rotationDegrees.z && scale == o.scale;
  }
  bool operator!=(const RigidMotion& o) const { return !(*this == o); }
};

// A deformed mesh (vertex parameters) as it was at one geometry version: its vertices and a BVH
// over them (defined in scene.h).
struct DeformedGeometry;

// The poses of the moving meshes at one geometry version: per moving mesh, the map from its rest
// pose to that pose and back. Reused ReSTIR samples test their support in the geometry they were
// created in (Wang et al. 2023, §3.2); motions are affine, so a few maps recall a whole geometry.
// A deformed mesh has no such map: its entry holds that version's vertices and their BVH, shared
// by every snapshot of the same version.
struct PoseSnapshot {
  uint64_t version = 0;  // Scene::geometryVersion() when taken
  struct Entry {
    uint32_t mesh;
    Affine3d toPose, fromPose;                         // rigid motion
    std::shared_ptr<const DeformedGeometry> deformed;  // vertex parameters (maps unused)
  };
  std::vector<Entry> meshes;  // sorted by mesh
  const Entry* find(uint32_t mesh) const {
    for (const Entry& e : meshes)
      if (e.mesh == mesh) return &e;
    return nullptr;
  }
};

// The motion as a map, and its derivative with respect to component k (per degree for rotations).
Affine3d motionMap(const RigidMotion& motion, Vec3 pivot);
Affine3d motionDerivative(const RigidMotion& motion, Vec3 pivot, int component);

// The motion state of a scene's meshes and groups. Owned by Scene; written by the parameter
// registry (core/diff/parameters.h), read by the shape-derivative estimators.
class ShapeMotion {
 public:
  // Velocity fields per mesh: 7 for the shape's own motion, then 7 for its group's (if any).
  static constexpr int kFields = 2 * RigidMotion::kComponents;

  void resize(size_t meshes, size_t groups);
  RigidMotion& mesh(uint32_t m) { return meshMotion_[m]; }
  RigidMotion& group(uint32_t g) { return groupMotion_[g]; }
  const RigidMotion& mesh(uint32_t m) const { return meshMotion_[m]; }
  const RigidMotion& group(uint32_t g) const { return groupMotion_[g]; }

  // dp/dtheta of motion component `field` (0-6: the mesh's own, 7-13: its group's) at a point p of
  // mesh m in its current pose. Valid after Scene::applyShapeMotion().
  Vec3 pointVelocity(uint32_t m, int field, Vec3 p) const { return velocity_[m][size_t(field)].point(p); }
  // d n / d theta of the same component for a unit normal n of mesh m (the normal of the moved
  // surface: n' ∝ A^-T n, so dn = -(I - n n^T) D^T n).
  Vec3 normalVelocity(uint32_t m, int field, Vec3 n) const {
    Vec3 g = velocity_[m][size_t(field)].transposedVector(n);
    return -(g - n * dot(n, g));
  }
  bool moving(uint32_t m) const { return m < moving_.size() && moving_[m]; }
  // Moved vertex by vertex (vertex parameters, Scene::deformMesh) rather than rigidly.
  bool deforming(uint32_t m) const { return m < deforming_.size() && deforming_[m]; }
  bool anyMoving() const { return !movingList_.empty(); }

 private:
  friend class Scene;
  std::vector<RigidMotion> meshMotion_, groupMotion_;
  std::vector<RigidMotion> appliedMesh_, appliedGroup_;  // what the vertices reflect
  std::vector<std::array<Affine3d, kFields>> velocity_;
  std::vector<std::vector<Vec3>> restPositions_, restNormals_;  // captured when a mesh first moves
  std::vector<uint8_t> moving_, deforming_;
  std::vector<uint32_t> movingList_;  // the moving meshes (rigid and deformed), ascending
  std::vector<Affine3d> appliedMap_;  // per mesh: rest pose -> the pose its vertices hold
};

}  // namespace invr
