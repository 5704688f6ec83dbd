#include "core/render/path_tracer.h"

#include "core/render/path_walk.h"

namespace invr {

Rgb pathRadiance(const Scene& scene, Vec3 o, Vec3 d, Sampler& sampler, const RenderOptions& opt, PathContext* ctx,
                 const PrimaryHit* primary) {
  WalkSettings ws;
  ws.maxDepth = opt.maxDepth;
  ws.russianRouletteDepth = opt.russianRouletteDepth;
  ws.bsdfMis = opt.estimator == LightEstimator::NeeMis;
  RadianceVisitor v;
  if (ws.bsdfMis) {
    NeeMisDirect direct{scene};
    walkPath(scene, o, d, sampler, ws, direct, v, ctx, primary);
  } else {
    RisDirect direct{scene, opt.risCandidates, opt.risVisibilityInTarget};
    walkPath(scene, o, d, sampler, ws, direct, v, ctx, primary);
  }
  return v.L;
}

}  // namespace invr
