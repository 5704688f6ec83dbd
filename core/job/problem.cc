#include "core/job/problem.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/diff/gradient_engine.h"
#include "core/error.h"
#include "core/image/image.h"
#include "core/render/renderer.h"

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
    if (ps.map_resolution_size() > 0) {
      if (ps.name().rfind("sampling/pixel_light_logits/", 0) != 0) fail(field + ".map_resolution", "only for sampling/pixel_light_logits/<view>");
      if (ps.map_resolution_size() != 2) fail(field + ".map_resolution", "needs [width, height]");
      po.mapWidth = ps.map_resolution(0);
      po.mapHeight = ps.map_resolution(1);
      if (po.mapWidth <= 0 || po.mapHeight <= 0) fail(field + ".map_resolution", "must be positive");
    }
    try {
      p.params.add(*p.scene, ps.name(), po);
    } catch (const InputError& e) {
      fail(field + ".name", e.what());
    }
  }
  p.truth = p.params.read(*p.scene);
  p.initial = p.truth;
  if (o.method() == v1::METHOD_RESTIR || o.method() == v1::METHOD_UNSPECIFIED)
    for (int i = 0; i < o.parameters_size(); ++i) {
      const ParameterSlot& s = p.params.slots()[size_t(i)];
      if ((s.kind == ParamKind::Albedo || s.kind == ParamKind::LightIntensity) && !(s.lower > 0.f))
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
    if (ps.has_initial()) std::fill(p.initial.begin() + s.offset, p.initial.begin() + s.offset + s.size, inBounds(field + ".initial", ps.initial()));
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
  switch (o.method()) {
    case v1::METHOD_PT: p.gradient.method = GradientMethod::Pt; break;
    case v1::METHOD_RIS: p.gradient.method = GradientMethod::Ris; break;
    default: p.gradient.method = GradientMethod::Restir; break;
  }
  try {
    p.gradient.loss = lossKindFromName(o.loss().empty() ? "l2" : o.loss());
  } catch (const InputError& e) {
    fail("loss", e.what());
  }
  try {
    p.optimizer = optimizerKindFromName(o.optimizer().empty() ? "adam" : o.optimizer());
  } catch (const InputError& e) {
    fail("optimizer", e.what());
  }
  if (!(o.learning_rate_half_life() >= 0.0) || !std::isfinite(o.learning_rate_half_life()))
    fail("learning_rate_half_life", "must be a finite number of steps >= 0 (0: constant learning rates)");
  p.schedule.halfLifeSteps = o.learning_rate_half_life();
  auto positive = [&](const char* field, int v, int dflt, int max) {
    if (v < 0 || v > max) fail(field, "must be in 1.." + std::to_string(max) + " (got " + std::to_string(v) + ")");
    return v == 0 ? dflt : v;
  };
  if (o.has_steps() && (o.steps() < 1 || o.steps() > 1000000))
    fail("steps", "must be in 1..1000000 (got " + std::to_string(o.steps()) + ")");
  p.steps = o.has_steps() ? o.steps() : 100;
  p.gradient.sppPrimal = positive("spp_primal", o.spp_primal(), 1, 4096);
  p.gradient.sppGradient = positive("spp_gradient", o.spp_gradient(), 1, 4096);
  p.gradient.restir.candidates = positive("ris_candidates", o.ris_candidates(), 8, 4096);
  p.gradient.restir.visibilityInTarget = !o.ris_target_without_visibility();
  const auto& r = o.restir();
  p.gradient.restir.neighbours = positive("restir.neighbours", r.neighbours(), 1, 32);
  if (r.radius_pixels() < 0 || r.radius_pixels() > 1000) fail("restir.radius_pixels", "must be in (0, 1000]");
  p.gradient.radiusPixels = r.radius_pixels() > 0 ? float(r.radius_pixels()) : 3.f;
  if (r.normal_threshold() < -1 || r.normal_threshold() > 1) fail("restir.normal_threshold", "must be in [-1, 1]");
  p.gradient.restir.normalDot = r.normal_threshold() != 0 ? float(r.normal_threshold()) : 0.9f;
  if (r.m_cap() < 0 || !std::isfinite(r.m_cap())) fail("restir.m_cap", "must be a positive number");
  // While parameters change, old reservoirs go stale and a lucky high-weight sample can dominate
  // its neighbours for many steps; a short memory and one neighbour fix both. Measured
  // on oxalis over 150 Adam steps: cap 160 / 4 neighbours 13 loss spikes, parameter RMSE 0.098;
  // cap 32 / 2: 3 spikes, 0.031; cap 16 / 1: 2 spikes, 0.027; cap 8 / 1: 0 spikes, 0.025.
  p.gradient.restir.mCap = r.m_cap() > 0 ? float(r.m_cap()) : 2.f * float(p.gradient.restir.candidates);
  if (r.burn_in() < 0 || r.burn_in() > 10000) fail("restir.burn_in", "must be in 0..10000");
  p.burnIn = p.gradient.method == GradientMethod::Restir ? r.burn_in() : 0;
  p.gradient.forwardOnly = r.forward_only();
  p.gradient.preserveOccluded = !r.discard_occluded();
  if (o.max_depth() < 0 || o.max_depth() > 64) fail("max_depth", "must be in 1..64 (got " + std::to_string(o.max_depth()) + ")");
  p.gradient.maxDepth = std::max(1, o.max_depth());
  if (job.render().max_depth() != 0 && job.render().max_depth() != p.gradient.maxDepth)
    throw InputError("render.max_depth (" + std::to_string(job.render().max_depth()) + ") and optimization.max_depth (" +
                     std::to_string(p.gradient.maxDepth) + (o.max_depth() == 0 ? ", the default" : "") +
                     ") disagree: targets, gradients and final renders share one light transport, set by "
                     "optimization.max_depth; remove render.max_depth or make the two equal");
  if (p.gradient.maxDepth > 1 && p.gradient.method != GradientMethod::Pt)
    fail("max_depth", "paths longer than direct illumination are differentiated by path replay with NEE + MIS at every vertex: set method METHOD_PT");
  try {
    p.gradient.pixels.sampler = pixelSamplerFromName(o.pixel_sampler().empty() ? "all" : o.pixel_sampler());
  } catch (const InputError& e) {
    fail("pixel_sampler", e.what());
  }
  const int filmPixels = p.scene->width * p.scene->height;
  if (o.pixel_samples() < 0 || o.pixel_samples() > 16 * filmPixels)
    fail("pixel_samples", "must be in 1.." + std::to_string(16 * filmPixels) + " (got " + std::to_string(o.pixel_samples()) + ")");
  p.gradient.pixels.samplesPerView = o.pixel_samples();
  if (!(o.pixel_defensive() >= 0 && o.pixel_defensive() <= 1))
    fail("pixel_defensive", "must be in (0, 1]: every pixel needs a probability above zero");
  p.gradient.pixels.defensive = o.pixel_defensive() > 0 ? float(o.pixel_defensive()) : 0.2f;
  p.gradient.pixels.refreshEvery = positive("pixel_refresh", o.pixel_refresh(), 20, 100000);
  int views = int(p.scene->cameras.size());
  if (o.views_per_step() < 0 || o.views_per_step() > views)
    fail("views_per_step", "must be in 1.." + std::to_string(views) + " (the scene has " + std::to_string(views) + " views)");
  p.viewsPerStep = o.views_per_step() == 0 ? views : o.views_per_step();
  p.targetSpp = positive("target_spp", o.target_spp(), 256, 1 << 16);
  p.seed = o.seed();
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
  if (o.has_variance()) {
    const auto& v = o.variance();
    VarianceOptions& vo = p.gradient.variance;
    vo.enabled = true;
    if (v.has_weight() && !(std::isfinite(v.weight()) && v.weight() >= 0)) fail("variance.weight", "must be a finite number >= 0");
    vo.weight = v.has_weight() ? v.weight() : 1.0;
    if (!(std::isfinite(v.samples()) && v.samples() >= 0)) fail("variance.samples", "must be a positive number (K, samples per pixel)");
    vo.samples = v.samples() > 0 ? v.samples() : 1.0;
    if (v.estimator() != "" && v.estimator() != "unbiased" && v.estimator() != "detached")
      fail("variance.estimator", "unknown estimator '" + v.estimator() + "' (use unbiased or detached)");
    vo.detached = v.estimator() == "detached";
    vo.spp = positive("variance.spp", v.spp(), 1, 4096);
    if (v.cost_model() != "" && v.cost_model() != "none" && v.cost_model() != "depth")
      fail("variance.cost_model", "unknown cost model '" + v.cost_model() + "' (use none or depth)");
    vo.cost = v.cost_model() == "depth" ? VarianceCost::Depth : VarianceCost::None;
    if (vo.cost == VarianceCost::Depth && v.samples() != 0)
      fail("variance.samples", "has no meaning with cost_model depth: the loss is bias + weight * t * V (Eq. 33); leave samples unset");
    if (p.gradient.method != GradientMethod::Pt)
      fail("variance", "needs method METHOD_PT: RIS and ReSTIR resampling have no variance derivatives yet");
    if (p.gradient.pixels.sampler != PixelSampler::All && p.gradient.pixels.sampler != PixelSampler::Uniform)
      fail("variance", "works with pixel_sampler all or uniform only");
  }
  if (o.has_boundary()) {
    const auto& b = o.boundary();
    if (b.samples() < 0 || b.samples() > (1 << 24)) fail("boundary.samples", "must be in 1..16777216 (0: the default)");
    if (b.light_points() < 0 || b.light_points() > 4096) fail("boundary.light_points", "must be in 1..4096 (0: the default 16)");
    BoundaryOptions& bo = p.gradient.boundary;
    bo.samples = b.samples();
    bo.lightPoints = b.light_points() > 0 ? b.light_points() : 16;
    bo.primary = !b.has_primary() || b.primary();
    bo.secondary = !b.has_secondary() || b.secondary();
    bo.multiViewShortcut = b.multi_view_shortcut();
    bo.areaSampling = b.area_sampling() == v1::AREA_SAMPLING_LIGHT_POINTS ? BoundaryOptions::AreaSampling::LightPoints
                                                                         : BoundaryOptions::AreaSampling::EdgeFirst;
    bo.edgeImportance = !b.has_edge_importance() || b.edge_importance();
    if (b.edge_neighbours() < 0 || b.edge_neighbours() > 8) fail("boundary.edge_neighbours", "must be in 0..8 (0, the default: none)");
    bo.edgeNeighbours = b.edge_neighbours();
  }
  try {
    checkShapeJob(*p.scene, p.params, p.gradient);
  } catch (const InputError& e) {
    fail("parameters", e.what());
  }
  if (p.params.hasSamplingParameters() && p.gradient.method != GradientMethod::Pt)
    fail("parameters", "sampling parameters (sampling/...) need method METHOD_PT");
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
  return ro;
}

RenderOptions targetRenderOptions(const Problem& p) { return transportRenderOptions(p, p.targetSpp, kTargetStream); }

Image renderTarget(Problem& p, int view, const std::atomic<bool>* cancel) {
  if (!p.givenTargets.empty()) return p.givenTargets.at(size_t(view));
  p.params.write(p.truth, *p.scene);
  RenderOptions ro = targetRenderOptions(p);
  ro.cancel = cancel;
  return renderView(*p.scene, view, ro).image;
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
  for (const ParameterSlot& s : p.params.slots()) {
    if (s.kind == ParamKind::LightLogits || s.kind == ParamKind::PixelLightLogits || s.kind == ParamKind::Survival) continue;
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
