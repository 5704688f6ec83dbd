#include "core/diff/boundary_term.h"

#include <algorithm>
#include <deque>
#include <stdexcept>

#include "core/diff/gradient_options.h"
#include "core/error.h"

namespace invr {

namespace v1 = invr::v1;

std::vector<EdgeTopology> buildBoundaryTopology(const Scene& scene, const ParameterRegistry& params) {
  std::vector<EdgeTopology> topology;
  for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
    topology.push_back(EdgeTopology::build(scene.meshes[m]));
    // Deforming meshes: any two faces may turn apart. Smooth meshes that deform recompute welded
    // vertex normals: no edge is a crease; their edges where a light's facing flips (the shadow
    // terminator) are the primary term's own candidates, found per step.
    if (params.deforms(m)) {
      if (scene.meshes[m].normals.empty()) topology.back().markEveryEdgeACrease();
      else topology.back().markNoEdgeACrease();
    }
  }
  return topology;
}

BoundaryOptions parseBoundaryOptions(const v1::BoundarySpec& b) {
  auto fail = [](const std::string& field, const std::string& why) { throw InputError("optimization.boundary." + field + ": " + why); };
  const BoundaryOptions defaults;
  BoundaryOptions o;
  if (b.samples() < 0 || b.samples() > (1 << 24)) fail("samples", "must be in 1..16777216 (0: the default)");
  if (b.light_points() < 0 || b.light_points() > 4096)
    fail("light_points", "must be in 1..4096 (0: the default " + std::to_string(defaults.lightPoints) + ")");
  o.samples = b.samples();
  o.lightPoints = b.light_points() > 0 ? b.light_points() : defaults.lightPoints;
  o.primary = b.has_primary() ? b.primary() : defaults.primary;
  o.secondary = b.has_secondary() ? b.secondary() : defaults.secondary;
  o.multiViewShortcut = b.multi_view_shortcut();
  o.areaSampling = b.area_sampling() == v1::AREA_SAMPLING_LIGHT_POINTS ? BoundaryOptions::AreaSampling::LightPoints
                                                                       : BoundaryOptions::AreaSampling::EdgeFirst;
  o.allowUnsampled = b.allow_unsampled_discontinuities();
  // Each term reads its own message (and the shared fields that are its aliases).
  for (const BoundaryTermKind* k : boundaryTermKinds())
    if (std::unique_ptr<BoundaryTermOptions> own = k->parse(b)) o.terms.set(k->name, std::move(own));
  return o;
}

namespace {

std::vector<const BoundaryTermKind*>& registry() {
  static std::vector<const BoundaryTermKind*> kinds;
  return kinds;
}
std::deque<BoundaryTermKind>& storage() {  // stable addresses for the registry's pointers
  static std::deque<BoundaryTermKind> kinds;
  return kinds;
}

}  // namespace

RegisterBoundaryTerm::RegisterBoundaryTerm(BoundaryTermKind kind) {
  auto& kinds = registry();
  if (!kind.parse) throw std::logic_error("boundary term '" + kind.name + "': it must parse its options");
  if (kind.pinnedStream && kind.pinnedStream->value <= kLastEngineStream)
    throw std::logic_error("boundary term '" + kind.name + "': its pinned stream is one of the engine's own");
  for (const BoundaryTermKind* k : kinds) {
    if (k->name == kind.name || k->order == kind.order)
      throw std::logic_error("boundary term '" + kind.name + "': its name or order is taken by '" + k->name + "'");
    // Terms of one discontinuity may share a stream (alternative samplings of it, never both in
    // one job); `applies` keeps them apart.
    if (k->stream() == kind.stream() && k->samples != kind.samples)
      throw std::logic_error("boundary term '" + kind.name + "': its random stream is '" + k->name + "'s");
  }
  kinds.push_back(&storage().emplace_back(std::move(kind)));
  std::sort(kinds.begin(), kinds.end(), [](const BoundaryTermKind* a, const BoundaryTermKind* b) { return a->order < b->order; });
}

const std::vector<const BoundaryTermKind*>& boundaryTermKinds() { return registry(); }

bool sampledBy(Discontinuity d, const std::vector<const BoundaryTermKind*>& kinds) {
  for (const BoundaryTermKind* k : kinds)
    if (std::find(k->samples.begin(), k->samples.end(), d) != k->samples.end()) return true;
  return false;
}

std::vector<const BoundaryTermKind*> boundaryTermsFor(const Scene& scene, const ParameterRegistry& params, const GradientOptions& options) {
  std::vector<const BoundaryTermKind*> out;
  if (!params.hasVisibilityParameters()) return out;
  for (const BoundaryTermKind* k : registry())
    if (options.boundary.enabled(k->name) && k->applies(scene, options)) out.push_back(k);
  return out;
}

}  // namespace invr
