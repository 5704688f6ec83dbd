#include "core/diff/gradient_engine.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <chrono>
#include <optional>

#include "core/diff/area_shadow_boundary.h"
#include "core/diff/edge_reservoir_boundary.h"
#include "core/diff/delta_shadow_boundary.h"
#include "core/diff/environment_shadow_boundary.h"
#include "core/diff/pass_driver.h"
#include "core/diff/primary_boundary.h"
#include "core/diff/render_cost.h"
#include "core/error.h"
#include "core/render/path_walk.h"
#include "core/render/renderer.h"

namespace invr {

GradientMethod gradientMethodFromName(const std::string& name) {
  if (name == "pt") return GradientMethod::Pt;
  if (name == "ris") return GradientMethod::Ris;
  if (name == "restir") return GradientMethod::Restir;
  throw InputError("unknown method '" + name + "' (use pt, ris or restir)");
}

const char* gradientMethodName(GradientMethod m) {
  return m == GradientMethod::Pt ? "pt" : m == GradientMethod::Ris ? "ris" : "restir";
}

namespace {

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The estimator a pass uses: the job's method, except that "forward only" ReSTIR samples its
// derivative pass with plain RIS, and that stage 1 leaves the reservoir chains alone.
std::unique_ptr<InteriorEstimator> estimatorFor(const GradientOptions& o, const EstimatorSetup& setup, bool reuse) {
  switch (o.method) {
    case GradientMethod::Pt: return makePtEstimator(setup);
    case GradientMethod::Ris: return makeRisEstimator(setup);
    default: return reuse ? makeRestirEstimator(setup) : makeRisEstimator(setup);
  }
}

}  // namespace

void checkShapeJob(const Scene& scene, const ParameterRegistry& params, const GradientOptions& o) {
  if (!params.hasShapeParameters()) return;
  const std::string what = "shape parameters: ";
  if (o.maxDepth != 1)
    throw InputError(what + "the interior shape derivative covers direct illumination only; set max_depth 1");
  if (o.pixels.sampler != PixelSampler::All)
    throw InputError(what + "the boundary terms need dLoss/dI at every pixel; use pixel_sampler all");
  if (o.variance.enabled) throw InputError(what + "variance-aware losses have no shape derivatives yet");
  for (uint32_t m : params.movingMeshes()) {
    const Material& mat = scene.materials[size_t(scene.meshMaterial[m])];
    if (mat.kind != BsdfKind::Diffuse || !mat.albedo.isConstant())
      throw InputError(what + "shape '" + scene.meshNames[m] + "' has material '" + mat.name +
                       "': the interior shape derivative covers diffuse, untextured materials only");
    // Measured: a smooth sphere moving sideways came out 5.6 % low against finite differences
    // (8 SE), all of it next to the silhouette; the same sphere filling the view agreed.
    if (!scene.meshes[m].normals.empty())
      throw InputError(what + "shape '" + scene.meshNames[m] +
                       "' has interpolated vertex normals: next to its silhouette the shading normal turns away from the camera "
                       "inside faces and the radiance jumps there, a moving discontinuity no boundary estimator samples yet; "
                       "flat-shade it (the shape's face_normals: true)");
  }
}

bool visibleFromCamera(const Scene& scene, const Camera& cam, Vec3 p, Vec3 n) {
  float px, py;
  if (!cam.project(p, scene.width, scene.height, px, py)) return false;
  Vec3 o = offsetOrigin(p, n, cam.eye - p);
  Vec3 dir;
  float tmax;
  return !scene.occludedSegment(o, cam.eye, dir, tmax);
}

GradientEngine::GradientEngine(const Scene& scene, const ParameterRegistry& params, std::vector<Image> targets, GradientOptions options)
    : scene_(scene), params_(params), targets_(std::move(targets)), opt_(options),
      scratch_(std::make_unique<GradientScratchPool>(params.size())) {
  if (!scene.accelerated()) throw std::logic_error("GradientEngine: the scene was built for validation only (no BVH)");
  if (opt_.sppPrimal <= 0 || opt_.sppGradient <= 0) throw InputError("spp_primal and spp_gradient must be positive");
  if (opt_.restir.candidates <= 0) throw InputError("ris_candidates must be positive");
  if (!(opt_.radiusPixels > 0.f)) throw InputError("restir radius_pixels must be positive");
  if (opt_.maxDepth < 1 || opt_.maxDepth > kMaxWalkDepth) throw InputError("max_depth must be in 1.." + std::to_string(kMaxWalkDepth));
  if (opt_.maxDepth > 1 && opt_.method != GradientMethod::Pt)
    throw InputError("max_depth > 1 (multi-bounce paths) needs method pt: NEE + MIS at every vertex");
  if (opt_.variance.enabled) {
    if (opt_.method != GradientMethod::Pt)
      throw InputError("variance needs method pt: RIS and ReSTIR resampling have no variance derivatives yet");
    if (opt_.pixels.sampler != PixelSampler::All && opt_.pixels.sampler != PixelSampler::Uniform)
      throw InputError("variance works with pixel_sampler all or uniform only");
    if (opt_.variance.spp <= 0) throw InputError("variance spp must be positive");
    if (!(opt_.variance.samples > 0) || !std::isfinite(opt_.variance.samples)) throw InputError("variance K (samples) must be positive");
    if (!(opt_.variance.weight >= 0) || !std::isfinite(opt_.variance.weight)) throw InputError("variance weight must be >= 0");
  }
  if (params.hasSamplingParameters() && opt_.method != GradientMethod::Pt)
    throw InputError("sampling parameters (sampling/...) need method pt");
  for (const auto& m : opt_.lossMasks)
    if (!m.empty() && m.size() != size_t(scene.width) * size_t(scene.height)) throw InputError("a target mask does not match the film's size");
  checkShapeJob(scene, params, opt_);
  if (opt_.boundary.samples < 0 || opt_.boundary.lightPoints < 1) throw InputError("boundary samples must be >= 0 and light_points >= 1");
  // Occluders need not move to cast a moving shadow (a moving receiver drags it): every mesh.
  if (params.hasShapeParameters())
    for (const TriangleMesh& m : scene.meshes) topology_.push_back(EdgeTopology::build(m));
}

GradientEngine::~GradientEngine() = default;

GradientResult GradientEngine::evaluate(const GradientRequest& req, EngineSession& session) {
  if (req.views.empty()) throw InputError("gradient request: no views");
  for (int v : req.views)
    if (v < 0 || size_t(v) >= scene_.cameras.size()) throw InputError("gradient request: view " + std::to_string(v) + " out of range");
  if (!req.renderOnly)
    for (int v : req.views)
      if (size_t(v) >= targets_.size() || targets_[size_t(v)].empty())
        throw InputError("gradient request: no target image for view " + std::to_string(v));
  GradientResult out;
  out.gradient.assign(params_.size(), 0.0);
  GradientStats& st = out.stats;
  const size_t pixels = size_t(scene_.width) * size_t(scene_.height);
  const bool restir = opt_.method == GradientMethod::Restir;
  const bool restirDerivative = restir && !opt_.forwardOnly;
  auto checkCancel = [&] {
    if (req.cancel && req.cancel->load()) throw EvaluationCancelled{};
  };

  auto t0 = std::chrono::steady_clock::now();
  if (restir) {
    // Re-place the reservoirs, and build a chain's kd-tree now if some view of the request will
    // search it (built on first use, it would stall the other threads mid-pass). The two chains
    // are independent: side by side.
    auto prepare = [&](ReservoirStore& chain) {
      chain.refresh(scene_);
      bool needsTree = !chain.empty() && !opt_.pixelNeighbours;
      for (int v : req.views) needsTree = needsTree || (!chain.empty() && !chain.slotsCover(v));
      if (needsTree) chain.buildIndex();
    };
    tbb::parallel_invoke([&] { prepare(session.primal); }, [&] { if (restirDerivative) prepare(session.derivative); });
  }
  st.secondsReservoirUpdate += secondsSince(t0);

  // The pixel mini-batch of each view (Yan et al. 2025, stage 2), from maps refreshed by stage 1
  // every `refreshEvery` steps and kept in the session.
  const PixelSamplingOptions& po = opt_.pixels;
  std::vector<PixelBatch> batches;
  if (po.sampler != PixelSampler::All) {
    const int n = po.samplesPerView > 0 ? po.samplesPerView : std::max<int>(1, int(pixels / 4));
    for (int v : req.views) {
      PixelMap& map = session.pixelMaps[v];
      bool stale = !map.valid() || req.step >= map.computedAt + uint64_t(std::max(1, po.refreshEvery)) || req.step < map.computedAt;
      bool measurable = size_t(v) < targets_.size() && !targets_[size_t(v)].empty();
      if (po.sampler == PixelSampler::Uniform || !measurable) {
        if (!map.valid()) map.setProbabilities(std::vector<float>(pixels, float(1.0 / double(pixels))));
      } else if (stale) {
        checkCancel();
        t0 = std::chrono::steady_clock::now();
        map = buildPixelMap(po, runStage1(v, req, st.drops), req.step, &st.drops);
        st.secondsStage1 += secondsSince(t0);
      }
      batches.push_back(drawPixelBatch(map, n, RngKey{streamSeed(req.seed, kPixelBatchStream), req.step, uint64_t(v), 0, 0}));
      for (size_t j = 0; j < pixels; ++j)
        INVR_INVARIANT((batches.back().draws[j] > 0) == (batches.back().weight[j] > 0.f) && std::isfinite(batches.back().weight[j]),
                       "a pixel batch weight does not match its draws");
    }
  }
  auto batchOf = [&](size_t k) { return batches.empty() ? nullptr : &batches[k]; };
  // Loss weights per view of the batch: the pixel mini-batch's, times the target's mask.
  std::vector<std::vector<float>> maskedWeights(req.views.size());
  for (size_t k = 0; k < req.views.size(); ++k) {
    const std::vector<float>* mask = maskOf(req.views[k]);
    if (!mask) continue;
    maskedWeights[k] = *mask;
    if (!batches.empty())
      for (size_t j = 0; j < pixels; ++j) maskedWeights[k][j] *= batches[k].weight[j];
  }
  auto weightsOf = [&](size_t k) -> const std::vector<float>* {
    if (!maskedWeights[k].empty()) return &maskedWeights[k];
    return batches.empty() ? nullptr : &batches[k].weight;
  };
  auto addCounters = [&](const PassOutput& pr, RestirCounters* counters) {
    st.rays += pr.rays;
    st.drops += pr.drops;
    if (counters) {
      counters->neighboursUsed += pr.restir.neighboursUsed;
      counters->shadingPoints += pr.restir.shadingPoints;
      counters->sumM += pr.restir.sumM;
    }
  };

  // Primal pass: images and dL/dI.
  t0 = std::chrono::steady_clock::now();
  // Next step's reservoirs, one slot per pixel sample, written in place by the passes into buffers
  // recycled from the step before last (no fresh pages to fault in each step). The pass driver
  // writes every slot (a reservoir, or mesh = UINT32_MAX), so the old contents never leak through.
  std::vector<StoredReservoir> newPrimal, newDerivative;
  if (restir) {
    newPrimal = session.primal.takeRecycled();
    newPrimal.resize(req.views.size() * pixels * size_t(opt_.sppPrimal));
  }
  const int batchViews = req.batchViews > 0 ? req.batchViews : int(req.views.size());
  std::vector<Image> adjoints(req.views.size());
  RestirCounters counters;
  for (size_t k = 0; k < req.views.size(); ++k) {
    checkCancel();
    const int view = req.views[k];
    auto estimator = estimatorFor(opt_, {scene_, params_, opt_, view, opt_.sppPrimal, restir ? &session.primal : nullptr}, restir);
    PassSpec spec;
    spec.kind = PassKind::Primal;
    spec.view = view;
    spec.stream = streamSeed(req.seed, kPrimalStream);
    spec.step = req.step;
    spec.spp = opt_.sppPrimal;
    spec.batch = batchOf(k);
    spec.reservoirs = restir ? newPrimal.data() + k * pixels * size_t(opt_.sppPrimal) : nullptr;
    spec.cancel = req.cancel;
    PassOutput pr = runPass(scene_, *estimator, spec, *scratch_);
    st.pixelsTraced += batches.empty() ? pixels : size_t(std::count_if(batches[k].draws.begin(), batches[k].draws.end(), [](uint32_t c) { return c > 0; }));
    addCounters(pr, &counters);
    if (!req.renderOnly) imageLoss(opt_.loss, pr.image, targets_[size_t(view)], &adjoints[k], batchViews, weightsOf(k));
    out.renders.push_back(std::move(pr.image));
  }
  st.secondsPrimal = secondsSince(t0);

  // Derivative pass: fresh paths weighted by dL/dI (or, during burn-in, only the reservoirs). Its
  // images are the second, independent render of the unbiased loss.
  t0 = std::chrono::steady_clock::now();
  std::vector<RenderCost> costs(req.views.size());  // variance-aware jobs: per view, from this pass's ray counts
  if (!req.renderOnly || restirDerivative) {
    if (restirDerivative) {
      newDerivative = session.derivative.takeRecycled();
      newDerivative.resize(req.views.size() * pixels * size_t(opt_.sppGradient));
    }
    for (size_t k = 0; k < req.views.size(); ++k) {
      checkCancel();
      const int view = req.views[k];
      auto estimator = estimatorFor(opt_, {scene_, params_, opt_, view, opt_.sppGradient, restirDerivative ? &session.derivative : nullptr},
                                    restirDerivative);
      PassSpec spec;
      spec.kind = req.renderOnly ? PassKind::Primal : PassKind::Derivative;
      spec.view = view;
      spec.stream = streamSeed(req.seed, kDerivativeStream);
      spec.step = req.step;
      spec.spp = opt_.sppGradient;
      spec.batch = batchOf(k);
      spec.adjoint = req.renderOnly ? nullptr : &adjoints[k];
      spec.reservoirs = restirDerivative ? newDerivative.data() + k * pixels * size_t(opt_.sppGradient) : nullptr;
      spec.cancel = req.cancel;
      PassOutput pr = runPass(scene_, *estimator, spec, *scratch_, req.renderOnly ? nullptr : &out.gradient);
      addCounters(pr, nullptr);
      // The cost comes from this pass: it is independent of both the primal render (the variance's
      // I1) and the variance pass, so t * V and its derivative stay unbiased.
      if (opt_.variance.enabled) costs[k] = renderCostByDepth(pr.rays, scene_.sampling.survival);
      if (!req.renderOnly) {
        double l = unbiasedImageLoss(opt_.loss, out.renders[k], pr.image, targets_[size_t(view)], batchViews, weightsOf(k));
        st.viewLoss.push_back(l * double(batchViews));
        st.loss += l;
      }
    }
  }
  st.secondsDerivative = secondsSince(t0);
  st.biasTerm = st.loss;

  // Boundary terms of shape derivatives: after the derivative pass (whose reservoir chain still
  // holds the previous step's reservoirs, the neighbours of Alg. 5), weighted by the primal pass's
  // dL/dI like the interior term.
  t0 = std::chrono::steady_clock::now();
  if (!topology_.empty() && !req.renderOnly) {
    const BoundaryOptions& bo = opt_.boundary;
    const int samples = bo.samplesFor(scene_.width, scene_.height);
    auto count = [&](const BoundaryPassStats& b) {
      st.boundaryEdges += b.candidateEdges;
      st.boundarySamples += b.samples;
      st.rays += b.rays;
      st.drops.boundary += b.dropped;
    };
    const bool edgeFirst = bo.secondary && bo.areaSampling == BoundaryOptions::AreaSampling::EdgeFirst && EdgeReservoirBoundary::applies(scene_);
    std::optional<EdgeReservoirBoundary> edgeSampler;
    std::vector<EdgeReservoir> createdEdges;
    if (edgeFirst) {
      EdgeSamplingSettings es;
      es.candidates = opt_.method == GradientMethod::Pt ? 1 : opt_.restir.candidates;
      es.reuse = restirDerivative;
      es.edgeImportance = restirDerivative && bo.edgeImportance;
      es.neighbours = bo.edgeNeighbours;
      edgeSampler.emplace(scene_, params_, topology_, session.edges, es);
    }
    for (size_t k = 0; k < req.views.size(); ++k) {
      checkCancel();
      const int view = req.views[k];
      auto estimator = estimatorFor(opt_, {scene_, params_, opt_, view, opt_.sppGradient, restirDerivative ? &session.derivative : nullptr},
                                    restirDerivative);
      if (bo.primary)
        count(PrimaryBoundary(scene_, params_, topology_)
                  .run(*estimator, view, adjoints[k], samples, streamSeed(req.seed, kPrimaryBoundaryStream), req.step, *scratch_,
                       out.gradient, req.cancel));
      if (bo.secondary && DeltaShadowBoundary::applies(scene_))
        count(DeltaShadowBoundary(scene_, params_, topology_)
                  .run(*estimator, view, adjoints[k], samples, streamSeed(req.seed, kDeltaShadowBoundaryStream), req.step, *scratch_,
                       out.gradient, req.cancel));
      if (edgeSampler)
        count(edgeSampler->run(view, adjoints[k], samples, streamSeed(req.seed, kAreaShadowBoundaryStream), req.step, *scratch_,
                               out.gradient, createdEdges, req.cancel));
      else if (bo.secondary && AreaShadowBoundary::applies(scene_))
        count(AreaShadowBoundary(scene_, params_, topology_)
                  .run(view, adjoints[k], samples, bo.lightPoints, streamSeed(req.seed, kAreaShadowBoundaryStream), req.step, *scratch_,
                       out.gradient, req.cancel));
      if (bo.secondary && EnvironmentShadowBoundary::applies(scene_))
        count(EnvironmentShadowBoundary(scene_, params_, topology_)
                  .run(view, adjoints[k], samples, bo.lightPoints, streamSeed(req.seed, kEnvironmentShadowBoundaryStream), req.step,
                       *scratch_, out.gradient, req.cancel));
    }
    if (edgeSampler && restirDerivative) {
      // Alg. 8: the previous step's reservoirs whose p1 no view of this batch sees stay, unless the
      // batch holds every view the session serves (then no later step could want them more).
      if (opt_.preserveOccluded && !req.allSessionViews) st.edgeReservoirsPreserved = edgeSampler->preserve(req.views, createdEdges, st.rays);
      edgeSampler.reset();
      session.edges.items = std::move(createdEdges);
      session.edges.index({});
      st.edgeReservoirs = session.edges.items.size();
    }
  }
  st.secondsBoundary = secondsSince(t0);

  // Variance pass (Yan et al. 2024): fresh paths, each paired with the primal render as the
  // independent estimate of its pixel's mean (Eq. 18).
  t0 = std::chrono::steady_clock::now();
  if (opt_.variance.enabled && !req.renderOnly) {
    const bool timeAware = opt_.variance.cost == VarianceCost::Depth;
    const double norm = 1.0 / (double(pixels) * 3.0 * double(batchViews));
    for (size_t k = 0; k < req.views.size(); ++k) {
      checkCancel();
      const int view = req.views[k];
      st.cost += costs[k].raysPerSample / double(batchViews);
      // L = L_bias + coef * V: coef = lambda / K, or lambda* t (Eq. 33).
      const double coef = timeAware ? opt_.variance.weight * costs[k].raysPerSample : opt_.variance.weight / opt_.variance.samples;
      const std::vector<float>* weights = weightsOf(k);
      Image adjointV(scene_.width, scene_.height, 3);
      for (size_t j = 0; j < pixels; ++j) {
        float a = float(coef * norm * (weights ? double((*weights)[j]) : 1.0));
        for (int c = 0; c < 3; ++c) adjointV.data()[j * 3 + size_t(c)] = a;
      }
      auto estimator = estimatorFor(opt_, {scene_, params_, opt_, view, opt_.variance.spp, nullptr}, false);
      PassSpec spec;
      spec.kind = PassKind::Variance;
      spec.view = view;
      spec.stream = streamSeed(req.seed, kVarianceStream);
      spec.step = req.step;
      spec.spp = opt_.variance.spp;
      spec.batch = batchOf(k);
      spec.adjoint = &adjointV;
      spec.mean = &out.renders[k];
      spec.detached = opt_.variance.detached;
      spec.cancel = req.cancel;
      PassOutput pr = runPass(scene_, *estimator, spec, *scratch_, &out.gradient);
      addCounters(pr, nullptr);
      // Unbiased per pixel: E[mean F^2] - E[I1] E[mean F] = E[F^2] - I^2 (I1 independent).
      Image var(scene_.width, scene_.height, 3);
      double sum = 0;
      for (size_t j = 0; j < pixels; ++j) {
        const double w = weights ? double((*weights)[j]) : 1.0;
        for (int c = 0; c < 3; ++c) {
          const size_t i = j * 3 + size_t(c);
          const double v = double(pr.secondMoment.data()[i]) - double(out.renders[k].data()[i]) * double(pr.image.data()[i]);
          var.data()[i] = float(v);
          sum += w * v;
        }
      }
      const double term = coef * sum * norm;
      st.varianceTerm += term;
      // Eq. 35's other half, lambda* V dt/dq: survival changes the cost (Eq. 36).
      if (timeAware && params_.survivalOffset() >= 0)
        for (size_t i = 0; i < costs[k].dSurvival.size(); ++i)
          out.gradient[size_t(params_.survivalOffset()) + i] += opt_.variance.weight * sum * norm * costs[k].dSurvival[i];
      if (k < st.viewLoss.size()) st.viewLoss[k] += term * double(batchViews);
      out.variances.push_back(std::move(var));
    }
    st.loss += st.varianceTerm;
  }
  st.secondsVariance = secondsSince(t0);

  // Next step's reservoirs: this step's, plus the old ones this step did not replace (Alg. 8).
  t0 = std::chrono::steady_clock::now();
  auto rebuild = [&](ReservoirStore& chain, std::vector<StoredReservoir>& fresh, size_t& preserved, size_t& carried, int& treeUsed) {
    // Compact out the empty slots, remembering where each pixel sample's reservoir went (the next
    // step tries it first, without a kd-tree search).
    std::vector<StoredReservoir> next = std::move(fresh);
    PixelSlots slots;
    slots.views = req.views;
    slots.slotsPerView = req.views.empty() ? 0 : next.size() / req.views.size();
    slots.item.resize(next.size());
    size_t kept = 0;
    for (size_t i = 0; i < next.size(); ++i) {
      if (next[i].mesh == UINT32_MAX) {
        slots.item[i] = UINT32_MAX;
        continue;
      }
      slots.item[i] = uint32_t(kept);
      if (kept != i) next[kept] = next[i];
      ++kept;
    }
    next.resize(kept);
    INVR_INVARIANT(slots.item.size() == req.views.size() * slots.slotsPerView, "a pass left reservoir slots unaccounted for");
    for (uint32_t item : slots.item) INVR_INVARIANT(item == UINT32_MAX || item < kept, "a pixel slot points past the stored reservoirs");
    // Alg. 8: an old reservoir is replaced when a view of this step traced the pixel it projects
    // to and sees it there; every other one is kept. With pixel mini-batches that keeps the
    // reservoirs of undrawn pixels of the batch's own views: whether one is kept depends only on
    // its position and the draw, not on its sample, so reuse stays unbiased. When the batch holds
    // every pixel of every view and the geometry never moved, each old reservoir is replaced (it
    // was seen by one of these views and is visible still): skip the rays.
    const bool unmoved = scene_.geometryVersion() == 0;
    const bool everyPixel = batches.empty();
    bool allViews = (req.allSessionViews || req.views.size() == scene_.cameras.size()) && unmoved && everyPixel;
    if (opt_.preserveOccluded && !allViews) {
      // On unmoved geometry a reservoir is visible from the camera whose primary ray found it: no
      // ray for that view. Other views trace one ray each until one sees it (only where their
      // batch drew the pixel), in parallel; the kept ones are appended in their old order
      // (deterministic).
      const std::vector<StoredReservoir>& old = chain.items();
      std::vector<uint8_t> keep(old.size()), carry(old.size());
      tbb::parallel_for(tbb::blocked_range<size_t>(0, old.size(), 2048), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i < range.end(); ++i) {
          const StoredReservoir& r = old[i];
          bool replaced = false, undrawn = false;
          for (size_t k = 0; !replaced && k < req.views.size(); ++k) {
            const Camera& cam = scene_.cameras[size_t(req.views[k])];
            float px, py;
            if (!cam.project(r.p, scene_.width, scene_.height, px, py)) continue;
            if (!everyPixel) {
              size_t pixel = size_t(py) * size_t(scene_.width) + size_t(px);
              if (!batches[k].contains(pixel)) {
                undrawn = undrawn || int(r.view) == req.views[k];
                continue;
              }
            }
            replaced = (unmoved && int(r.view) == req.views[k]) || visibleFromCamera(scene_, cam, r.p, r.n());
          }
          keep[i] = !replaced;
          carry[i] = !replaced && undrawn;
        }
      });
      for (size_t i = 0; i < old.size(); ++i)
        if (keep[i]) {
          next.push_back(old[i]);
          ++preserved;
          carried += carry[i];
        }
    }
    // Fresh items carry their hit's position; kept ones were re-placed by this step's refresh().
    treeUsed = chain.hasIndex() ? 1 : 0;
    chain.assignPlaced(std::move(next), scene_.geometryVersion(), std::move(slots));
  };
  // The two chains are independent: side by side.
  size_t preserved[2] = {0, 0}, carried[2] = {0, 0};
  int treeUsed[2] = {0, 0};
  tbb::parallel_invoke([&] { if (restir) rebuild(session.primal, newPrimal, preserved[0], carried[0], treeUsed[0]); },
                       [&] { if (restirDerivative) rebuild(session.derivative, newDerivative, preserved[1], carried[1], treeUsed[1]); });
  st.reservoirsPreserved += preserved[0] + preserved[1];
  st.reservoirsCarried += carried[0] + carried[1];
  st.kdTreesBuilt += treeUsed[0] + treeUsed[1];
  st.secondsReservoirUpdate += secondsSince(t0);
  st.reservoirs = session.primal.size() + session.derivative.size();
  if (counters.shadingPoints) {
    st.meanNeighbours = double(counters.neighboursUsed) / double(counters.shadingPoints);
    st.meanM = counters.sumM / double(counters.shadingPoints);
  }
  st.nonFiniteSamples = st.drops.total();
  return out;
}

