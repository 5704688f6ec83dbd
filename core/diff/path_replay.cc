#include "core/diff/path_replay.h"

#include "core/diff/bsdf_adjoint.h"
#include "core/render/direct_light.h"

namespace invr {

namespace {

// One surface vertex as the visitor sees it.
struct Vertex {
  const SurfaceHit* hit;
  const Bsdf* bsdf;
  int material;
  Vec3 wo;  // local
};

// The path tracer both passes share, so the replay consumes exactly the random numbers the
// first pass did. The visitor receives every contribution with the factors it needs.
template <class Visitor>
void tracePath(const Scene& scene, Vec3 o, Vec3 d, Sampler& sampler, const PathReplaySettings& s, RayStats* rays, Visitor& v) {
  Rgb beta(1.f);
  bool specular = true;
  float prevBsdfPdf = 0.f;
  Vec3 prevP = o;
  const auto& select = scene.lightSelection();
  PathContext ctx{rays, nullptr};
  for (int depth = 0;; ++depth) {
    if (rays) ++(depth == 0 ? rays->camera : rays->bounce);
    SurfaceHit hit;
    if (!scene.intersect(o, d, hit)) {
      for (uint32_t li : scene.infiniteLights()) {
        const Light& l = scene.lights[li];
        Rgb Le = environmentRadiance(l, d);
        if (isBlack(Le)) continue;
        float w = specular ? 1.f : powerHeuristic(prevBsdfPdf, select.pmf(li) * environmentPdf(l, d));
        v.emission(beta * w, Le, li, l.kind == LightKind::ConstantEnvironment ? l.scale : 0.f);
      }
      return;
    }
    if (int li = scene.meshLight[hit.mesh]; li >= 0) {
      const Light& l = scene.lights[size_t(li)];
      Rgb Le = areaEmission(l, hit.ng, -d);
      if (!isBlack(Le)) {
        float w = specular ? 1.f : powerHeuristic(prevBsdfPdf, select.pmf(size_t(li)) * areaLightPdf(l, prevP, hit.p, hit.ng));
        v.emission(beta * w, Le, uint32_t(li), l.scale);
      }
    }
    if (depth >= s.maxDepth) return;

    const int material = scene.meshMaterial[hit.mesh];
    Bsdf bsdf = scene.materials[size_t(material)].at(hit.uv);
    ShadingPoint sp{&hit, &bsdf, Frame(hit.ns), Vec3(), -d};
    sp.wo = sp.frame.toLocal(-d);
    Vertex vx{&hit, &bsdf, material, sp.wo};
    if (!bsdf.isDelta()) {
      DirectPath p;
      if (sampleDirectNee(scene, sp, sampler, &ctx, p)) v.nee(beta, p, vx);
    }
    float uc = sampler.next1D();
    Vec2 u(sampler.next1D(), sampler.next1D());
    auto bs = bsdf.sample(sp.wo, uc, u);
    if (!bs) return;
    Vec3 wi = sp.frame.toWorld(bs->wi);
    float side = dot(wi, hit.ng) * dot(-d, hit.ng);
    if (bs->transmitted ? side >= 0.f : side <= 0.f) return;
    if (!bs->delta) v.bounce(vx, bs->wi);
    beta *= bs->weight;
    specular = bs->delta;
    prevBsdfPdf = bs->pdf;
    prevP = hit.p;
    o = offsetOrigin(hit.p, hit.ng, wi);
    d = wi;
    if (depth + 1 >= s.russianRouletteDepth) {
      float q = std::min(1.f, maxComponent(beta));
      if (!(sampler.next1D() < q)) return;
      beta = beta / q;
    }
  }
}

struct RadianceVisitor {
  Rgb L{0.f};
  void emission(Rgb weight, Rgb Le, uint32_t, float) { L += weight * Le; }
  void nee(Rgb beta, const DirectPath& p, const Vertex&) { L += beta * p.contribution(); }
  void bounce(const Vertex&, Vec3) {}
};

struct BackpropVisitor {
  const Scene& scene;
  const ParameterRegistry& params;
  Rgb L, adjoint;
  PathGradient& grad;
  Rgb gathered{0.f};  // radiance of the path up to the current vertex

  void lightGradient(uint32_t light, Rgb perUnitContribution) {
    int off = params.intensityOffset(int(light));
    if (off < 0) return;
    Rgb g = adjoint * perUnitContribution;
    for (int c = 0; c < 3; ++c) grad.add(uint32_t(off + c), g[c]);
  }
  void emission(Rgb weight, Rgb Le, uint32_t light, float perUnit) {
    gathered += weight * Le;
    if (perUnit > 0.f) lightGradient(light, weight * perUnit);
  }
  void nee(Rgb beta, const DirectPath& p, const Vertex& v) {
    gathered += beta * p.contribution();
    if (hasBsdfParameters(params, v.material))
      addBsdfGradient(params, scene, v.material, v.hit->uv, v.bsdf->evalDerivatives(v.wo, p.wiLocal), adjoint * beta * p.weight * p.emission,
                      grad);
    if (p.emissionPerUnit > 0.f) lightGradient(p.light.light, beta * p.weight * p.bsdfValue * p.emissionPerUnit);
  }
  void bounce(const Vertex& v, Vec3 wi) {
    if (!hasBsdfParameters(params, v.material)) return;
    // Everything after this vertex went through its f|cos| once: d/dtheta = (L - gathered) df / f.
    Rgb f = v.bsdf->eval(v.wo, wi);
    Rgb after = L - gathered;
    Rgb ratio(f.x > 0.f ? after.x / f.x : 0.f, f.y > 0.f ? after.y / f.y : 0.f, f.z > 0.f ? after.z / f.z : 0.f);
    addBsdfGradient(params, scene, v.material, v.hit->uv, v.bsdf->evalDerivatives(v.wo, wi), adjoint * ratio, grad);
  }
};

}  // namespace

Rgb pathReplayRadiance(const Scene& scene, Vec3 o, Vec3 d, Sampler sampler, const PathReplaySettings& s, RayStats* rays) {
  RadianceVisitor v;
  tracePath(scene, o, d, sampler, s, rays, v);
  return v.L;
}

void pathReplayBackprop(const Scene& scene, const ParameterRegistry& params, Vec3 o, Vec3 d, Sampler sampler,
                        const PathReplaySettings& s, Rgb L, Rgb adjoint, PathGradient& grad, RayStats* rays) {
  BackpropVisitor v{scene, params, L, adjoint, grad};
  tracePath(scene, o, d, sampler, s, rays, v);
}

}  // namespace invr
