// Baseline B.1 (and every path longer than direct illumination): one light sample chosen by power
// plus a BSDF sample, combined with the power heuristic at every vertex, Russian roulette after
// russianRouletteDepth bounces.
#include "core/diff/interior_estimator.h"
#include "core/diff/path_adjoint.h"

namespace invr {

namespace {

class PtEstimator final : public InteriorEstimator {
 public:
  explicit PtEstimator(const EstimatorSetup& s) : scene_(s.scene), params_(s.params), view_(s.view) {
    walk_.maxDepth = s.options.maxDepth;
    walk_.russianRouletteDepth = s.options.russianRouletteDepth;
    walk_.bsdfMis = true;
  }
  Rgb sample(const CameraSampleInput& in, Sampler& sampler, SampleCounters& counters, Rgb adjoint, PathGradient* grad,
             StoredReservoir*) const override {
    PathContext ctx{&counters.rays};
    thread_local std::vector<float> pmf;
    WalkSettings walk = walk_;
    walk.lightPmf = pixelLightPmf(scene_, view_, in.x, in.y, pmf);
    NeeMisDirect direct{scene_, walk.lightPmf};
    return walkCameraPath(scene_, &params_, in.o, in.d, sampler, walk, direct, &ctx, adjoint, grad, in.primary, view_);
  }
  Rgb varianceSample(const CameraSampleInput& in, Sampler& sampler, SampleCounters& counters, const VarianceWeights& weights,
                     PathGradient& grad) const override {
    PathContext ctx{&counters.rays};
    thread_local std::vector<float> pmf;
    VarianceWeights w = weights;
    w.view = view_;
    w.pixelPmf = pixelLightPmf(scene_, view_, in.x, in.y, pmf, &w.pixelCell);
    return walkVariancePath(scene_, params_, in.o, in.d, sampler, walk_, w, &ctx, grad, in.primary);
  }

 private:
  const Scene& scene_;
  const ParameterRegistry& params_;
  int view_;
  WalkSettings walk_;
};

}  // namespace

std::unique_ptr<InteriorEstimator> makePtEstimator(const EstimatorSetup& s) { return std::make_unique<PtEstimator>(s); }

}  // namespace invr