Image GradientEngine::sampleVarianceMap(int view, int spp, uint64_t seed, const std::atomic<bool>* cancel) {
  if (view < 0 || size_t(view) >= scene_.cameras.size()) throw InputError("variance map: view " + std::to_string(view) + " out of range");
  if (spp < 2) throw InputError("variance map: needs at least 2 samples per pixel");
  auto estimator = estimatorFor(opt_, {scene_, params_, opt_, view, spp, nullptr}, false);
  PassSpec spec;
  spec.kind = PassKind::Primal;
  spec.squares = true;
  spec.view = view;
  spec.stream = streamSeed(seed, kVarianceMapStream);
  spec.spp = spp;
  spec.cancel = cancel;
  PassOutput pr = runPass(scene_, *estimator, spec, *scratch_);
  Image var(scene_.width, scene_.height, 3);
  const double bessel = double(spp) / double(spp - 1);
  for (size_t i = 0; i < var.data().size(); ++i) {
    const double m = double(pr.image.data()[i]);
    var.data()[i] = float(std::max(0.0, (double(pr.secondMoment.data()[i]) - m * m) * bessel));
  }
  return var;
}

Stage1 GradientEngine::measureStage1(int view, const GradientRequest& request) {
  SampleDrops drops;
  return runStage1(view, request, drops);
}

