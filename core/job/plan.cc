#include "core/job/plan.h"

#include <algorithm>
#include <cstdio>
#include <sstream>

#include "core/diff/gradient_job_check.h"

namespace invr {

namespace {
std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}
std::string mib(double bytes) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f", bytes / 1048576.0);
  return b;
}
}  // namespace

v1::JobPlan planJob(const v1::JobSpec& job, const Problem& p, unsigned workerThreads) {
  v1::JobPlan plan;
  const Scene& s = *p.scene;
  const size_t pixels = size_t(s.width) * size_t(s.height);
  size_t tris = 0;
  for (const auto& m : s.meshes) tris += m.triangleCount();
  std::ostringstream out;
  out << "job " << job.name() << ": scene "
      << (job.has_zoo() ? job.zoo() : s.name.empty() ? std::string("(inline)") : s.name) << ", " << s.cameras.size() << " view(s) "
      << s.width << "x" << s.height << ", " << tris << " triangles, " << s.lights.size() << " light(s)\n";
  out << "parameters: " << p.params.size() << " values\n";
  plan.set_parameter_values(p.params.size());
  for (const auto& sl : p.params.slots()) {
    out << "  " << sl.name << ": " << sl.size << " value(s)";
    if (sl.width) out << " (" << sl.width << "x" << sl.height << " texture)";
    out << ", bounds [" << num(sl.lower) << ", " << num(sl.upper) << "], learning rate " << num(sl.learningRate) << "\n";
  }
  const auto& g = p.gradient;
  std::vector<std::string> est;
  const bool shapes = p.params.hasVisibilityParameters();
  if (p.params.hasCameraParameters())
    est.push_back("primal and derivative: direct illumination; interior term (Wang et al. 2023, Eq. 12-13) for materials and lights, and "
                  "for the moving cameras at every camera hit (the camera ray moves, its hit slides along the surface; diffuse untextured "
                  "meshes)" + std::string(p.params.hasShapeParameters() ? " and for shapes at the camera hit" : ""));
  else if (shapes)
    est.push_back("primal and derivative: direct illumination; interior term (Wang et al. 2023, Eq. 12-13) for materials and lights, and "
                  "for shapes at the camera hit (the hit slides along the fixed camera ray, normals turn; diffuse untextured moving meshes)");
  else if (g.maxDepth > 1)
    est.push_back("primal and derivative: path tracing up to " + std::to_string(g.maxDepth) +
                  " vertices with NEE + MIS and Russian roulette, derivatives by replaying each path's recorded vertices; interior term only");
  else
    est.push_back("primal and derivative: direct illumination, interior term only (Wang et al. 2023, Eq. 12-13)");
  est.push_back("independent primal and derivative passes (" + std::to_string(g.sppPrimal) + " + " + std::to_string(g.sppGradient) +
                " spp); the reported loss is their unbiased product (I1 - T)(I2 - T)");
  std::string light = "light sampling: " + std::string(gradientMethodName(g.method));
  if (g.method != GradientMethod::Pt)
    light += " (" + std::to_string(g.restir.candidates) + " candidates, visibility " + (g.restir.visibilityInTarget ? "in" : "not in") +
             " the target)";
  if (g.method == GradientMethod::Restir)
    light += "; reuse: " + std::to_string(g.restir.neighbours) + " neighbour(s) within " + num(g.radiusPixels) + " px, M-cap " +
             num(g.restir.mCap) + ", burn-in " + std::to_string(p.burnIn) + (g.forwardOnly ? ", forward only" : "") +
             (g.preserveOccluded ? ", reservoirs no step replaced are kept (Alg. 8)" : "");
  est.push_back(light);
  const int batchSamples = g.pixels.samplesFor(pixels);
  std::string px = "pixels: " + std::string(g.pixels.sampler->name()) + " (" + g.pixels.sampler->describe(g.pixels) + ")";
  if (g.pixels.sampler->miniBatch())
    px += "; a mini-batch of " + std::to_string(batchSamples) + " pixel samples per view, each traced, weighted 1/(N p), defensive uniform share " +
          num(g.pixels.defensive);
  if (g.pixels.sampler->usesStage1())
    px += "; stage-1 maps every " + std::to_string(g.pixels.refreshEvery) + " steps (one pixel in " + std::to_string(g.pixels.stage1Stride) +
          " per axis, 1 sample, edge-aware upsampling)";
  est.push_back(px);
  if (g.variance.enabled) {
    const auto& v = g.variance;
    std::string line = "variance pass (Yan et al. 2024): " + std::to_string(v.spp) + " spp of fresh paths per step, " +
                       (v.detached ? "detached estimator (Weier et al. 2021 baseline: densities held constant)"
                                   : "unbiased estimator (every sampling decision scored, MIS and roulette differentiated)") +
                       ", the primal render as the independent mean; loss = bias + ";
    line += v.cost == VarianceCost::Depth ? num(v.weight) + " * t * V, t the render cost in rays per sample (Eq. 33, 36)"
                                          : num(v.weight) + " / " + num(v.samples) + " * V (Eq. 32)";
    est.push_back(line);
  }
  if (!p.scene->sampling.survival.empty()) {
    std::string q;
    for (float x : p.scene->sampling.survival) q += (q.empty() ? "" : ", ") + num(x);
    est.push_back("Russian roulette: fixed survival per bounce (" + q + "; the last repeats)");
  }
  if (shapes) {
    const auto& b = g.boundary;
    size_t maxShardViews = 0;
    for (const auto& sh : p.shards) maxShardViews = std::max(maxShardViews, sh.size());
    const BoundaryPlanInput input{s, g, maxShardViews, &p.params};
    if (!b.primary) est.push_back("boundary, primary: off (ablation)");
    if (!b.secondary) est.push_back("boundary, secondary (shadow borders): off (ablation)");
    for (const BoundaryTermKind* term : boundaryTermKinds())
      if (!b.enabled(term->name)) est.push_back("boundary, " + term->name + ": off (boundary.terms." + term->name + ".enabled false: an ablation)");
    for (const BoundaryTermKind* term : boundaryTermsFor(s, p.params, g)) est.push_back(term->describe(input));
    const std::vector<std::string> unsampled = unsampledDiscontinuities(s, p.params);
    if (unsampled.empty())
      est.push_back("discontinuities not sampled: none found (no moving shape, or any shape when a camera moves, touches another surface or itself where a camera sees it, in the scene as given, "
                    "and no spot cone is hard; contact curves and hard cone borders would not be sampled)");
    for (const std::string& u : unsampled)
      est.push_back("BIASED (boundary.allow_unsampled_discontinuities): " + u + "; no boundary term samples it");
    bool deformed = false;
    for (uint32_t m : p.params.movingMeshes()) deformed = deformed || p.params.deforms(m);
    if (deformed)
      est.push_back("vertex parameters: each vertex takes the interior term through the hit triangle's position and normal, and the boundary "
                    "terms through the edge point's position along its edge; every edge of a deforming flat-shaded mesh is a crease "
                    "candidate, and of a deforming smooth one its shadow terminator's edges (found each step)");
    if (g.method == GradientMethod::Restir)
      est.push_back(b.multiViewShortcut
                        ? "reused samples' support tested in the current geometry (multi-view shortcut, §3.2: biased while geometry moves)"
                        : std::string("reused samples' support tested in the geometry they were created in (§3.2: unbiased; the poses of the moving "
                                      "shapes are kept per step") +
                              (deformed ? ", and the vertices of deformed meshes with a BVH over them)" : ")"));
  } else {
    est.push_back("boundary (visibility) terms: none: only material and light parameters are optimised, so no visibility discontinuity moves with them");
  }
  est.push_back("light transport of targets, gradients and final renders: " +
                (g.maxDepth > 1 ? std::to_string(g.maxDepth) + " vertices, NEE + MIS" : std::string("direct illumination")));
  out << "estimators:\n";
  for (const auto& e : est) {
    out << "  " << e << "\n";
    plan.add_estimators(e);
  }
  out << "  loss " << lossName(g.loss) << ", optimiser " << optimizerKindName(p.optimizer)
      << (p.schedule.halfLifeSteps > 0 ? " (the t-th update at learning_rate * h / (h + t), h = " + num(p.schedule.halfLifeSteps) + ")"
                                       : std::string(" (constant learning rates)"))
      << ", " << p.steps << " steps, " << p.viewsPerStep << " view(s) per step\n";
  out << "targets: "
      << (p.groundTruthKnown()
              ? "rendered from the scene (" + std::to_string(p.targetSpp) + " spp)" +
                    (parameterError(p, p.initial) >= 0 ? "; parameter error reported"
                     : p.truthMeshes.empty()           ? "; sampling parameters only: no parameter error"
                                                       : "; no parameter error (started from another mesh)") +
                    (p.truthMeshes.empty() ? "" : "; shape error reported (chamfer distance to the scene's own mesh over its bounding-box diagonal)")
              : std::string("uploaded images; no ground truth"))
      << "\n";
  size_t maxShard = 0;
  for (const auto& sh : p.shards) maxShard = std::max(maxShard, sh.size());
  // A mini-batch traces each of its N draws (a pixel drawn twice, twice); stage 1 comes on top.
  const double pixelSamples = g.pixels.sampler->miniBatch() ? double(batchSamples) : double(pixels);
  const double paths = double(p.viewsPerStep) * pixelSamples * double(g.sppPrimal + g.sppGradient + (g.variance.enabled ? g.variance.spp : 0));
  out << "work: " << p.shards.size() << " shard(s) of views (at most " << maxShard << " per shard), " << num(paths / 1e6)
      << " M camera paths per step\n";
  plan.set_shards(uint32_t(p.shards.size()));
  plan.set_views_per_step(uint32_t(p.viewsPerStep));
  plan.set_camera_paths_per_step(paths);
  // Memory of one worker holding the largest shard (the model the service checks its budget with).
  const WorkerMemory mem = estimateWorkerMemory(p, workerThreads);
  out << "memory per worker (largest shard, " << workerThreads << " threads): ~" << mib(mem.total()) << " MiB (geometry "
      << mib(mem.geometry) << ", images " << mib(mem.images) << ", reservoirs " << mib(mem.reservoirs) << ", gradients "
      << mib(mem.gradients) << ", textures " << mib(mem.textures)
      << (g.variance.enabled ? ", variance pass " + mib(mem.variance) : std::string())
      << (shapes ? ", boundary edges " + mib(mem.boundary) : std::string()) << ")\n";
  plan.set_worker_threads(workerThreads);
  plan.set_worker_memory_bytes(mem.total());
  plan.set_geometry_bytes(mem.geometry);
  plan.set_image_bytes(mem.images);
  plan.set_reservoir_bytes(mem.reservoirs);
  plan.set_gradient_bytes(mem.gradients);
  plan.set_texture_bytes(mem.textures);
  plan.set_variance_bytes(mem.variance);
  plan.set_boundary_bytes(mem.boundary);
  plan.set_text(out.str());
  return plan;
}

}  // namespace invr
