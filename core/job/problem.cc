#include "core/job/problem.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>

#include "core/diff/gradient_engine.h"
#include "core/diff/gradient_job_check.h"
#include "core/error.h"
#include "core/image/image.h"
#include "core/math/rng.h"
#include "core/render/renderer.h"
#include "core/diff/parameter_kind.h"

namespace invr {

namespace v1 = invr::v1;

namespace {

// An image the job gives per view (a target, a mask), read and checked against the film's size.
Image readViewImage(const v1::AssetRef& ref, const std::string& field, bool srgb, const AssetResolver& assets, const Scene& scene) {
  Image im;
  try {
    im = readImage(assets.resolve(ref, field), srgb, assets.budget);
  } catch (const InputError& e) {
    if (std::string(e.what()).rfind(field, 0) == 0) throw;
    rethrowWithMessage(e, field + ": " + e.what());
  }
  if (im.width() != scene.width || im.height() != scene.height)
    throw InputError(field + ": is " + std::to_string(im.width()) + "x" + std::to_string(im.height()) + ", the film is " +
                     std::to_string(scene.width) + "x" + std::to_string(scene.height));
  return im;
}

}  // namespace

Problem buildProblem(const v1::JobSpec& job, const AssetResolver& assets, SceneUse use) {
  const auto& o = job.optimization();
  auto fail = [](const std::string& field, const std::string& why) { throw InputError("optimization." + field + ": " + why); };
  Problem p;
  p.scene = buildJobScene(job, assets, use);
  if (o.parameters_size() == 0) fail("parameters", "list at least one parameter to recover");
  // Russian roulette: by throughput (default) or fixed survival per bounce.
  {
    const auto& r = job.render();
    bool namesSurvival = false;
    for (const auto& ps : o.parameters()) namesSurvival = namesSurvival || ps.name() == "sampling/rr_survival";
    const std::string mode = r.russian_roulette().empty() ? (namesSurvival ? "fixed" : "throughput") : r.russian_roulette();
    if (mode != "throughput" && mode != "fixed")
      throw InputError("render.russian_roulette: unknown mode '" + mode + "' (use throughput or fixed)");
    if (mode == "throughput" && r.survival_size() > 0) throw InputError("render.survival: needs render.russian_roulette \"fixed\"");
    if (mode == "throughput" && namesSurvival)
      throw InputError("render.russian_roulette: sampling/rr_survival needs \"fixed\" survival (or leave the mode unset)");
    if (mode == "fixed") {
      const int bounces = std::max(1, o.max_depth());
      if (r.survival_size() > bounces)
        throw InputError("render.survival: " + std::to_string(r.survival_size()) + " values for " + std::to_string(bounces) + " bounces (max_depth)");
      std::vector<float> q(size_t(bounces), 1.f);
      for (int k = 0; k < bounces; ++k) {
        if (r.survival_size() == 0) break;
        double v = r.survival(std::min(k, r.survival_size() - 1));
        if (!(v > 0 && v <= 1)) throw InputError("render.survival[" + std::to_string(std::min(k, r.survival_size() - 1)) + "]: must be in (0, 1]");
        q[size_t(k)] = float(v);
      }
      p.scene->sampling.survival = std::move(q);
    }
  }
  for (int i = 0; i < o.parameters_size(); ++i) {
    const auto& ps = o.parameters(i);
    std::string field = "parameters[" + std::to_string(i) + "]";
    ParameterOptions po;
    auto finite = [&](const char* name, double v) {
      if (!std::isfinite(v)) fail(field + "." + name, "must be a finite number (got " + std::to_string(v) + ")");
      return float(v);
    };
    if (ps.has_learning_rate()) po.learningRate = finite("learning_rate", ps.learning_rate());
    if (ps.has_lower()) po.lower = finite("lower", ps.lower());
    if (ps.has_upper()) po.upper = finite("upper", ps.upper());
    if (ps.has_large_steps_lambda()) {
      po.largeStepsLambda = finite("large_steps_lambda", ps.large_steps_lambda());
      if (*po.largeStepsLambda < 0.f) fail(field + ".large_steps_lambda", "must be >= 0 (got " + std::to_string(ps.large_steps_lambda()) + ")");
    }
    if (ps.map_resolution_size() > 0) {
      if (ps.name().rfind("sampling/pixel_light_logits/", 0) != 0) fail(field + ".map_resolution", "only for sampling/pixel_light_logits/<view>");
      if (ps.map_resolution_size() != 2) fail(field + ".map_resolution", "needs [width, height]");
      po.mapWidth = ps.map_resolution(0);
      po.mapHeight = ps.map_resolution(1);
      if (po.mapWidth <= 0 || po.mapHeight <= 0) fail(field + ".map_resolution", "must be positive");
    }
    // A start mesh replaces the shape's geometry before its vertices are registered (the
    // parameter has the start mesh's vertices); the shape's own mesh stays the truth.
    std::optional<Problem::TruthMesh> replaced;
    if (ps.has_initial_mesh()) {
      std::string invrName;
      try {
        invrName = invrParameterName(*p.scene, ps.name());
      } catch (const InputError& e) {
        fail(field + ".name", e.what());
      }
      const std::string prefix = "shapes/", suffix = "/vertices";
      if (invrName.rfind(prefix, 0) != 0 || invrName.size() <= prefix.size() + suffix.size() ||
          invrName.compare(invrName.size() - suffix.size(), suffix.size(), suffix) != 0)
        fail(field + ".initial_mesh", "a start mesh is for vertex parameters (shapes/<name>/vertices), not '" + ps.name() + "'");
      const std::string shape = invrName.substr(prefix.size(), invrName.size() - prefix.size() - suffix.size());
      const v1::Scene spec = jobSceneSpec(job);
      const v1::Shape* shapeSpec = nullptr;
      for (const auto& s : spec.shapes())
        if (s.name() == shape) shapeSpec = &s;
      uint32_t mesh = 0;
      while (mesh < p.scene->meshNames.size() && p.scene->meshNames[mesh] != shape) ++mesh;
      if (!shapeSpec || mesh >= p.scene->meshNames.size()) fail(field + ".name", "parameter '" + ps.name() + "': no shape named '" + shape + "'");
      if (p.scene->meshLight[mesh] >= 0) fail(field + ".name", "parameter '" + ps.name() + "': shape '" + shape + "' emits light");
      if (p.params.moves(mesh)) fail(field + ".initial_mesh", "shape '" + shape + "' is already moved by another parameter");
      replaced = Problem::TruthMesh{0, mesh, p.scene->meshes[mesh], 0.0, true, nullptr};
      p.scene->replaceMesh(mesh, startMesh(ps.initial_mesh(), *shapeSpec, p.scene->meshes[mesh], assets, "optimization." + field + ".initial_mesh"));
    }
    try {
      p.params.add(*p.scene, ps.name(), po);
    } catch (const InputError& e) {
      fail(field + ".name", e.what());
    }
    const ParameterSlot& added = p.params.slots().back();
    if (added.kind->isMesh()) {
      Problem::TruthMesh t = replaced ? *replaced : Problem::TruthMesh{0, uint32_t(added.shape), p.scene->meshes[size_t(added.shape)], 0.0, false, nullptr};
      t.slot = p.params.slots().size() - 1;
      t.diagonal = boundingBoxDiagonal(t.geometry);
      t.distance = std::make_shared<const SurfaceDistance>(t.geometry);
      p.truthMeshes.push_back(std::move(t));
    }
  }
  p.truth = p.params.read(*p.scene);
  p.initial = p.truth;
  if (o.method() == v1::METHOD_RESTIR || o.method() == v1::METHOD_UNSPECIFIED)
    for (int i = 0; i < o.parameters_size(); ++i) {
      const ParameterSlot& s = p.params.slots()[size_t(i)];
      if (s.kind->zeroBiasesReuse() && !(s.lower > 0.f))
        fail("parameters[" + std::to_string(i) + "].lower",
             "must be above 0 with method METHOD_RESTIR (default " + std::to_string(kPositiveFloor) +
             "): a value at 0 changes which light samples reused reservoirs could have produced, and ReSTIR's "
             "normalisation would count them wrongly (a biased gradient)");
    }
  for (int i = 0; i < o.parameters_size(); ++i) {
    const auto& ps = o.parameters(i);
    const ParameterSlot& s = p.params.slots()[size_t(i)];
    const std::string field = "parameters[" + std::to_string(i) + "]";
    auto inBounds = [&](const std::string& f, double v) {
      if (!std::isfinite(v)) fail(f, "must be a finite number (got " + std::to_string(v) + ")");
      if (v < s.lower || v > s.upper)
        fail(f, "outside the bounds [" + std::to_string(s.lower) + ", " + std::to_string(s.upper) + "] (got " + std::to_string(v) + ")");
      return float(v);
    };
    if (ps.has_initial() && ps.initial_values_size() > 0) fail(field, "set either initial or initial_values, not both");
    if (s.kind->isMesh() && (ps.has_initial() || (ps.initial_values_size() > 0 && uint32_t(ps.initial_values_size()) != s.size)))
      fail(field + (ps.has_initial() ? ".initial" : ".initial_values"),
           "would put every vertex of '" + ps.name() + "' at one point; start from another mesh with initial_mesh, or give every coordinate (" +
               std::to_string(s.size) + " values)");
    if (ps.has_initial()) std::fill(p.initial.begin() + s.offset, p.initial.begin() + s.offset + s.size, inBounds(field + ".initial", ps.initial()));
    if (const int nt = ps.truth_values_size(); nt > 0) {
      const std::string tf = field + ".truth_values";
      if (o.targets_size() > 0) fail(tf, "the job's targets are uploaded images, whose truth is unknown: remove truth_values or the targets");
      if (s.kind->changesNoiseOnly())
        fail(tf, "'" + s.name + "' changes the noise, never the image: it has no truth");
      if (s.kind->isMesh()) fail(tf, "the truth of '" + s.name + "' is the shape's own mesh (start elsewhere with initial_mesh)");
      if (nt != 1 && nt != s.channels && uint32_t(nt) != s.size)
        fail(tf, "has " + std::to_string(nt) + " values; '" + s.name + "' takes 1, " + std::to_string(s.channels) + " (one per channel)" +
                     (s.size != uint32_t(s.channels) ? " or " + std::to_string(s.size) + " (one per texel and channel)" : ""));
      for (uint32_t k = 0; k < s.size; ++k) {
        const int j = nt == 1 ? 0 : uint32_t(nt) == s.size ? int(k) : int(k % uint32_t(s.channels));
        const double v = ps.truth_values(j);
        if (!std::isfinite(v)) fail(tf + "[" + std::to_string(j) + "]", "must be a finite number");
        p.truth[s.offset + k] = float(v);
      }
    }
    const int n = ps.initial_values_size();
    if (n == 0) continue;
    if (n != 1 && n != s.channels && uint32_t(n) != s.size)
      fail(field + ".initial_values",
           "has " + std::to_string(n) + " values; '" + s.name + "' takes 1, " + std::to_string(s.channels) + " (one per channel)" +
               (s.size != uint32_t(s.channels) ? " or " + std::to_string(s.size) + " (one per texel and channel)" : ""));
    for (uint32_t k = 0; k < s.size; ++k) {
      int j = n == 1 ? 0 : uint32_t(n) == s.size ? int(k) : int(k % uint32_t(s.channels));
      p.initial[s.offset + k] = inBounds(field + ".initial_values[" + std::to_string(j) + "]", ps.initial_values(j));
    }
  }
  // The scene's own values (the default start) may lie outside the default bounds (a black texel
  // under the positive floor): start inside them.
  p.params.clampToBounds(p.initial);
  // The gradient's options, each family's parsed beside its code (interior estimators, pixel
  // samplers, the variance pass, boundary terms).
  p.gradient = parseGradientOptions(o, p.scene->width, p.scene->height);
  if (job.render().max_depth() != 0 && job.render().max_depth() != p.gradient.maxDepth)
    throw InputError("render.max_depth (" + std::to_string(job.render().max_depth()) + ") and optimization.max_depth (" +
                     std::to_string(p.gradient.maxDepth) + (o.max_depth() == 0 ? ", the default" : "") +
                     ") disagree: targets, gradients and final renders share one light transport, set by "
                     "optimization.max_depth; remove render.max_depth or make the two equal");
  if (!job.render().sampler().empty() && samplerKindFromName(job.render().sampler(), "render.sampler") != p.gradient.sampler)
    throw InputError(std::string("render.sampler (") + job.render().sampler() + ") and optimization.sampler (" +
                     samplerKindName(p.gradient.sampler) + (o.sampler().empty() ? ", the default" : "") +
                     ") disagree: every render and pass of an optimisation job uses optimization.sampler; remove "
                     "render.sampler or make the two equal");
  try {
    p.optimizer = o.optimizer().empty() ? p.optimizer : optimizerKindFromName(o.optimizer());
  } catch (const InputError& e) {
    fail("optimizer", e.what());
  }
  if (p.optimizer == OptimizerKind::AdamUniform)
    for (size_t i = 0; i < p.params.slots().size(); ++i)
      if (p.params.slots()[i].size == 1)
        fail("optimizer", "adam_uniform scales each parameter's steps by the largest second moment over its values; parameters[" + std::to_string(i) +
                              "] ('" + p.params.slots()[i].name + "') has one value, where that is plain Adam: use adam");
  if (!(o.learning_rate_half_life() >= 0.0) || !std::isfinite(o.learning_rate_half_life()))
    fail("learning_rate_half_life", "must be a finite number of steps >= 0 (0: constant learning rates)");
  p.schedule.halfLifeSteps = o.learning_rate_half_life();
  auto positive = [&](const char* field, int v, int dflt, int max) {
    if (v < 0 || v > max) fail(field, "must be in 1.." + std::to_string(max) + " (got " + std::to_string(v) + ")");
    return v == 0 ? dflt : v;
  };
  if (o.has_steps() && (o.steps() < 1 || o.steps() > 1000000))
    fail("steps", "must be in 1..1000000 (got " + std::to_string(o.steps()) + ")");
  p.steps = o.has_steps() ? o.steps() : p.steps;
  if (o.restir().burn_in() < 0 || o.restir().burn_in() > 10000) fail("restir.burn_in", "must be in 0..10000");
  p.burnIn = p.gradient.method == GradientMethod::Restir ? o.restir().burn_in() : 0;
  int views = int(p.scene->cameras.size());
  if (o.views_per_step() < 0 || o.views_per_step() > views)
    fail("views_per_step", "must be in 1.." + std::to_string(views) + " (the scene has " + std::to_string(views) + " views)");
  p.viewsPerStep = o.views_per_step() == 0 ? views : o.views_per_step();
  p.targetSpp = positive("target_spp", o.target_spp(), p.targetSpp, 1 << 16);
  p.seed = o.seed();
  if (o.snapshot_every() < 0) fail("snapshot_every", "must be 0 (no snapshots) or a number of steps (got " + std::to_string(o.snapshot_every()) + ")");
  // Each snapshot adds files to the job's result list, which every status answer carries.
  constexpr int kMaxSnapshots = 1000;
  if (o.snapshot_every() > 0 && p.steps / o.snapshot_every() > kMaxSnapshots)
    fail("snapshot_every", "at most " + std::to_string(kMaxSnapshots) + " snapshots per job: with " + std::to_string(p.steps) +
                               " steps, snapshot every " + std::to_string((p.steps + kMaxSnapshots - 1) / kMaxSnapshots) +
                               " steps or more (got " + std::to_string(o.snapshot_every()) + ")");
  if (p.scene->width * p.scene->height <= 0) fail("scene", "empty film");
  if (o.shards() < 0 || o.shards() > views)
    fail("shards", "must be in 1.." + std::to_string(views) + " (one view per shard at most; got " + std::to_string(o.shards()) + ")");
  int shards = o.shards() > 0 ? o.shards() : std::min(views, 4);
  p.shards.resize(size_t(shards));
  for (int v = 0; v < views; ++v) p.shards[size_t(v * shards / views)].push_back(v);  // contiguous blocks
  if (o.targets_size() > 0) {
    if (o.targets_size() != views)
      fail("targets", "needs one image per view: the scene has " + std::to_string(views) + ", the job gives " + std::to_string(o.targets_size()));
    for (int v = 0; v < views; ++v) {
      Image im = readViewImage(o.targets(v), "optimization.targets[" + std::to_string(v) + "]", true, assets, *p.scene);
      if (im.channels() != 3) {  // grey or RGBA: the loss compares RGB
        Image rgb(im.width(), im.height(), 3);
        for (int y = 0; y < im.height(); ++y)
          for (int x = 0; x < im.width(); ++x) rgb.setRgb(x, y, im.rgb(x, y));
        im = std::move(rgb);
      }
      for (float x : im.data())
        if (!std::isfinite(x)) fail("targets[" + std::to_string(v) + "]", "has non-finite pixels");
      p.givenTargets.push_back(std::move(im));
    }
  }
  // Combinations the gradients cannot deliver, now that the scene, parameters and options stand.
  validateGradientJob(*p.scene, p.params, p.gradient);
  if (o.target_masks_size() > 0) {
    if (o.targets_size() == 0) fail("target_masks", "masks need targets (rendered targets have nothing to mask)");
    if (o.target_masks_size() != o.targets_size())
      fail("target_masks", "needs one entry per target (" + std::to_string(o.targets_size()) + "), got " + std::to_string(o.target_masks_size()) +
                               "; use {} for a view without a mask");
    p.gradient.lossMasks.resize(size_t(views));
    for (int v = 0; v < views; ++v) {
      const auto& ref = o.target_masks(v);
      if (ref.source_case() == v1::AssetRef::SOURCE_NOT_SET) continue;
      Image im = readViewImage(ref, "optimization.target_masks[" + std::to_string(v) + "]", false, assets, *p.scene);
      std::vector<float> w(size_t(im.width()) * size_t(im.height()));
      double sum = 0;
      const int c = im.channels() == 2 ? 1 : std::min(im.channels(), 3);  // grey+alpha or RGBA: alpha is not part of the weight
      for (int y = 0; y < im.height(); ++y)
        for (int x = 0; x < im.width(); ++x) {
          double m = 0;
          for (int k = 0; k < c; ++k) m += im.at(x, y, k);
          m /= c;
          if (!(m >= -1e-6 && m <= 1 + 1e-6))
            fail("target_masks[" + std::to_string(v) + "]", "pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") is " + std::to_string(m) +
                 "; mask values must be in [0, 1]");
          w[size_t(y) * size_t(im.width()) + size_t(x)] = float(std::clamp(m, 0.0, 1.0));
          sum += std::clamp(m, 0.0, 1.0);
        }
      if (!(sum > 0)) fail("target_masks[" + std::to_string(v) + "]", "excludes every pixel");
      const double norm = double(w.size()) / sum;  // mean 1: the loss is the mean over what the mask keeps
      for (float& x : w) x = float(x * norm);
      p.gradient.lossMasks[size_t(v)] = std::move(w);
    }
  }
  return p;
}