Stage1 GradientEngine::runStage1(int view, const GradientRequest& req, SampleDrops& drops) {
  Stage1 s;
  s.width = scene_.width;
  s.height = scene_.height;
  s.stride = std::max(1, opt_.pixels.stage1Stride);
  s.gw = (s.width + s.stride - 1) / s.stride;
  s.gh = (s.height + s.stride - 1) / s.stride;
  const size_t pixels = size_t(s.width) * size_t(s.height);
  // One pixel per cell, at its centre.
  PixelBatch cellPixels;
  cellPixels.weight.assign(pixels, 0.f);
  cellPixels.draws.assign(pixels, 0);
  std::vector<size_t> cellPixel(size_t(s.gw) * size_t(s.gh));
  for (int j = 0; j < s.gh; ++j)
    for (int i = 0; i < s.gw; ++i) {
      int x = std::min(s.width - 1, i * s.stride + s.stride / 2), y = std::min(s.height - 1, j * s.stride + s.stride / 2);
      cellPixel[size_t(j * s.gw + i)] = size_t(y) * size_t(s.width) + size_t(x);
      cellPixels.weight[cellPixel[size_t(j * s.gw + i)]] = 1.f;
      cellPixels.draws[cellPixel[size_t(j * s.gw + i)]] = 1;
    }
  // Stage 1 leaves the reservoir chains alone: ReSTIR's stage 1 samples with plain RIS.
  auto estimator = estimatorFor(opt_, {scene_, params_, opt_, view, 1, nullptr}, false);
  // dL/dI from one primal sample per cell.
  PassSpec spec;
  spec.kind = PassKind::Primal;
  spec.view = view;
  spec.stream = streamSeed(req.seed, kStage1PrimalStream);
  spec.step = req.step;
  spec.batch = &cellPixels;
  spec.cancel = req.cancel;
  PassOutput primal = runPass(scene_, *estimator, spec, *scratch_);
  Image adjoint;
  if (const std::vector<float>* mask = maskOf(view))
    for (size_t j = 0; j < pixels; ++j) cellPixels.weight[j] *= (*mask)[j];
  imageLoss(opt_.loss, primal.image, targets_[size_t(view)], &adjoint, 1, &cellPixels.weight);
  // Squared parameter derivatives of one sample per cell (Eq. 16), with a unit adjoint.
  spec.kind = PassKind::Stage1;
  spec.stream = streamSeed(req.seed, kStage1DerivativeStream);
  PassOutput deriv = runPass(scene_, *estimator, spec, *scratch_);
  drops += primal.drops;
  drops += deriv.drops;
  s.adjoint.resize(cellPixel.size() * 3);
  s.derivSq.resize(cellPixel.size());
  for (size_t c = 0; c < cellPixel.size(); ++c) {
    for (int ch = 0; ch < 3; ++ch) s.adjoint[3 * c + size_t(ch)] = adjoint.data()[cellPixel[c] * 3 + size_t(ch)];
    s.derivSq[c] = deriv.derivSq[cellPixel[c]];
  }
  // Guides for the edge-aware upsampling: first-hit normal and albedo.
  Aovs aov = renderAovs(scene_, view);
  s.guide.resize(pixels * 6);
  for (size_t p = 0; p < pixels; ++p)
    for (int c = 0; c < 3; ++c) {
      s.guide[p * 6 + size_t(c)] = aov.normal.data()[p * size_t(aov.normal.channels()) + size_t(c)];
      s.guide[p * 6 + 3 + size_t(c)] = aov.albedo.data()[p * size_t(aov.albedo.channels()) + size_t(c)];
    }
  return s;
}

}  // namespace invr
