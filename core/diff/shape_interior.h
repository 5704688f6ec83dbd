// The interior shape derivative (Wang et al. 2023's interior term for geometry): what a fixed
// camera sample sees when the mesh it hits moves, at fixed visibility. The camera ray is fixed,
// so the hit point slides along it, p' = d (ng . V(p)) / (ng . d) for the mesh's velocity field
// V; the shading normal turns with the mesh and, when it is interpolated, also changes because
// the hit slides across the surface (body-frame displacement p' - V(p), through the barycentric
// gradient of the vertex normals). The light point y stays fixed in its own measure (area lights:
// a point on the emitter; point and spot lights: their position; environments: a world
// direction), and every pdf, MIS and resampling weight is detached; with a diffuse f the
// contribution's derivative is then contribution * d log(|cos_p| G) with G the light-measure
// geometry: |cos_y| / r^2 (area), falloff / r^2 (point, spot), 1 (directions). Emission reached
// by a BSDF sample is differentiated in the same area measure (pdf_bsdf * |cos_y| / r^2 detached),
// so the two MIS halves stay a partition of one integral over y and the sum is unbiased.
//
// A moving camera (cameras/<view>/..., param_camera.cc) moves the ray instead: its point at fixed
// distance t, c = o + t d, moves with the camera's velocity field D_k (o' = D_k(o), d' its linear
// part applied to d, so c' = D_k(c)), and the hit slides along the fixed surface,
// p' = P c', P = I - d ng^T / (ng . d); the shading normal follows through the barycentric
// gradient. Every camera hit of a moving view takes this term, whatever it hits.
//
// Only diffuse, untextured materials on moving meshes (every mesh, when a camera moves) and direct
// illumination (max_depth 1) are supported; the job check refuses the rest (gradient_job_check.cc).
#pragma once

#include <cmath>

#include "core/diff/gradient_sink.h"
#include "core/diff/parameters.h"
#include "core/lights/light.h"
#include "core/scene/scene.h"

namespace invr {

// d log(|cos_p| G) with respect to the shading point p and its shading normal ns.
struct LogGeometryGradient {
  Vec3 dp{0.f}, dn{0.f};
};

// Towards a light point y (with normal nl when it is an area light's; spot lights pass `light`
// for the falloff). Zero when any factor vanishes (no contribution, no derivative).
inline LogGeometryGradient logGeometryGradient(Vec3 p, Vec3 ns, Vec3 y, const Vec3* nl, const Light* spot) {
  LogGeometryGradient g;
  const Vec3 r = y - p;
  const float dist = length(r);
  if (!(dist > 0.f)) return g;
  const Vec3 wi = r / dist;
  const float cp = dot(ns, wi);
  if (cp == 0.f) return g;
  // log|cos_p|: d cos_p / dp = -(ns - cos_p wi) / r, d cos_p / dns = wi.
  g.dn = wi / cp;
  g.dp = -(ns - wi * cp) / (dist * cp);
  // -2 log r: d r / dp = -wi.
  g.dp = g.dp + wi * (2.f / dist);
  if (nl) {  // log|cos_y|, cos_y = -nl . wi
    const float cl = -dot(*nl, wi);
    if (cl == 0.f) return LogGeometryGradient{};
    g.dp = g.dp + (*nl + wi * cl) / (dist * cl);
  }
  if (spot && spot->kind == LightKind::Spot) {  // log falloff(c), c = light.direction . (-wi)
    const float c = -dot(spot->direction, wi);
    if (c <= spot->cosOuter) return LogGeometryGradient{};
    if (c < spot->cosInner) {
      const float span = spot->cosInner - spot->cosOuter, t = (c - spot->cosOuter) / span;
      const float s = t * t * (3.f - 2.f * t), ds = 6.f * t * (1.f - t) / span;
      const Vec3 dc = (spot->direction - wi * dot(spot->direction, wi)) / dist;
      g.dp = g.dp + dc * (ds / s);
    }
  }
  return g;
}

// Towards a fixed world direction (environment light): log|cos_p| only.
inline LogGeometryGradient logDirectionGradient(Vec3 ns, Vec3 wi) {
  LogGeometryGradient g;
  const float cp = dot(ns, wi);
  if (cp != 0.f) g.dn = wi / cp;
  return g;
}

// The end of a direct-light path as the interior derivative sees it: its log-geometry gradient
// at p, for the light a sample reached (`wi` the world direction of that sample).
inline LogGeometryGradient lightEndGradient(const Scene& scene, const LightSampleRef& ref, Vec3 p, Vec3 ns, Vec3 wi) {
  const Light& l = scene.lights[ref.light];
  switch (l.kind) {
    case LightKind::Area: {
      const SurfaceHit y = scene.surfaceAt(l.mesh, ref.tri, ref.b1, ref.b2);
      return logGeometryGradient(p, ns, y.p, &y.ng, nullptr);
    }
    case LightKind::Point:
    case LightKind::Spot: return logGeometryGradient(p, ns, l.position, nullptr, &l);
    default: return logDirectionGradient(ns, wi);
  }
}

// Accumulates dLoss/dp and dLoss/dns at the camera hit of a moving mesh over a path's
// contributions, then maps them to the shape parameters through the camera-ray constraint.
class CameraHitShapeGradient {
 public:
  // `view`: the camera's view when it moves (its parameters take the camera term), else -1.
  void reset(const SurfaceHit& hit, Vec3 rayDir, int view = -1) {
    hit_ = hit;
    d_ = rayDir;
    view_ = view;
    dp_ = dn_ = Vec3(0.f);
    active_ = true;
  }
  bool active() const { return active_; }
  const SurfaceHit& hit() const { return hit_; }
  // `weight` = adjoint . contribution (a scalar: diffuse f has no spectral derivative here).
  void add(float weight, const LogGeometryGradient& g) {
    if (weight == 0.f || !std::isfinite(weight)) {
      if (!std::isfinite(weight)) dp_ = Vec3(weight);  // let the driver's non-finite check drop the sample
      return;
    }
    dp_ = dp_ + g.dp * weight;
    dn_ = dn_ + g.dn * weight;
  }
  // dLoss/dtheta_k = dp . p'_k + dn . ns'_k, with p'_k = d (ng . V_k) / (ng . d) and
  // ns'_k = (the normal turning with the mesh) + Jb (p'_k - V_k), Jb the shading normal's
  // gradient along the surface. Both are linear in V_k(p): folded into one point gradient. V_k is
  // a rigid motion's velocity field or, for vertex parameters, b_i at the hit for vertex i (the
  // triangle's points move linearly with its vertices), and the normal turns as the triangle does.
  void finish(const Scene& scene, const ParameterRegistry& params, PathGradient& grad) {
    if (!active_) return;
    active_ = false;
    if (dp_ == Vec3(0.f) && dn_ == Vec3(0.f)) return;
    const Vec3 ng = hit_.ng;
    const float nd = dot(ng, d_);
    if (std::abs(nd) < 1e-7f) return;  // grazing: measure zero
    const Vec3 m = surfaceNormalGradient(scene);
    // dp . p'_k + m . (p'_k - V_k) = (ng ((dp + m) . d) / (ng . d) - m) . V_k
    const Vec3 g = ng * (dot(dp_ + m, d_) / nd) - m;
    params.addHitGradient(scene, hit_, g, dn_, grad);
    // The camera: (dp + m) . P c'_k = (P^T (dp + m)) . D_k(c), with c = p (the hit is on the ray).
    if (view_ >= 0) {
      const Vec3 dpm = dp_ + m;
      params.addCameraPointGradient(scene, view_, hit_.p, dpm - ng * (dot(d_, dpm) / nd), grad);
    }
  }