RenderOptions transportRenderOptions(const Problem& p, int spp, StreamId stream) {
  // Targets set the floor of every reconstruction (the optimum fits their noise), so use the
  // lowest-variance estimator we have: visibility-aware RIS with 16 candidates.
  RenderOptions ro;
  ro.spp = spp;
  ro.russianRouletteDepth = p.gradient.russianRouletteDepth;
  ro.maxDepth = 1;
  ro.estimator = LightEstimator::Ris;
  ro.risCandidates = 16;
  ro.risVisibilityInTarget = true;
  if (p.gradient.maxDepth > 1) {  // the same light transport as the gradients: NEE + MIS paths
    ro.maxDepth = p.gradient.maxDepth;
    ro.estimator = LightEstimator::NeeMis;
  }
  ro.seed = streamSeed(p.seed, stream);
  ro.sampler = p.gradient.sampler;
  return ro;
}

RenderOptions targetRenderOptions(const Problem& p) { return transportRenderOptions(p, p.targetSpp, kTargetStream); }

Image renderTarget(Problem& p, int view, const std::atomic<bool>* cancel) {
  if (!p.givenTargets.empty()) return p.givenTargets.at(size_t(view));
  p.params.write(p.truth, *p.scene);
  // Shapes started from another mesh: the truth's own geometry for the render, then back.
  struct TruthGeometry {
    Problem& p;
    std::vector<std::pair<uint32_t, TriangleMesh>> held;
    explicit TruthGeometry(Problem& problem) : p(problem) {
      for (const auto& t : p.truthMeshes)
        if (t.replaced) {
          held.emplace_back(t.mesh, p.scene->meshes[t.mesh]);
          p.scene->replaceMesh(t.mesh, t.geometry);
        }
    }
    ~TruthGeometry() {
      for (auto& [m, geometry] : held) p.scene->replaceMesh(m, std::move(geometry));
    }
  } truthGeometry(p);
  RenderOptions ro = targetRenderOptions(p);
  ro.cancel = cancel;
  return renderView(*p.scene, view, ro).image;
}

