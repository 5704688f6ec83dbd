#include "core/diff/gradient_job_check.h"

#include <cmath>
#include <set>

#include "core/error.h"
#include "core/geometry/edge_topology.h"
#include "core/geometry/embree_scene.h"
#include "core/diff/boundary_term.h"
#include "core/diff/parameter_kind.h"

namespace invr {

namespace {

// Meshes (a, b) whose surfaces touch or cross where a camera sees it, in the scene as given: an edge
// of one, lengthened by `tol` at both ends, meets a triangle of the other (of the same mesh: a
// triangle that shares no vertex with the edge), at a point inside a camera's view with nothing in
// front of it. Two triangles that cross or touch along a curve have an edge of one meeting the
// other, so testing the edges of each moving mesh against everything, and everything else's edges
// against the moving meshes, finds every pair with a moving member. A contact no camera sees puts
// no discontinuity on the film (the tree's parts meet out of view).
std::set<std::pair<uint32_t, uint32_t>> touchingPairs(const Scene& scene, const ParameterRegistry& params) {
  std::set<std::pair<uint32_t, uint32_t>> pairs;
  const float tol = 1e-4f * scene.radius;
  std::vector<EdgeTopology> topology(scene.meshes.size());
  // A moving camera moves every contact curve on its film: every mesh counts as moving.
  std::vector<uint32_t> movers = params.movingMeshes();
  if (params.hasCameraParameters()) {
    movers.resize(scene.meshes.size());
    for (uint32_t m = 0; m < movers.size(); ++m) movers[m] = m;
  }
  std::vector<bool> moving(scene.meshes.size(), false);
  for (uint32_t m : movers) moving[m] = true;
  EmbreeScene all;
  all.build(scene.meshes);
  std::vector<TriangleMesh> movingMeshes;
  std::vector<uint32_t> movingIndex;
  for (uint32_t m : movers) {
    movingMeshes.push_back(scene.meshes[m]);
    movingIndex.push_back(m);
  }
  EmbreeScene moverAccel;
  moverAccel.build(movingMeshes);
  auto seen = [&](Vec3 p) {
    for (const Camera& cam : scene.cameras) {
      float px, py;
      if (!cam.project(p, scene.width, scene.height, px, py)) continue;
      const Vec3 d = p - cam.eye;
      const float dist = length(d);
      // Stopped short of the point: the surfaces that meet there must not hide it from itself.
      if (dist > 0.f && !all.occluded(cam.eye, d / dist, 0.f, dist - 4.f * tol)) return true;
    }
    return false;
  };
  // Every hit along the edge a -> b of mesh `from`, against `accel` (whose mesh k is meshOf(k)).
  auto crossEdge = [&](uint32_t from, const EdgeTopology& topo, const MeshEdge& e, const EmbreeScene& accel, auto meshOf) {
    const TriangleMesh& mesh = scene.meshes[from];
    const Vec3 a = mesh.positions[e.v0], b = mesh.positions[e.v1];
    const float len = length(b - a);
    if (!(len > 0.f)) return;
    const Vec3 d = (b - a) / len, o = a - d * tol;
    float tnear = 0.f;
    const float tfar = len + 2.f * tol;
    for (int guard = 0; guard < 64 && tnear < tfar; ++guard) {
      RayHit h;
      if (!accel.intersect(o, d, tnear, tfar, h)) return;
      const uint32_t other = meshOf(h.mesh);
      if (other == from) {
        // Its own faces around the edge's end points lie along the ray: not a contact.
        bool adjacent = false;
        for (int k = 0; k < 3; ++k) {
          const uint32_t v = topo.welded(mesh.indices[3 * h.tri + uint32_t(k)]);
          adjacent = adjacent || v == topo.welded(e.v0) || v == topo.welded(e.v1);
        }
        if (adjacent) {
          tnear = std::nextafter(h.t, tfar) + 1e-3f * tol;
          continue;
        }
      }
      if (seen(o + d * h.t)) {
        pairs.insert({std::min(from, other), std::max(from, other)});
        return;
      }
      tnear = std::nextafter(h.t, tfar) + 1e-3f * tol;
    }
  };
  for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
    topology[m] = EdgeTopology::build(scene.meshes[m]);
    for (const MeshEdge& e : topology[m].edges()) {
      if (moving[m]) crossEdge(m, topology[m], e, all, [](uint32_t k) { return k; });
      else crossEdge(m, topology[m], e, moverAccel, [&](uint32_t k) { return movingIndex[k]; });
    }
  }
  return pairs;
}

std::string quoted(const std::string& s) { return "'" + s + "'"; }

}  // namespace

std::vector<std::string> unsampledDiscontinuities(const Scene& scene, const ParameterRegistry& params) {
  return unsampledDiscontinuities(scene, params, boundaryTermKinds());
}

