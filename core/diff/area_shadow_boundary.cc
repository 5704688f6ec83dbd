#include "core/diff/area_shadow_boundary.h"

#include <algorithm>

#include "core/diff/gradient_options.h"
#include "core/diff/shadow_border.h"
#include "core/math/sampling.h"

namespace invr {

AreaShadowBoundary::AreaShadowBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology,
                                       int lightPoints)
    : lightPoints_(lightPoints), scene_(scene), params_(params), topology_(topology) {}

bool AreaShadowBoundary::applies(const Scene& scene) {
  for (const Light& l : scene.lights)
    if (emittedPower(l) > 0.f) return true;
  return false;
}

BoundaryPassStats AreaShadowBoundary::run(const BoundaryView& bv) {
  const int view = bv.view, samples = bv.samples, lightPoints = lightPoints_;
  const uint64_t stream = bv.stream, step = bv.step;
  const SamplerKind samplerKind = bv.sampler;
  std::vector<float> power(scene_.lights.size());
  for (size_t i = 0; i < power.size(); ++i) power[i] = emittedPower(scene_.lights[i]);
  if (samples <= 0 || lightPoints <= 0 || *std::max_element(power.begin(), power.end()) <= 0.f) return {};
  const Distribution1D pickLight(power);
  // The pass's light points: keyed by the step, view and point index (not by thread).
  std::vector<LightPoint> points;
  std::vector<BorderSource> sources;
  for (int j = 0; j < lightPoints; ++j) {
    Sampler s = Sampler::forSampleSet(samplerKind, RngKey{stream, step, uint64_t(view), uint64_t(j), 1});
    const uint32_t li = uint32_t(pickLight.sample(s.next1D()));
    const Light& l = scene_.lights[li];
    float remapped;
    const Vec2 uv = s.next2D();
    const float u = uv.x, v = uv.y;
    const uint32_t tri = uint32_t(l.triangles.sample(u, &remapped));
    const Vec2 bc = sampleUniformTriangle({remapped, v});
    const SurfaceHit y = scene_.surfaceAt(l.mesh, tri, bc.x, bc.y);
    points.push_back({li, y.p, y.ng, double(pickLight.pmf(li)) / double(l.area)});
    // The density of y_j over the pass's lightPoints draws.
    sources.push_back({ShadowSource::at(y.p, y.ng), 1.0 / (points.back().pdf * double(lightPoints)), l.mesh});
  }
  return sampleShadowBorders(
      scene_, params_, topology_, view, bv.adjoint, samples, sources,
      [&](uint32_t j, const SurfaceHit& at, Vec3 eye, RayStats& rays) {
        return pointSourceRadiance(scene_, at, eye, scene_.lights[points[j].light], points[j], rays);
      },
      stream, step, bv.scratch, bv.gradient, bv.cancel, bv.sampler, bv.pixels);
}

namespace {

const RegisterBoundaryTerm kAreaLightPoints({
    .name = LightPointsAreaShadowOptions::kTerm,
    .order = 31,
    .pinnedStream = kAreaShadowBoundaryStream,
    .applies =
        [](const Scene& scene, const GradientOptions& o) {
          return o.boundary.secondary && o.boundary.areaSampling == BoundaryOptions::AreaSampling::LightPoints && AreaShadowBoundary::applies(scene);
        },
    .make = [](const BoundaryStep& s) -> std::unique_ptr<BoundaryTerm> {
      return std::make_unique<AreaShadowBoundary>(s.scene, s.params, s.topology,
                                                  s.options.boundary.termOr<LightPointsAreaShadowOptions>().lightPointsOf(s.options.boundary));
    },
    .describe =
        [](const BoundaryPlanInput& in) {
          const BoundaryOptions& b = in.options.boundary;
          return "boundary, secondary, area lights (Eq. 21-26): " + std::to_string(b.samplesFor(LightPointsAreaShadowOptions::kTerm, in.scene.width, in.scene.height)) +
                 " samples per view and step over the silhouette edges of " + std::to_string(b.termOr<LightPointsAreaShadowOptions>().lightPointsOf(b)) +
                 " light points per pass, jump evaluated directly";
        },
    .memoryBytes = {},
    .samples = {Discontinuity::AreaLightShadows},
    .parse = [](const invr::v1::BoundarySpec& b) -> std::unique_ptr<BoundaryTermOptions> {
      if (!b.terms().has_area_shadows_light_points()) return nullptr;
      const invr::v1::LightPointsAreaShadowSpec& spec = b.terms().area_shadows_light_points();
      auto o = std::make_unique<LightPointsAreaShadowOptions>();
      parseSharedTermFields(spec, LightPointsAreaShadowOptions::kTerm, *o);
      if (spec.light_points() < 0 || spec.light_points() > 4096)
        throw InputError("optimization.boundary.terms.area_shadows_light_points.light_points: must be in 1..4096 (0: optimization.boundary.light_points)");
      o->lightPoints = spec.light_points();
      return o;
    },
});

}  // namespace

}  // namespace invr
