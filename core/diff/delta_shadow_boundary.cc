#include "core/diff/delta_shadow_boundary.h"

#include "core/diff/gradient_options.h"
#include "core/diff/shadow_border.h"

namespace invr {

DeltaShadowBoundary::DeltaShadowBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology)
    : scene_(scene), params_(params), topology_(topology) {}

bool DeltaShadowBoundary::applies(const Scene& scene) {
  for (const Light& l : scene.lights)
    if (l.isDelta()) return true;
  return false;
}

BoundaryPassStats DeltaShadowBoundary::run(const BoundaryView& bv) {
  std::vector<BorderSource> sources;
  std::vector<const Light*> lights;
  for (const Light& light : scene_.lights) {
    if (!light.isDelta()) continue;
    sources.push_back({ShadowSource::at(light.position)});
    lights.push_back(&light);
  }
  return sampleShadowBorders(
      scene_, params_, topology_, bv.view, bv.adjoint, bv.samples, sources,
      [&](uint32_t j, const SurfaceHit& at, Vec3 eye, RayStats& rays) { return deltaSourceRadiance(scene_, at, eye, *lights[j], rays); }, bv.stream,
      bv.step, bv.scratch, bv.gradient, bv.cancel, bv.sampler, bv.pixels);
}

namespace {

constexpr const char* kName = "delta_shadows";

const RegisterBoundaryTerm kDeltaShadows({
    .name = kName,
    .order = 20,
    .pinnedStream = kDeltaShadowBoundaryStream,
    .applies = [](const Scene& scene, const GradientOptions& o) { return o.boundary.secondary && DeltaShadowBoundary::applies(scene); },
    .make = [](const BoundaryStep& s) -> std::unique_ptr<BoundaryTerm> {
      return std::make_unique<DeltaShadowBoundary>(s.scene, s.params, s.topology);
    },
    .describe =
        [](const BoundaryPlanInput& in) {
          return "boundary, secondary, point/spot lights: " + std::to_string(in.options.boundary.samplesFor(kName, in.scene.width, in.scene.height)) +
                 " samples per view and step on occluder silhouette edges seen from each light, that light's jump evaluated directly";
        },
    .memoryBytes = {},
    .samples = {Discontinuity::DeltaLightShadows},
    .parse = [](const invr::v1::BoundarySpec& b) -> std::unique_ptr<BoundaryTermOptions> {
      if (!b.terms().has_delta_shadows()) return nullptr;
      auto o = std::make_unique<BoundaryTermOptions>();
      parseSharedTermFields(b.terms().delta_shadows(), kName, *o);
      return o;
    },
});

}  // namespace

}  // namespace invr
