#include "core/scene/scene.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/error.h"
#include "core/lights/light_selection.h"

namespace invr {

void Scene::finalize(bool accelerate) {
  boundsMin = Vec3(std::numeric_limits<float>::infinity());
  boundsMax = -boundsMin;
  for (const auto& m : meshes)
    for (const auto& p : m.positions) { boundsMin = vmin(boundsMin, p); boundsMax = vmax(boundsMax, p); }
  if (meshes.empty()) { boundsMin = Vec3(-1.f); boundsMax = Vec3(1.f); }
  for (uint32_t m = 0; m < meshes.size(); ++m) computeFaceNormals(m);
  radius = std::max(0.5f * length(boundsMax - boundsMin), 1e-3f);

  for (Light& l : lights) {
    if (l.kind != LightKind::Area) continue;
    const TriangleMesh& m = meshes[l.mesh];
    std::vector<float> areas(m.triangleCount());
    double total = 0;
    for (size_t t = 0; t < areas.size(); ++t) total += (areas[t] = m.triangleArea(t));
    l.area = float(total);
    if (!(l.area > 0.f)) throw InputError("light '" + l.name + "': emitting shape has zero area");
    l.triangles = Distribution1D(areas);
  }
  updateLightSelection();
  if (meshGroup.size() != meshes.size()) meshGroup.assign(meshes.size(), -1);
  if (meshPivot.size() != meshes.size()) {
    meshPivot.resize(meshes.size());
    for (size_t m = 0; m < meshes.size(); ++m) {
      Vec3 lo(std::numeric_limits<float>::infinity()), hi = -lo;
      for (const auto& p : meshes[m].positions) { lo = vmin(lo, p); hi = vmax(hi, p); }
      meshPivot[m] = (lo + hi) * 0.5f;
    }
  }
  motion.resize(meshes.size(), groups.size());
  dynamicMeshes_.assign(meshes.size(), false);
  if (accelerate) accel.build(meshes);
  accelerated_ = accelerate;
}

void Scene::updateLightSelection() {
  infiniteLights_.clear();
  power_.assign(lights.size(), 0.f);
  powerTotal_ = 0;
  for (size_t i = 0; i < lights.size(); ++i) {
    if (lights[i].isInfinite()) infiniteLights_.push_back(uint32_t(i));
    powerTotal_ += (power_[i] = std::max(lightPower(lights[i], radius), 0.f));
  }
  lightSelect_ = selectsByPower() ? Distribution1D(power_) : Distribution1D(softmax(sampling.lightLogits));
}

void Scene::computeFaceNormals(uint32_t mesh) {
  const TriangleMesh& m = meshes[mesh];
  auto& out = meshes[mesh].faceNormals;
  out.resize(m.triangleCount());
  for (size_t t = 0; t < out.size(); ++t) {
    Vec3 a = m.positions[m.indices[3 * t]], b = m.positions[m.indices[3 * t + 1]], c = m.positions[m.indices[3 * t + 2]];
    Vec3 n = cross(b - a, c - a);
    float len = length(n);
    out[t] = len > 0.f ? n / len : Vec3(0, 0, 1);
  }
}

void Scene::updateMeshPositions(uint32_t mesh, std::vector<Vec3> positions) {
  if (positions.size() != meshes.at(mesh).positions.size())
    throw std::invalid_argument("updateMeshPositions: vertex count changed");
  meshes[mesh].positions = std::move(positions);
  computeFaceNormals(mesh);
  accel.updatePositions(mesh, meshes[mesh].positions);
  ++geometryVersion_;
}

void Scene::applyCameraMotion() {
  if (cameraRest_.size() != cameras.size()) {
    cameraRest_ = cameras;
    cameraApplied_.assign(cameras.size(), RigidMotion{});
    // As for a smooth mesh that moves (applyShapeMotion): where its shading normal turns away from
    // the eye the lobe would switch, along a curve that moves on the film with the camera.
    for (size_t m = 0; m < meshes.size(); ++m)
      if (!meshes[m].normals.empty()) materials[size_t(meshMaterial[m])].geometricSide = true;
  }
  cameraMotion.resize(cameras.size());
  cameraVelocity_.resize(cameras.size());
  bool moved = false;
  for (size_t v = 0; v < cameras.size(); ++v) {
    const Camera& rest = cameraRest_[v];
    const RigidMotion& mo = cameraMotion[v];
    const Affine3d map = motionMap(mo, rest.eye), inverse = map.inverse();
    for (int k = 0; k < 6; ++k) cameraVelocity_[v][size_t(k)] = motionDerivative(mo, rest.eye, k) * inverse;
    if (mo == cameraApplied_[v]) continue;
    cameraApplied_[v] = mo;
    Camera& c = cameras[v];
    c.eye = map.point(rest.eye);
    // A rotation keeps the frame orthonormal; normalising only drops the float rounding.
    c.forward = normalize(map.vector(rest.forward));
    c.right = normalize(map.vector(rest.right));
    c.up = normalize(map.vector(rest.up));
    moved = true;
  }
  if (moved) ++cameraVersion_;
}

Vec3 Scene::cameraPointVelocity(int view, int k, Vec3 p) const {
  if (size_t(view) < cameraVelocity_.size()) return cameraVelocity_[size_t(view)][size_t(k)].point(p);
  // Never applied: the camera is at rest, its motion the identity.
  return motionDerivative(RigidMotion{}, cameras[size_t(view)].eye, k).point(p);
}

void Scene::applyShapeMotion(const std::vector<uint32_t>& optimised) {
  bool rebuild = false;
  for (uint32_t m : optimised) {
    if (motion.moving_[m]) continue;
    motion.moving_[m] = 1;
    motion.restPositions_[m] = meshes[m].positions;
    motion.restNormals_[m] = meshes[m].normals;
    // A smooth-shaded mesh that moves shades by its geometric side (Bsdf::geometricSide): the
    // shading normal's horizon would otherwise be a moving discontinuity inside its faces.
    if (!meshes[m].normals.empty()) materials[size_t(meshMaterial[m])].geometricSide = true;
    motion.movingList_.insert(std::lower_bound(motion.movingList_.begin(), motion.movingList_.end(), m), m);
    dynamicMeshes_[m] = true;
    if (accelerated_) {
      if (restAccel_.size() != meshes.size()) restAccel_.resize(meshes.size());
      restAccel_[m] = std::make_unique<EmbreeScene>();
      restAccel_[m]->build({meshes[m]}, {true});  // robust traversal, as for the moving copy
      restAccel_[m]->observe(accel.observer());
    }
    rebuild = true;
  }
  // Refit-quality geometry for the moving meshes, once; later moves only refit.
  if (rebuild && accelerated_) accel.build(meshes, dynamicMeshes_);
  bool moved = false;
  for (uint32_t m : optimised) {
    const int g = meshGroup[m];
    const RigidMotion& own = motion.meshMotion_[m];
    const RigidMotion group = g >= 0 ? motion.groupMotion_[size_t(g)] : RigidMotion{};
    const Affine3d shapeMap = motionMap(own, meshPivot[m]);
    const Affine3d groupMap = g >= 0 ? motionMap(group, groups[size_t(g)].pivot) : Affine3d{};
    const Affine3d map = groupMap * shapeMap, inverse = map.inverse();
    motion.appliedMap_[m] = map;
    // Velocity fields D = dA/dtheta * A^-1 (shape_motion.h): the group's linear part carries the
    // shape's own derivative; the group's derivative acts on the shape's moved points.
    auto& v = motion.velocity_[m];
    for (int k = 0; k < RigidMotion::kComponents; ++k) {
      v[size_t(k)] = groupMap.linearPart() * motionDerivative(own, meshPivot[m], k) * inverse;
      v[size_t(k + RigidMotion::kComponents)] =
          g >= 0 ? motionDerivative(group, groups[size_t(g)].pivot, k) * groupMap.inverse() : Affine3d::zero();
    }
    const bool changed = own != motion.appliedMesh_[m] || (g >= 0 && group != motion.appliedGroup_[size_t(g)]);
    if (!changed && !rebuild) continue;
    TriangleMesh& mesh = meshes[m];
    const auto& rest = motion.restPositions_[m];
    std::vector<Vec3> positions(rest.size());
    for (size_t i = 0; i < rest.size(); ++i) positions[i] = map.point(rest[i]);
    const auto& restN = motion.restNormals_[m];
    for (size_t i = 0; i < restN.size(); ++i) mesh.normals[i] = normalize(inverse.transposedVector(restN[i]));
    mesh.positions = std::move(positions);
    computeFaceNormals(m);
    if (accelerated_) accel.updatePositions(m, mesh.positions);
    moved = true;
  }
  for (uint32_t m : optimised) {
    motion.appliedMesh_[m] = motion.meshMotion_[m];
    if (meshGroup[m] >= 0) motion.appliedGroup_[size_t(meshGroup[m])] = motion.groupMotion_[size_t(meshGroup[m])];
  }
  if (moved) ++geometryVersion_;
}

void Scene::deformMesh(uint32_t m, const std::vector<Vec3>& positions, const std::vector<uint32_t>* normalWeld) {
  TriangleMesh& mesh = meshes.at(m);
  if (positions.size() != mesh.positions.size())
    throw std::invalid_argument("deformMesh: " + std::to_string(positions.size()) + " positions for a mesh of " +
                                std::to_string(mesh.positions.size()) + " vertices");
  if (!motion.deforming_[m]) {
    if (motion.moving_[m]) throw std::logic_error("deformMesh: mesh " + meshNames[m] + " already moves rigidly");
    motion.moving_[m] = motion.deforming_[m] = 1;
    if (!mesh.normals.empty()) materials[size_t(meshMaterial[m])].geometricSide = true;  // as applyShapeMotion
    motion.movingList_.insert(std::lower_bound(motion.movingList_.begin(), motion.movingList_.end(), m), m);
    dynamicMeshes_[m] = true;
    if (accelerated_) accel.build(meshes, dynamicMeshes_);  // refit-friendly from now on
  } else if (positions == mesh.positions) {
    return;
  }
  mesh.positions = positions;
  // A smooth mesh's vertex normals follow its positions, as in Mitsuba when a mesh that has normals
  // moves (ParameterRegistry::foldNormalAdjoints differentiates through them).
  if (!mesh.normals.empty()) computeSmoothNormals(mesh, normalWeld);
  computeFaceNormals(m);
  if (accelerated_) accel.updatePositions(m, mesh.positions);
  ++geometryVersion_;
}

void Scene::replaceMesh(uint32_t m, TriangleMesh geometry) {
  if (meshLight.at(m) >= 0) throw std::logic_error("replaceMesh: mesh " + meshNames[m] + " emits light");
  if (motion.moving(m) && !motion.deforming(m)) throw std::logic_error("replaceMesh: mesh " + meshNames[m] + " moves rigidly");
  meshes[m] = std::move(geometry);
  computeFaceNormals(m);
  if (accelerated_) accel.build(meshes, dynamicMeshes_);
  ++geometryVersion_;
}

bool Scene::intersect(Vec3 o, Vec3 d, SurfaceHit& hit, float tmax) const {
  RayHit rh;
  if (!accel.intersect(o, d, 0.f, tmax, rh)) return false;
  hit = surfaceOf(rh);
  return true;
}

void Scene::observeRays(RayObserver* o) {
  accel.observe(o);
  for (const auto& rest : restAccel_)
    if (rest) rest->observe(o);
  std::lock_guard<std::mutex> lock(deformedMutex_);
  for (const auto& g : deformedCache_)
    if (g) g->bvh.observe(o);
}

PoseSnapshot Scene::pose() const {
  PoseSnapshot s;
  s.version = geometryVersion_;
  for (uint32_t m : motion.movingList_) {
    if (!motion.deforming_[m]) {
      s.meshes.push_back({m, motion.appliedMap_[m], motion.appliedMap_[m].inverse(), nullptr});
      continue;
    }
    // Deformed meshes: their vertices now, and a BVH over them, once per geometry version.
    std::lock_guard<std::mutex> lock(deformedMutex_);
    if (deformedCache_.size() != meshes.size()) deformedCache_.resize(meshes.size());
    auto& cached = deformedCache_[m];
    if (!cached || cached->positions != meshes[m].positions) {
      auto g = std::make_shared<DeformedGeometry>();
      g->positions = meshes[m].positions;
      g->faceNormals = meshes[m].faceNormals;
      g->normals = meshes[m].normals;
      if (accelerated_) {
        TriangleMesh copy = meshes[m];
        g->bvh.build({copy}, {true});  // robust traversal, as for the moving copy
        g->bvh.observe(accel.observer());
      }
      cached = std::move(g);
    }
    s.meshes.push_back({m, {}, {}, cached});
  }
  return s;
}

SurfaceHit Scene::surfaceAt(const PoseSnapshot& pose, uint32_t mesh, uint32_t tri, float b1, float b2) const {
  const PoseSnapshot::Entry* e = pose.version == geometryVersion_ ? nullptr : pose.find(mesh);
  if (!e) return surfaceAt(mesh, tri, b1, b2);
  // The vertices as applyShapeMotion placed them in that pose (the same float operations), then
  // the surface point as surfaceAt computes it.
  const TriangleMesh& m = meshes[mesh];
  uint32_t i0 = m.indices[3 * tri], i1 = m.indices[3 * tri + 1], i2 = m.indices[3 * tri + 2];
  if (e->deformed) {
    const DeformedGeometry& g = *e->deformed;
    SurfaceHit hit = surfaceAt(mesh, tri, b1, b2);
    const float b0 = 1.f - b1 - b2;
    hit.p = g.positions[i0] * b0 + g.positions[i1] * b1 + g.positions[i2] * b2;
    hit.ng = hit.ns = g.faceNormals[tri];
    if (!g.normals.empty()) {  // as surfaceAt interpolates them
      const Vec3 n = g.normals[i0] * b0 + g.normals[i1] * b1 + g.normals[i2] * b2;
      const float len = length(n);
      if (len > 0.f) hit.ns = dot(n, hit.ng) < 0.f ? -n / len : n / len;
    }
    return hit;
  }
  const auto& rest = motion.restPositions_[mesh];
  const auto& restN = motion.restNormals_[mesh];
  const Vec3 a = e->toPose.point(rest[i0]), b = e->toPose.point(rest[i1]), c = e->toPose.point(rest[i2]);
  SurfaceHit hit = surfaceAt(mesh, tri, b1, b2);  // uv and indices; positions and normals below
  const float b0 = 1.f - b1 - b2;
  hit.p = a * b0 + b * b1 + c * b2;
  Vec3 n = cross(b - a, c - a);
  float len = length(n);
  hit.ng = len > 0.f ? n / len : Vec3(0, 0, 1);
  if (!restN.empty()) {
    auto turned = [&](uint32_t i) { return normalize(e->fromPose.transposedVector(restN[i])); };
    Vec3 ns = turned(i0) * b0 + turned(i1) * b1 + turned(i2) * b2;
    float l = length(ns);
    hit.ns = l > 0.f ? ns / l : hit.ng;
    if (dot(hit.ns, hit.ng) < 0.f) hit.ns = -hit.ns;
  } else {
    hit.ns = hit.ng;
  }
  return hit;
}

bool Scene::occludedByStatic(Vec3 o, Vec3 d, float tmax) const {
  // Walks the hits along the ray in order, stepping past those on moving meshes. The same
  // triangle reports the same t for the same ray, so starting just past it cannot find it again.
  float tnear = 0.f;
  for (int guard = 0; guard < 1024; ++guard) {
    RayHit h;
    if (!accel.intersect(o, d, tnear, tmax, h)) return false;
    if (!motion.moving(h.mesh)) return true;
    tnear = std::nextafter(h.t, std::numeric_limits<float>::infinity());
  }
  return true;  // a pathological stack of moving surfaces: call it blocked
}

bool Scene::occludedSegment(const PoseSnapshot& pose, Vec3 o, Vec3 target) const {
  if (pose.version == geometryVersion_) {
    Vec3 dir;
    float tmax;
    return occludedSegment(o, target, dir, tmax);
  }
  const Vec3 d = target - o;
  const float len = length(d);
  if (!(len > 0.f)) return false;
  if (occludedByStatic(o, d / len, len)) return true;
  // In each moving mesh's rest frame the segment is still o + t d, t in [0, 1] (maps are affine).
  for (const PoseSnapshot::Entry& e : pose.meshes) {
    if (e.deformed ? e.deformed->bvh.occluded(o, d, 0.f, 1.f) : restAccel_[e.mesh]->occluded(e.fromPose.point(o), e.fromPose.vector(d), 0.f, 1.f))
      return true;
  }
  return false;
}

bool Scene::occludedDirection(const PoseSnapshot& pose, Vec3 o, Vec3 d) const {
  if (pose.version == geometryVersion_) return occludedDirection(o, d);
  const float inf = std::numeric_limits<float>::infinity();
  if (occludedByStatic(o, d, inf)) return true;
  for (const PoseSnapshot::Entry& e : pose.meshes) {
    if (e.deformed ? e.deformed->bvh.occluded(o, d, 0.f, inf) : restAccel_[e.mesh]->occluded(e.fromPose.point(o), e.fromPose.vector(d), 0.f, inf))
      return true;
  }
  return false;
}

SurfaceHit Scene::surfaceAt(uint32_t mesh, uint32_t tri, float b1, float b2) const {
  SurfaceHit hit;
  const TriangleMesh& m = meshes[mesh];
  uint32_t i0 = m.indices[3 * tri], i1 = m.indices[3 * tri + 1], i2 = m.indices[3 * tri + 2];
  float b0 = 1.f - b1 - b2;
  hit.p = m.positions[i0] * b0 + m.positions[i1] * b1 + m.positions[i2] * b2;
  hit.ng = meshes[mesh].faceNormals[tri];
  if (!m.normals.empty()) {
    Vec3 n = m.normals[i0] * b0 + m.normals[i1] * b1 + m.normals[i2] * b2;
    float len = length(n);
    hit.ns = len > 0.f ? n / len : hit.ng;
    // Keep the shading normal on the geometric normal's side so the local frame is consistent.
    if (dot(hit.ns, hit.ng) < 0.f) hit.ns = -hit.ns;
  } else {
    hit.ns = hit.ng;
  }
  hit.uv = m.uvs.empty() ? Vec2(b1, b2) : m.uvs[i0] * b0 + m.uvs[i1] * b1 + m.uvs[i2] * b2;
  hit.mesh = mesh;
  hit.tri = tri;
  hit.b1 = b1;
  hit.b2 = b2;
  return hit;
}

}  // namespace invr
