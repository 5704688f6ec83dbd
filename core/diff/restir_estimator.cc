// Our interior estimator: streaming RIS plus reuse of the previous gradient step's reservoirs
// (Wang et al. 2023, Alg. 3-4; the combination itself is core/restir/direct_restir.cc). Direct
// illumination: the walk stops after the first vertex, whose direct light comes from the combined
// reservoir; the reservoir is what this sample leaves for the next step.
#include <cmath>
#include <utility>
#include <vector>

#include "core/diff/interior_estimator.h"
#include "core/diff/path_adjoint.h"

namespace invr {

namespace {

class RestirEstimator final : public InteriorEstimator {
 public:
  explicit RestirEstimator(const EstimatorSetup& s)
      : scene_(s.scene), params_(s.params), settings_(s.options.restir), previous_(s.previous), view_(s.view), spp_(s.spp) {
    walk_.maxDepth = 1;
    walk_.bsdfMis = false;
    settings_.supportInCreatedGeometry = !s.options.boundary.multiViewShortcut;
    const Camera& cam = scene_.cameras[size_t(view_)];
    const int W = scene_.width, H = scene_.height;
    pixelFootprint_ = s.options.radiusPixels * 2.f * cam.tanHalfFovY / float(H);  // world radius per unit distance
    // Where to look for a neighbour (one, by default) when last step rendered this view:
    //  1. the reservoir a random pixel within the reuse radius left behind (offsets uniform over the
    //     disk one pixel short of the radius, so that sub-pixel jitter rarely fails the world-space
    //     test). Random rather than this pixel's own predecessor: on ajar (150 Adam steps, seeds
    //     1-3) the own predecessor ended at 1.01-1.04x the starting parameter error, the kd-tree's
    //     nearest at 0.94-0.96x and a random neighbour at 0.88-0.91x: mixing keeps one lucky sample
    //     from pushing the same texel step after step;
    //  2. this pixel's own predecessor;
    //  3. a search: last step's pixels around this one when they hold every stored reservoir (one
    //     view, nothing preserved, unmoved geometry), else the kd-tree. A point within the world
    //     radius R px * t of this one projects at most R (t/z)(1 + |x/z|) pixels away per axis
    //     (pinhole camera), plus one pixel for the two points' jitter: that bounds the window.
    probeItems_ = previous_ && s.options.pixelNeighbours ? previous_->pixelSlots(view_) : nullptr;
    windowSearch_ = probeItems_ && previous_->slotsCover(view_);
    if (probeItems_) {
      const int r = std::max(0, int(std::floor(s.options.radiusPixels - 1.f)));
      for (int dy = -r; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx)
          if (dx * dx + dy * dy <= r * r) probeOffsets_.push_back({dx, dy});
      const float tx = cam.tanHalfFovY * float(W) / float(H), ty = cam.tanHalfFovY;
      windowHalf_ = int(std::ceil(s.options.radiusPixels * (1.f + std::max(tx, ty)) * std::sqrt(1.f + tx * tx + ty * ty))) + 1;
    }
  }

  bool stratifiable() const override { return false; }  // its reservoirs are resampled together

  Rgb sample(const CameraSampleInput& in, Sampler& sampler, SampleCounters& counters, Rgb adjoint, PathGradient* grad,
             StoredReservoir* reservoir) const override {
    PathContext ctx{&counters.rays};
    auto direct = [&](const ShadingPoint& sp, int, Sampler& smp, PathContext* c, DirectPath& out) {
      return combine(in, sp, smp, c, counters.restir, out, reservoir);
    };
    return walkCameraPath(scene_, &params_, in.o, in.d, sampler, walk_, direct, &ctx, adjoint, grad, in.primary, view_);
  }

 private:
  bool combine(const CameraSampleInput& in, const ShadingPoint& sp, Sampler& sampler, PathContext* ctx, RestirCounters& counters,
               DirectPath& out, StoredReservoir* keep) const {
    const SurfaceHit& hit = *sp.hit;
    RestirSettings settings = settings_;
    settings.radius = pixelFootprint_ * hit.t;
    uint32_t tryFirst[2] = {UINT32_MAX, UINT32_MAX};
    NeighbourHints hints;
    if (probeItems_) {
      const int W = scene_.width, H = scene_.height;
      const auto& o = probeOffsets_[std::min(probeOffsets_.size() - 1, size_t(sampler.next1D() * float(probeOffsets_.size())))];
      int px = in.x + o.first, py = in.y + o.second;
      if (px >= 0 && py >= 0 && px < W && py < H) tryFirst[0] = probeItems_[(size_t(py) * size_t(W) + size_t(px)) * size_t(spp_) + size_t(in.slot)];
      tryFirst[1] = probeItems_[size_t(in.pixel) * size_t(spp_) + size_t(in.slot)];
      hints.items = tryFirst;
      hints.count = 2;
      // The two reservoirs are last step's (a cache miss each: the store is megabytes) and are read
      // only after the fresh candidates: fetching them now hides the miss behind that work.
      for (uint32_t i : tryFirst)
        if (i < previous_->size()) __builtin_prefetch(&previous_->items()[i]);
      if (windowSearch_) {
        hints.slots = probeItems_;
        hints.x = in.x;
        hints.y = in.y;
        hints.width = W;
        hints.height = H;
        hints.spp = spp_;
        hints.half = windowHalf_;
      }
    }
    Reservoir r;
    uint8_t deltaKnown = 0, deltaVisible = 0;
    bool contributes = sampleDirectRestir(scene_, sp, sampler, settings, previous_, ctx, out, r, &counters,
                                          probeItems_ ? &hints : nullptr, &deltaKnown, &deltaVisible);
    if (keep) {
      keep->r = StoredSample(r);
      keep->mesh = hit.mesh;
      keep->tri = hit.tri;
      keep->b1 = hit.b1;
      keep->b2 = hit.b2;
      keep->view = uint16_t(view_);
      keep->p = hit.p;
      keep->setNormal(hit.ns);
      keep->deltaKnown = deltaKnown;
      keep->deltaVisible = deltaVisible;
      keep->pose = previous_ ? previous_->createdPose() : 0;
    }
    return contributes;
  }

  const Scene& scene_;
  const ParameterRegistry& params_;
  RestirSettings settings_;
  const ReservoirStore* previous_;
  int view_, spp_;
  WalkSettings walk_;
  float pixelFootprint_ = 0.f;
  const uint32_t* probeItems_ = nullptr;
  bool windowSearch_ = false;
  std::vector<std::pair<int, int>> probeOffsets_;
  int windowHalf_ = 0;
};

}  // namespace

std::unique_ptr<InteriorEstimator> makeRestirEstimator(const EstimatorSetup& s) { return std::make_unique<RestirEstimator>(s); }

}  // namespace invr