double shapeError(const Problem& p, const std::vector<float>& theta) {
  if (!p.groundTruthKnown() || p.truthMeshes.empty()) return -1.0;
  double sum = 0;
  for (const auto& t : p.truthMeshes) {
    const ParameterSlot& s = p.params.slots()[t.slot];
    const TriangleMesh now = p.params.vertexMesh(*p.scene, s, theta.data() + s.offset);
    sum += t.distance->symmetricChamferTo(now) / std::max(t.diagonal, 1e-30);
  }
  return sum / double(p.truthMeshes.size());
}

std::vector<Image> renderTargets(Problem& p) {
  std::vector<Image> targets;
  for (size_t v = 0; v < p.scene->cameras.size(); ++v) targets.push_back(renderTarget(p, int(v)));
  return targets;
}

Evaluation evaluationAt(const Problem& p, uint64_t counter) {
  Evaluation e;
  e.counter = counter;
  e.renderOnly = counter < uint64_t(p.burnIn);
  e.views = viewsForStep(p, counter);
  return e;
}

GradientRequest shardRequest(const Problem& p, const Evaluation& e, size_t shard) {
  GradientRequest r;
  const auto& mine = p.shards.at(shard);
  for (int v : e.views)
    if (std::binary_search(mine.begin(), mine.end(), v)) r.views.push_back(v);
  r.step = e.counter;
  r.seed = p.seed;
  r.renderOnly = e.renderOnly;
  r.batchViews = int(e.views.size());
  r.allSessionViews = r.views.size() == mine.size();
  return r;
}