std::vector<std::string> unsampledDiscontinuities(const Scene& scene, const ParameterRegistry& params,
                                                  const std::vector<const BoundaryTermKind*>& terms) {
  std::vector<std::string> out;
  if (!params.hasVisibilityParameters()) return out;
  const bool camera = params.hasCameraParameters();
  auto unsampled = [&](Discontinuity d) { return !sampledBy(d, terms); };
  // What the job's moving geometry or cameras put on the film, each kind asked of the terms.
  if (unsampled(Discontinuity::MeshEdges))
    out.push_back(std::string("the edges of ") + (camera ? "every shape in a moving view" : "the moving shapes") +
                  " (silhouettes and creases) move on the film");
  for (const Light& l : scene.lights) {
    const Discontinuity d = l.isDelta() ? Discontinuity::DeltaLightShadows
                            : l.kind == LightKind::Area ? Discontinuity::AreaLightShadows
                                                        : Discontinuity::EnvironmentShadows;
    if (unsampled(d)) out.push_back("light " + quoted(l.name) + " casts shadows whose borders move on the film");
  }
  if (unsampled(Discontinuity::ContactCurves))
    for (const auto& [a, b] : touchingPairs(scene, params)) {
      if (camera && a != b)
        out.push_back("shapes " + quoted(scene.meshNames[a]) + " and " + quoted(scene.meshNames[b]) +
                      " touch or cut each other in view: their contact curve moves on the film with the camera and is not a mesh edge");
      else if (a == b)
        out.push_back("shape " + quoted(scene.meshNames[a]) + " cuts or touches itself in view: the curve where it does is a visibility discontinuity, not a mesh edge");
      else
        out.push_back("shape " + quoted(scene.meshNames[params.moves(a) ? a : b]) + " touches or cuts " +
                      quoted(scene.meshNames[params.moves(a) ? b : a]) + " in view: their contact curve moves with it and is not a mesh edge");
    }
  if (unsampled(Discontinuity::HardSpotCones))
    for (const Light& l : scene.lights)
      if (l.kind == LightKind::Spot && l.cosInner <= std::nextafter(l.cosOuter, 1.f))
        out.push_back("spot light " + quoted(l.name) +
                      " has a hard cone edge (cone_inner_degrees == cone_outer_degrees): its border moves across the moving surfaces it lights");
  if (camera && unsampled(Discontinuity::EnvironmentTexelBorders))
    for (const Light& l : scene.lights)
      if (l.kind == LightKind::Environment)
        out.push_back("environment map " + quoted(l.name) +
                      " is seen by a moving camera: its texel borders move on the film (a constant environment has none)");
  return out;
}

void validateGradientJob(const Scene& scene, const ParameterRegistry& params, const GradientOptions& o) {
  auto fail = [](const std::string& field, const std::string& why) { throw InputError("optimization." + field + ": " + why); };
  if (params.hasSamplingParameters() && o.method != GradientMethod::Pt)
    fail("parameters", "sampling parameters (sampling/...) need method METHOD_PT");
  // The time-aware loss weighs V by t, and dt/dtheta = E[R S] (R the rays of a path, S its score)
  // is estimated in closed form for fixed survival only (render_cost.h). Albedos, roughness and
  // light settings change t too (throughput roulette, rejected BSDF samples, light selection).
  if (o.variance.enabled && o.variance.cost == VarianceCost::Depth)
    for (const ParameterSlot& s : params.slots())
      if (std::string(s.kind->name()) != "rr_survival")
        fail("variance.cost_model", "\"depth\" optimises sampling/rr_survival only: the render cost t also depends on '" + s.name +
                                        "' (through roulette and sampling), and V dt/dtheta is not estimated for it; use cost_model none "
                                        "or optimise sampling/rr_survival alone");
  if (o.variance.enabled)
    for (const ParameterSlot& s : params.slots())
      if (!s.kind->varianceDerivatives())
        fail("parameters", "'" + s.name + "': variance-aware losses have no derivatives for " + s.kind->name() + " parameters yet");
  if (!params.hasVisibilityParameters()) return;
  const bool camera = params.hasCameraParameters();
  const std::string what = camera ? "camera parameters: " : "shape parameters: ";
  if (o.maxDepth != 1) fail("parameters", what + "the interior shape derivative covers direct illumination only; set max_depth 1");
  if (o.pixels.sampler->miniBatch()) fail("parameters", what + "the boundary terms need dLoss/dI at every pixel; use pixel_sampler all");
  if (o.variance.enabled) fail("parameters", what + "variance-aware losses have no shape derivatives yet");
  for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
    // A moving camera slides every camera hit along its surface (shape_interior.h).
    if (!params.moves(m) && !camera) continue;
    const Material& mat = scene.materials[size_t(scene.meshMaterial[m])];
    if (mat.kind != BsdfKind::Diffuse || !mat.albedo.isConstant())
      fail("parameters", what + "shape '" + scene.meshNames[m] + "' has material '" + mat.name +
                             "': the interior derivative of a moving " + (camera ? "camera" : "shape") +
                             " covers diffuse, untextured materials only");
  }
  if (!o.boundary.allowUnsampled) {
    const std::vector<std::string> unsampled = unsampledDiscontinuities(scene, params);
    if (!unsampled.empty()) {
      std::string why;
      for (const std::string& u : unsampled) why += (why.empty() ? "" : "; ") + u;
      fail("parameters", what + why +
                             ". No boundary term samples such a discontinuity, so the gradients would be biased: separate the shapes "
                             "(or soften the cone: cone_inner_degrees < cone_outer_degrees; or light a moving view with a constant environment), "
                             "or accept the bias with "
                             "optimization.boundary.allow_unsampled_discontinuities");
    }
  }
}

}  // namespace invr
