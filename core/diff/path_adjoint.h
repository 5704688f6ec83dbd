// The derivative visitor of the shared walk (core/render/path_walk.h): adjoint * dL/dtheta of one
// path for material and light parameters, where L is the path's radiance and `adjoint` is dLoss/dI
// of its pixel. At each vertex it backpropagates through
//   - the direct-light sample there:  d(f|cos|)(wo, wl) * weight * Le, and d Le,
//   - emission reached there:         d Le,
//   - the continuation:               d(f|cos|)(wo, wi) * (L - radiance gathered so far) / (f|cos|)(wo, wi),
// because everything gathered after a vertex carries that vertex's f|cos|/pdf once. The first two
// are known when the walk reaches them; continuation terms need the radiance gathered after the
// vertex, so the visitor keeps one small record per non-delta bounce (its BSDF derivatives, f and
// the radiance gathered so far) and replays those records in finish(), once L is known. This is
// path replay (Vicini et al. 2021) without the second walk: the record costs O(depth) memory per
// path, the random numbers are consumed once. Pdfs, MIS and roulette weights are detached.
// When the camera ray hits a mesh that shape parameters move, or the view's camera moves, the
// visitor also collects the interior derivative of the direct light there (shape_interior.h).
#pragma once

#include "core/error.h"
#include <new>

#include "core/diff/bsdf_adjoint.h"
#include "core/diff/shape_interior.h"
#include "core/render/path_walk.h"

namespace invr {

class PathAdjointVisitor {
 public:
  // `view`: the camera path's view (its camera parameters take the interior term), or -1.
  PathAdjointVisitor(const Scene& scene, const ParameterRegistry& params, Rgb adjoint, PathGradient& grad, Vec3 cameraDir = Vec3(0.f),
                     int view = -1)
      : scene_(scene),
        params_(params),
        adjoint_(adjoint),
        grad_(grad),
        cameraDir_(cameraDir),
        cameraView_(params.movesCamera(view) ? view : -1),
        shapes_(params.hasShapeParameters() || cameraView_ >= 0) {}

  void emission(Rgb weight, Rgb Le, const LightSampleRef& light, float perUnit) {
    L_ += weight * Le;
    if (perUnit > 0.f) lightGradient(light, weight * perUnit);
    // Emission a BSDF sample from a moving camera hit reached (the MIS half of PT).
    if (shape_.active()) {
      const SurfaceHit& h = shape_.hit();
      shape_.add(dot3(adjoint_, weight * Le), lightEndGradient(scene_, light, h.p, h.ns, light.direction()));
    }
  }
  void direct(Rgb beta, const DirectPath& p, const WalkVertex& v) {
    L_ += beta * p.contribution();
    if (shapes_ && v.depth == 0 && movesOnFilm(v.hit->mesh)) {
      beginShape(v);
      const Vec3 wi = v.frame->toWorld(p.wiLocal);
      shape_.add(dot3(adjoint_, beta * p.contribution()), lightEndGradient(scene_, p.light, v.hit->p, v.hit->ns, wi));
    }
    if (p.throughBsdf && hasBsdfParameters(params_, v.material))
      addBsdfGradient(params_, scene_, v.material, v.hit->uv, v.bsdf->evalDerivatives(v.wo, p.wiLocal),
                      adjoint_ * beta * p.weight * p.emission, grad_);
    if (p.emissionPerUnit > 0.f) lightGradient(p.light, beta * p.weight * p.bsdfValue * p.emissionPerUnit);
  }
  void bounce(const WalkVertex& v, Vec3 wi) {
    if (shapes_ && v.depth == 0 && movesOnFilm(v.hit->mesh)) beginShape(v);
    if (!hasBsdfParameters(params_, v.material)) return;
    INVR_INVARIANT(count_ < size_t(kMaxWalkDepth), "more bounces than max_depth allows");  // one per depth
    if (count_ < size_t(kMaxWalkDepth))
      new (&pending_[count_++ * sizeof(Pending)]) Pending{v.material, v.hit->uv, v.bsdf->evalDerivatives(v.wo, wi), v.bsdf->eval(v.wo, wi), L_};
  }
  // The path's radiance (complete once the walk returned).
  Rgb radiance() const { return L_; }
  // Adds the continuation terms; call once, after the walk.
  void finish() {
    for (size_t i = 0; i < count_; ++i) {
      const Pending& b = *std::launder(reinterpret_cast<const Pending*>(&pending_[i * sizeof(Pending)]));
      Rgb after = L_ - b.gathered;
      Rgb ratio(b.f.x > 0.f ? after.x / b.f.x : 0.f, b.f.y > 0.f ? after.y / b.f.y : 0.f, b.f.z > 0.f ? after.z / b.f.z : 0.f);
      addBsdfGradient(params_, scene_, b.material, b.uv, b.dd, adjoint_ * ratio, grad_);
    }
    count_ = 0;
    shape_.finish(scene_, params_, grad_);
  }

 private:
  struct Pending {  // trivially destructible: never destroyed
    int material;
    Vec2 uv;
    BsdfDerivatives dd;
    Rgb f, gathered;
  };
  static float dot3(Rgb a, Rgb b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
  bool movesOnFilm(uint32_t mesh) const { return cameraView_ >= 0 || params_.moves(mesh); }
  void beginShape(const WalkVertex& v) {
    if (!shape_.active()) shape_.reset(*v.hit, cameraDir_, cameraView_);
  }
  // d(contribution)/d(the light's value): its intensity, or the environment texel `ref` looks up.
  void lightGradient(const LightSampleRef& ref, Rgb perUnitContribution) {
    int off = params_.intensityOffset(int(ref.light));
    if (off < 0) {
      off = params_.texelsOffset(int(ref.light));
      if (off < 0) return;
      off += 3 * environmentTexel(scene_.lights[ref.light], ref.direction());
    }
    Rgb g = adjoint_ * perUnitContribution;
    for (int c = 0; c < 3; ++c) grad_.add(uint32_t(off + c), g[c]);
  }

  const Scene& scene_;
  const ParameterRegistry& params_;
  Rgb adjoint_;
  PathGradient& grad_;
  Vec3 cameraDir_;
  int cameraView_;
  bool shapes_;
  CameraHitShapeGradient shape_;
  Rgb L_{0.f};
  // One per non-delta bounce through a material with parameters: raw stack storage, constructed
  // on use (no allocation or clearing per path).
  alignas(Pending) unsigned char pending_[sizeof(Pending) * kMaxWalkDepth];
  size_t count_ = 0;
};

// One camera path: its radiance and, with `grad` set, adjoint * dL/dtheta added to it. The walk is
// the same with and without `grad` (equal samplers give equal radiance). `primary`: the camera
// ray's hit when traced beforehand (walkPath). `view`: the path's view (camera parameters), or -1.
template <class Direct>
Rgb walkCameraPath(const Scene& scene, const ParameterRegistry* params, Vec3 o, Vec3 d, Sampler& sampler, const WalkSettings& s,
                   Direct& direct, PathContext* ctx, Rgb adjoint = Rgb(0.f), PathGradient* grad = nullptr,
                   const PrimaryHit* primary = nullptr, int view = -1) {
  if (!grad) {
    RadianceVisitor v;
    walkPath(scene, o, d, sampler, s, direct, v, ctx, primary);
    return v.L;
  }
  PathAdjointVisitor v(scene, *params, adjoint, *grad, d, view);
  walkPath(scene, o, d, sampler, s, direct, v, ctx, primary);
  v.finish();
  return v.radiance();
}

}  // namespace invr
