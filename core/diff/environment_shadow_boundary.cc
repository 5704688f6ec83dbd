#include "core/diff/environment_shadow_boundary.h"

#include <algorithm>

#include "core/diff/gradient_options.h"
#include "core/diff/shadow_border.h"

namespace invr {

EnvironmentShadowBoundary::EnvironmentShadowBoundary(const Scene& scene, const ParameterRegistry& params,
                                                     const std::vector<EdgeTopology>& topology, int directions)
    : directions_(directions), scene_(scene), params_(params), topology_(topology) {}

bool EnvironmentShadowBoundary::applies(const Scene& scene) {
  for (const Light& l : scene.lights)
    if (l.isInfinite()) return true;
  return false;
}

BoundaryPassStats EnvironmentShadowBoundary::run(const BoundaryView& bv) {
  const int view = bv.view, samples = bv.samples, directions = directions_;
  const uint64_t stream = bv.stream, step = bv.step;
  const SamplerKind samplerKind = bv.sampler;
  std::vector<uint32_t> environments;
  for (uint32_t i = 0; i < scene_.lights.size(); ++i)
    if (scene_.lights[i].isInfinite()) environments.push_back(i);
  if (samples <= 0 || directions <= 0 || environments.empty()) return {};
  // The pass's directions: keyed by the step, view and direction index (not by thread). A
  // direction the environment gives no radiance or density keeps its slot with weight 0 (no edges).
  std::vector<LightSample> dirs;
  std::vector<BorderSource> sources;
  for (int j = 0; j < directions; ++j) {
    Sampler s = Sampler::forSampleSet(samplerKind, RngKey{stream, step, uint64_t(view), uint64_t(j), 1});
    const uint32_t li = environments[std::min(environments.size() - 1, size_t(s.next1D() * float(environments.size())))];
    const Vec2 uv = s.next2D();
    const float u = uv.x, v = uv.y;
    dirs.push_back(sampleLight(scene_.lights[li], scene_, Vec3(0.f), Vec2(u, v), li));
    // Solid-angle density of w_j (environment choice included) over the pass's draws.
    const double pdf = double(dirs.back().pdf) / double(environments.size());
    const bool usable = pdf > 0.0 && !isBlack(dirs.back().radiance);
    sources.push_back({ShadowSource::towards(dirs.back().wi), usable ? 1.0 / (pdf * double(directions)) : 0.0});
  }
  return sampleShadowBorders(
      scene_, params_, topology_, view, bv.adjoint, samples, sources,
      [&](uint32_t j, const SurfaceHit& at, Vec3 eye, RayStats& rays) { return directionalSourceRadiance(scene_, at, eye, dirs[j], rays); }, stream,
      step, bv.scratch, bv.gradient, bv.cancel, bv.sampler, bv.pixels);
}

namespace {

const RegisterBoundaryTerm kEnvironmentShadows({
    .name = EnvironmentShadowOptions::kTerm,
    .order = 40,
    .pinnedStream = kEnvironmentShadowBoundaryStream,
    .applies = [](const Scene& scene, const GradientOptions& o) { return o.boundary.secondary && EnvironmentShadowBoundary::applies(scene); },
    .make = [](const BoundaryStep& s) -> std::unique_ptr<BoundaryTerm> {
      return std::make_unique<EnvironmentShadowBoundary>(s.scene, s.params, s.topology,
                                                         s.options.boundary.termOr<EnvironmentShadowOptions>().directionsOf(s.options.boundary));
    },
    .describe =
        [](const BoundaryPlanInput& in) {
          const BoundaryOptions& b = in.options.boundary;
          return "boundary, secondary, environment lights: " + std::to_string(b.samplesFor(EnvironmentShadowOptions::kTerm, in.scene.width, in.scene.height)) +
                 " samples per view and step over the silhouette edges of " + std::to_string(b.termOr<EnvironmentShadowOptions>().directionsOf(b)) +
                 " directions per pass drawn by the environment's sampling, jump evaluated directly";
        },
    .memoryBytes = {},
    .samples = {Discontinuity::EnvironmentShadows},
    .parse = [](const invr::v1::BoundarySpec& b) -> std::unique_ptr<BoundaryTermOptions> {
      if (!b.terms().has_environment_shadows()) return nullptr;
      const invr::v1::EnvironmentShadowBoundarySpec& spec = b.terms().environment_shadows();
      auto o = std::make_unique<EnvironmentShadowOptions>();
      parseSharedTermFields(spec, EnvironmentShadowOptions::kTerm, *o);
      if (spec.directions() < 0 || spec.directions() > 4096)
        throw InputError("optimization.boundary.terms.environment_shadows.directions: must be in 1..4096 (0: optimization.boundary.light_points)");
      o->directions = spec.directions();
      return o;
    },
});

}  // namespace

}  // namespace invr