double parameterError(const Problem& p, const std::vector<float>& theta) {
  // Sampling parameters change the noise, never the mean: they have no ground truth.
  double sum = 0;
  size_t n = 0;
  for (size_t k = 0; k < p.params.slots().size(); ++k) {
    const ParameterSlot& s = p.params.slots()[k];
    if (s.kind->changesNoiseOnly()) continue;
    bool startedElsewhere = false;  // its truth has other vertices: shapeError measures it
    for (const auto& t : p.truthMeshes) startedElsewhere = startedElsewhere || (t.slot == k && t.replaced);
    if (startedElsewhere) continue;
    for (size_t i = s.offset; i < s.offset + s.size; ++i) sum += double(theta[i] - p.truth[i]) * double(theta[i] - p.truth[i]);
    n += s.size;
  }
  if (n == 0) return -1.0;
  return std::sqrt(sum / double(n));
}

std::vector<int> viewsForStep(const Problem& p, uint64_t step) {
  int n = int(p.scene->cameras.size());
  std::vector<int> all(static_cast<size_t>(n));
  std::iota(all.begin(), all.end(), 0);
  if (p.viewsPerStep >= n) return all;
  // Fisher-Yates with counter-based randomness: the batch depends only on (seed, step).
  Sampler s(RngKey{streamSeed(p.seed, kViewBatchStream), step, 0, 0, 0});
  for (int i = n - 1; i > 0; --i) std::swap(all[size_t(i)], all[size_t(s.nextBits() % uint64_t(i + 1))]);
  all.resize(size_t(p.viewsPerStep));
  std::sort(all.begin(), all.end());
  return all;
}

}  // namespace invr