 private:
  // m = Jb^T dn: how dLoss changes when the hit moves across the surface (interpolated normals).
  Vec3 surfaceNormalGradient(const Scene& scene) const {
    const TriangleMesh& mesh = scene.meshes[hit_.mesh];
    if (mesh.normals.empty()) return Vec3(0.f);
    const uint32_t i0 = mesh.indices[3 * hit_.tri], i1 = mesh.indices[3 * hit_.tri + 1], i2 = mesh.indices[3 * hit_.tri + 2];
    const float b0 = 1.f - hit_.b1 - hit_.b2;
    const Vec3 n = mesh.normals[i0] * b0 + mesh.normals[i1] * hit_.b1 + mesh.normals[i2] * hit_.b2;
    const float len = length(n);
    if (!(len > 0.f)) return Vec3(0.f);
    // ns = ±n / |n|: d ns = ±(I - ns ns^T) dn_raw / |n|.
    const float sign = dot(n, hit_.ns) < 0.f ? -1.f : 1.f;
    const Vec3 q = (dn_ - hit_.ns * dot(hit_.ns, dn_)) * (sign / len);
    // Barycentrics on the triangle's plane: b1 = g1 . (p - P0), b2 = g2 . (p - P0).
    const Vec3 p0 = mesh.positions[i0], e1 = mesh.positions[i1] - p0, e2 = mesh.positions[i2] - p0;
    const Vec3 N = cross(e1, e2);
    const float n2 = dot(N, N);
    if (!(n2 > 0.f)) return Vec3(0.f);
    const Vec3 g1 = cross(e2, N) / n2, g2 = cross(N, e1) / n2;
    return g1 * dot(mesh.normals[i1] - mesh.normals[i0], q) + g2 * dot(mesh.normals[i2] - mesh.normals[i0], q);
  }

  SurfaceHit hit_;
  Vec3 d_{0.f}, dp_{0.f}, dn_{0.f};
  int view_ = -1;
  bool active_ = false;
};

}  // namespace invr
