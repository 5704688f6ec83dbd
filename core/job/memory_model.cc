#include "core/job/memory_model.h"

#include <algorithm>

#include "core/diff/area_shadow_boundary.h"
#include "core/diff/environment_shadow_boundary.h"
#include "core/restir/reservoir_store.h"

namespace invr {

WorkerMemory estimateWorkerMemory(const Problem& p, unsigned threads) {
  const Scene& s = *p.scene;
  const auto& g = p.gradient;
  const double pixels = double(s.width) * double(s.height);
  double tris = 0;
  for (const auto& m : s.meshes) tris += double(m.triangleCount());
  size_t maxShard = 0;
  for (const auto& sh : p.shards) maxShard = std::max(maxShard, sh.size());
  WorkerMemory w;
  w.geometry = tris * (3 * 12 + 12 + 4 * 3) * 2.5;  // vertices, face normals, indices; BVH ~1.5x
  // Moving meshes keep their rest pose (vertices, normals) and a BVH of it, for tests in past
  // geometry (Scene::pose()).
  double movingTris = 0, deformedTris = 0;
  for (uint32_t m : p.params.movingMeshes()) (p.params.deforms(m) ? deformedTris : movingTris) += double(s.meshes[m].triangleCount());
  w.geometry += movingTris * (3 * 12 + 4 * 3) * 2.5;
  // Deformed meshes (vertex parameters) under ReSTIR keep, per geometry a kept reservoir was
  // created in (last step's and this one's), their vertices, face normals and a BVH over them.
  if (g.method == GradientMethod::Restir && !g.boundary.multiViewShortcut) w.geometry += 2 * deformedTris * (3 * 12 + 12) * 2.5;
  // Smooth deformed meshes keep their vertex normals with each such geometry, ~one vertex per two triangles.
  double smoothDeformedTris = 0;
  for (uint32_t m : p.params.movingMeshes())
    if (p.params.deforms(m) && !s.meshes[m].normals.empty()) smoothDeformedTris += double(s.meshes[m].triangleCount());
  if (g.method == GradientMethod::Restir && !g.boundary.multiViewShortcut) w.geometry += 2 * smoothDeformedTris * 0.5 * 12;
  double texels = 0;
  for (const auto& sl : p.params.slots()) texels += sl.width ? double(sl.size) * 4 : 0;
  w.textures = texels * 3;
  w.images = double(maxShard) * pixels * 12 * 3;
  if (g.method == GradientMethod::Restir)
    w.reservoirs = double(maxShard) * pixels * double(g.sppPrimal + (g.forwardOnly ? 0 : g.sppGradient)) *
                   double(sizeof(StoredReservoir) + 24) * 2;  // current and previous chain, kd-tree
  // Dense accumulators per thread and per evaluation, with the smooth meshes' vertex-normal
  // entries (ParameterRegistry::adjointSize); a thread's scratch also keeps a touched byte each.
  w.gradients = double(p.params.adjointSize()) * 9 * double(threads + 2);
  // Per view: dL/dV, the pass's mean and second moment, the variance map (RGB floats each); per
  // thread: one walk's decision records (variance_visitor.h), at most a few hundred bytes per vertex.
  if (g.variance.enabled) w.variance = double(maxShard) * pixels * 12 * 4 + double(threads) * double(g.maxDepth + 1) * 512;
  // Shape and camera parameters: 1.5 welded edges per triangle (MeshEdge, 20 bytes) plus the weld map per
  // vertex; a pass's candidate lists hold at most every edge once per light point or environment
  // direction (ShadowEdge, 32 bytes, and its weight), and the film-space primary candidates.
  if (p.params.hasVisibilityParameters()) {
    double points = 0;
    const double area = g.boundary.termOr<LightPointsAreaShadowOptions>().lightPointsOf(g.boundary);
    const double directions = g.boundary.termOr<EnvironmentShadowOptions>().directionsOf(g.boundary);
    for (const Light& l : s.lights) points += l.kind == LightKind::Area ? area : l.isInfinite() ? directions : l.isDelta() ? 1.0 : 0.0;
    w.boundary = tris * 1.5 * 20 + tris * 3 * 4 + tris * 1.5 * (points + 1) * 36;
    // What the boundary terms keep beyond that (edge reservoirs).
    const BoundaryPlanInput input{s, g, maxShard};
    for (const BoundaryTermKind* term : boundaryTermsFor(s, p.params, g))
      if (term->memoryBytes) w.boundary += term->memoryBytes(input);
  }
  return w;
}

}  // namespace invr
