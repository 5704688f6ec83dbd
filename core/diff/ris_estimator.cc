// Baseline B.2: direct illumination by streaming RIS over M light candidates (Alg. 1); the
// target includes visibility (Eq. 14) unless the job asks for Eq. 17. Emission reached through a
// delta lobe is added by the walk; through rough lobes RIS alone accounts for it.
#include "core/diff/interior_estimator.h"
#include "core/diff/path_adjoint.h"

namespace invr {

namespace {

class RisEstimator final : public InteriorEstimator {
 public:
  explicit RisEstimator(const EstimatorSetup& s)
      : scene_(s.scene), params_(s.params), candidates_(s.options.restir.candidates), visibility_(s.options.restir.visibilityInTarget), view_(s.view) {
    walk_.maxDepth = 1;
    walk_.bsdfMis = false;
  }
  Rgb sample(const CameraSampleInput& in, Sampler& sampler, SampleCounters& counters, Rgb adjoint, PathGradient* grad,
             StoredReservoir*) const override {
    PathContext ctx{&counters.rays};
    RisDirect direct{scene_, candidates_, visibility_};
    return walkCameraPath(scene_, &params_, in.o, in.d, sampler, walk_, direct, &ctx, adjoint, grad, in.primary, view_);
  }

 private:
  const Scene& scene_;
  const ParameterRegistry& params_;
  int candidates_;
  bool visibility_;
  int view_;
  WalkSettings walk_;
};

}  // namespace

std::unique_ptr<InteriorEstimator> makeRisEstimator(const EstimatorSetup& s) { return std::make_unique<RisEstimator>(s); }

}  // namespace invr
