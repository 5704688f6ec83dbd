#include "core/diff/gradient_engine.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>

#include "core/diff/gradient_stats.h"
#include "core/diff/parameter_kind.h"
#include "core/diff/pass_driver.h"
#include "core/diff/render_cost.h"
#include "core/geometry/ray_observer.h"
#include "core/error.h"
#include "core/render/path_walk.h"
#include "core/render/renderer.h"
#include "core/stopwatch.h"

namespace invr {

namespace {

// The estimator a pass uses: the job's method, except that "forward only" ReSTIR samples its
// derivative pass with plain RIS ("derivative only", a lab ablation, its primal pass), and that
// stage 1 leaves the reservoir chains alone.
std::unique_ptr<InteriorEstimator> estimatorFor(const GradientOptions& o, const EstimatorSetup& setup, bool reuse) {
  switch (o.method) {
    case GradientMethod::Pt: return makePtEstimator(setup);
    case GradientMethod::Ris: return makeRisEstimator(setup);
    default: return reuse ? makeRestirEstimator(setup) : makeRisEstimator(setup);
  }
}

}  // namespace

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
      scratch_(std::make_unique<GradientScratchPool>(params.adjointSize())) {
  // User errors were refused when the job was built (parseGradientOptions, validateGradientJob).
  INVR_INVARIANT(scene.accelerated(), "GradientEngine: the scene was built for validation only (no BVH)");
  INVR_INVARIANT(opt_.sppPrimal > 0 && opt_.sppGradient > 0 && opt_.restir.candidates > 0 && opt_.radiusPixels > 0.f,
                 "sample counts and the reuse radius are positive");
  INVR_INVARIANT(opt_.maxDepth >= 1 && opt_.maxDepth <= kMaxWalkDepth && (opt_.maxDepth == 1 || opt_.method == GradientMethod::Pt),
                 "multi-bounce paths are differentiated with method pt");
  INVR_INVARIANT(!opt_.variance.enabled || (opt_.method == GradientMethod::Pt && !opt_.pixels.sampler->usesStage1() && opt_.variance.spp > 0),
                 "variance passes need method pt and a sampler without stage-1 maps");
  INVR_INVARIANT(!params.hasSamplingParameters() || opt_.method == GradientMethod::Pt, "sampling parameters need method pt");
  INVR_INVARIANT(!(opt_.forwardOnly && opt_.derivativeOnly), "ReSTIR in one pass only: forward only or derivative only, not both");
  INVR_INVARIANT(opt_.boundary.samples >= 0 && opt_.boundary.lightPoints >= 1, "boundary sample counts are valid");
  for (const auto& m : opt_.lossMasks)
    INVR_INVARIANT(m.empty() || m.size() == size_t(scene.width) * size_t(scene.height), "a loss mask matches the film");
  boundaryTerms_ = boundaryTermsFor(scene, params, opt_);
  // Occluders need not move to cast a moving shadow (a moving receiver drags it): every mesh.
  if (params.hasVisibilityParameters()) topology_ = buildBoundaryTopology(scene, params);
}

GradientEngine::~GradientEngine() = default;

// One evaluation's working state, handed from phase to phase.
struct GradientEngine::Step {
  const GradientRequest& req;
  EngineSession& session;
  GradientResult out;
  size_t pixels = 0;
  bool restir = false, restirPrimal = false, restirDerivative = false;
  int batchViews = 0;
  std::vector<PixelBatch> batches;              // per view of the request (pixel mini-batches; empty: every pixel)
  std::vector<std::vector<float>> maskedWeights;  // per view: the batch's weights times the target's mask
  std::vector<Image> adjoints;                  // per view: dL/dI of the primal render
  std::vector<StoredReservoir> newPrimal, newDerivative;  // next step's reservoirs, one slot per pixel sample
  std::vector<RenderCost> costs;                // variance-aware jobs: per view, from the derivative pass's rays
  RayStats rays;
  SampleDrops drops;
  RestirCounters restirCounters;                // the primal pass's reuse
  Step(const GradientRequest& r, EngineSession& s) : req(r), session(s) {}
  void checkCancel() const {
    if (req.cancel && req.cancel->load()) throw EvaluationCancelled{};
  }
  const PixelBatch* batchOf(size_t k) const { return batches.empty() ? nullptr : &batches[k]; }
  // Loss weights of view k of the request: the pixel mini-batch's, times the target's mask.
  const std::vector<float>* weightsOf(size_t k) const {
    if (!maskedWeights[k].empty()) return &maskedWeights[k];
    return batches.empty() ? nullptr : &batches[k].weight;
  }
  void count(const PassOutput& pr) {
    rays += pr.rays;
    drops += pr.drops;
  }
};

GradientResult GradientEngine::evaluate(const GradientRequest& req, EngineSession& session) {
  if (req.views.empty()) throw InputError("gradient request: no views");
  for (int v : req.views)
    if (v < 0 || size_t(v) >= scene_.cameras.size()) throw InputError("gradient request: view " + std::to_string(v) + " out of range");
  if (req.derivativeImage) {
    if (req.views.size() != 1 || req.renderOnly) throw InputError("derivative image: one view, and not a render-only step");
    if (req.derivativeImage->index >= params_.size()) throw InputError("derivative image: parameter value out of range");
    for (const ParameterSlot& slot : params_.slots())
      if (req.derivativeImage->index >= slot.offset && req.derivativeImage->index < slot.offset + slot.size && slot.kind->isMesh())
        throw InputError("derivative image: " + slot.name +
                         " is a mesh's vertices (their normals' share is folded in after the passes); pick a material, light, pose or camera value");
    if (req.derivativeWeights && (req.derivativeWeights->width() != scene_.width || req.derivativeWeights->height() != scene_.height ||
                                  req.derivativeWeights->channels() != 3))
      throw InputError("derivative image: the weights are not an RGB image of the film's size");
    req.derivativeImage->image.assign(size_t(scene_.width) * size_t(scene_.height), 0.0);
  } else if (!req.renderOnly) {
    for (int v : req.views)
      if (size_t(v) >= targets_.size() || targets_[size_t(v)].empty())
        throw InputError("gradient request: no target image for view " + std::to_string(v));
  }
  Step s(req, session);
  s.out.gradient.assign(params_.adjointSize(), 0.0);
  s.pixels = size_t(scene_.width) * size_t(scene_.height);
  s.restir = opt_.method == GradientMethod::Restir;
  s.restirPrimal = s.restir && !opt_.derivativeOnly && !req.derivativeImage;
  s.restirDerivative = s.restir && !opt_.forwardOnly;
  s.batchViews = req.batchViews > 0 ? req.batchViews : int(req.views.size());
  prepareReservoirs(s);
  drawPixelBatches(s);
  primalPass(s);
  derivativePass(s);
  boundaryPasses(s);
  variancePass(s);
  params_.foldNormalAdjoints(scene_, s.out.gradient, opt_.vertexNormalTerm);
  storeReservoirs(s);
  v1::GradientStats& st = s.out.stats;
  setRayCounts(st, s.rays);
  setDropCounts(st, s.drops);
  st.set_reservoirs(session.primal.size() + session.derivative.size());
  st.set_shading_points(s.restirCounters.shadingPoints);
  st.set_neighbours_used(s.restirCounters.neighboursUsed);
  st.set_sum_m(s.restirCounters.sumM);
  return std::move(s.out);
}

void GradientEngine::prepareReservoirs(Step& s) {
  if (!s.restir) return;
  Stopwatch clock;
  // Re-place the reservoirs, and build a chain's kd-tree now if some view of the request will
  // search it (built on first use, it would stall the other threads mid-pass). The two chains
  // are independent: side by side.
  auto prepare = [&](ReservoirStore& chain) {
    chain.refresh(scene_);
    bool needsTree = !chain.empty() && !opt_.pixelNeighbours;
    for (int v : s.req.views) needsTree = needsTree || (!chain.empty() && !chain.slotsCover(v));
    if (needsTree) chain.buildIndex();
  };
  tbb::parallel_invoke([&] { if (s.restirPrimal) prepare(s.session.primal); }, [&] { if (s.restirDerivative) prepare(s.session.derivative); });
  s.out.stats.set_seconds_reservoir(s.out.stats.seconds_reservoir() + clock.seconds());
}

void GradientEngine::drawPixelBatches(Step& s) {
  // The pixel mini-batch of each view (Yan et al. 2025, stage 2), from maps refreshed by stage 1
  // every `refreshEvery` steps and kept in the session.
  const PixelSamplingOptions& po = opt_.pixels;
  const GradientRequest& req = s.req;
  if (po.sampler->miniBatch() && !req.derivativeImage) {
    const int n = po.samplesFor(s.pixels);
    for (int v : req.views) {
      PixelMap& map = s.session.pixelMaps[v];
      bool stale = !map.valid() || req.step >= map.computedAt + uint64_t(std::max(1, po.refreshEvery)) || req.step < map.computedAt;
      bool measurable = size_t(v) < targets_.size() && !targets_[size_t(v)].empty();
      if (!po.sampler->usesStage1() || !measurable) {
        if (!map.valid()) map.setProbabilities(std::vector<float>(s.pixels, float(1.0 / double(s.pixels))));
      } else if (stale) {
        s.checkCancel();
        Stopwatch clock;
        Stage1& history = s.session.stage1History[v];
        accumulateStage1(history, runStage1(v, req, s.drops), po.stage1History);
        map = buildPixelMap(po, history, req.step, &s.drops);
        s.out.stats.set_seconds_stage1(s.out.stats.seconds_stage1() + clock.seconds());
      }
      s.batches.push_back(drawPixelBatch(map, n, RngKey{streamSeed(req.seed, kPixelBatchStream), req.step, uint64_t(v), 0, 0}));
      for (size_t j = 0; j < s.pixels; ++j)
        INVR_INVARIANT((s.batches.back().draws[j] > 0) == (s.batches.back().weight[j] > 0.f) && std::isfinite(s.batches.back().weight[j]),
                       "a pixel batch weight does not match its draws");
    }
  }
  s.maskedWeights.resize(req.views.size());
  for (size_t k = 0; k < req.views.size(); ++k) {
    const std::vector<float>* mask = maskOf(req.views[k]);
    if (!mask) continue;
    s.maskedWeights[k] = *mask;
    if (!s.batches.empty())
      for (size_t j = 0; j < s.pixels; ++j) s.maskedWeights[k][j] *= s.batches[k].weight[j];
  }
}

void GradientEngine::primalPass(Step& s) {
  // Primal pass: images and dL/dI.
  Stopwatch clock;
  const GradientRequest& req = s.req;
  // Next step's reservoirs, one slot per pixel sample, written in place by the passes into buffers
  // recycled from the step before last (no fresh pages to fault in each step). The pass driver
  // writes every slot (a reservoir, or mesh = UINT32_MAX), so the old contents never leak through.
  if (s.restirPrimal) {
    s.newPrimal = s.session.primal.takeRecycled();
    s.newPrimal.resize(req.views.size() * s.pixels * size_t(opt_.sppPrimal));
  }
  s.adjoints.resize(req.views.size());
  if (req.derivativeImage) {  // dL/dI = 1/3: the derivative of each pixel's channel mean
    if (req.derivativeWeights) {
      s.adjoints[0] = *req.derivativeWeights;
      return;
    }
    s.adjoints[0] = Image(scene_.width, scene_.height, 3);
    for (int y = 0; y < scene_.height; ++y)
      for (int x = 0; x < scene_.width; ++x) s.adjoints[0].setRgb(x, y, Rgb(1.f / 3.f));
    return;
  }
  uint64_t traced = 0;
  for (size_t k = 0; k < req.views.size(); ++k) {
    s.checkCancel();
    const int view = req.views[k];
    auto estimator =
        estimatorFor(opt_, {scene_, params_, opt_, view, opt_.sppPrimal, s.restirPrimal ? &s.session.primal : nullptr}, s.restirPrimal);
    PassSpec spec;
    spec.kind = PassKind::Primal;
    spec.view = view;
    spec.stream = streamSeed(req.seed, kPrimalStream);
    spec.sampler = opt_.sampler;
    spec.step = req.step;
    spec.spp = opt_.sppPrimal;
    spec.batch = s.batchOf(k);
    spec.reservoirs = s.restirPrimal ? s.newPrimal.data() + k * s.pixels * size_t(opt_.sppPrimal) : nullptr;
    spec.cancel = req.cancel;
    PassOutput pr = runPass(scene_, *estimator, spec, *scratch_);
    traced += s.batches.empty() ? s.pixels
                                : size_t(std::count_if(s.batches[k].draws.begin(), s.batches[k].draws.end(), [](uint32_t c) { return c > 0; }));
    s.count(pr);
    s.restirCounters.neighboursUsed += pr.restir.neighboursUsed;
    s.restirCounters.shadingPoints += pr.restir.shadingPoints;
    s.restirCounters.sumM += pr.restir.sumM;
    if (!req.renderOnly)
      s.out.stats.set_primal_loss(s.out.stats.primal_loss() +
                                  imageLoss(opt_.loss, pr.image, targets_[size_t(view)], &s.adjoints[k], s.batchViews, s.weightsOf(k)));
    s.out.renders.push_back(std::move(pr.image));
  }
  s.out.stats.set_pixels_traced(traced);
  s.out.stats.set_seconds_primal(clock.seconds());
}

void GradientEngine::derivativePass(Step& s) {
  // Derivative pass: fresh paths weighted by dL/dI (or, during burn-in, only the reservoirs). Its
  // images are the second, independent render of the unbiased loss.
  Stopwatch clock;
  const GradientRequest& req = s.req;
  v1::GradientStats& st = s.out.stats;
  s.costs.resize(req.views.size());
  if (!req.renderOnly || s.restirDerivative) {
    if (s.restirDerivative) {
      s.newDerivative = s.session.derivative.takeRecycled();
      s.newDerivative.resize(req.views.size() * s.pixels * size_t(opt_.sppGradient));
    }
    for (size_t k = 0; k < req.views.size(); ++k) {
      s.checkCancel();
      const int view = req.views[k];
      auto estimator = estimatorFor(opt_, {scene_, params_, opt_, view, opt_.sppGradient, s.restirDerivative ? &s.session.derivative : nullptr},
                                    s.restirDerivative);
      PassSpec spec;
      spec.kind = req.renderOnly ? PassKind::Primal : PassKind::Derivative;
      spec.view = view;
      spec.stream = streamSeed(req.seed, opt_.correlatedPrimal ? kPrimalStream : kDerivativeStream);
      spec.sampler = opt_.sampler;
      spec.step = req.step;
      spec.spp = opt_.sppGradient;
      spec.batch = s.batchOf(k);
      spec.adjoint = req.renderOnly ? nullptr : &s.adjoints[k];
      spec.reservoirs = s.restirDerivative ? s.newDerivative.data() + k * s.pixels * size_t(opt_.sppGradient) : nullptr;
      spec.cancel = req.cancel;
      spec.pixels = req.derivativeImage;
      PassOutput pr = runPass(scene_, *estimator, spec, *scratch_, req.renderOnly ? nullptr : &s.out.gradient);
      s.count(pr);
      // The cost comes from this pass: it is independent of both the primal render (the variance's
      // I1) and the variance pass, so t * V and its derivative stay unbiased.
      if (opt_.variance.enabled) s.costs[k] = renderCostByDepth(pr.rays, scene_.sampling.survival);
      if (!req.renderOnly && !req.derivativeImage)
        st.set_loss(st.loss() + unbiasedImageLoss(opt_.loss, s.out.renders[k], pr.image, targets_[size_t(view)], s.batchViews, s.weightsOf(k)));
    }
  }
  st.set_seconds_derivative(clock.seconds());
  st.set_bias_term(st.loss());
}

void GradientEngine::boundaryPasses(Step& s) {
  // Boundary terms of shape derivatives: after the derivative pass (whose reservoir chain still
  // holds the previous step's reservoirs, the neighbours of Alg. 5), weighted by the primal pass's
  // dL/dI like the interior term. Per view, the terms run in their registered order: the gradient
  // is summed in that order.
  const GradientRequest& req = s.req;
  if (boundaryTerms_.empty() || req.renderOnly) return;
  Stopwatch clock;
  const RayObserver::BoundaryPhase boundaryRays(scene_.rayObserver());  // `invr-lab bench step` counts these rays apart
  v1::GradientStats& st = s.out.stats;
  std::vector<std::unique_ptr<BoundaryTerm>> terms;
  for (const BoundaryTermKind* kind : boundaryTerms_)
    terms.push_back(kind->make({scene_, params_, topology_, opt_, s.session.boundary[kind->name], req.views, req.allSessionViews}));
  std::vector<double> seconds(terms.size(), 0.0);
  std::vector<BoundaryPassStats> totals(terms.size());
  for (size_t k = 0; k < req.views.size(); ++k) {
    s.checkCancel();
    const int view = req.views[k];
    auto estimator = estimatorFor(opt_, {scene_, params_, opt_, view, opt_.sppGradient, s.restirDerivative ? &s.session.derivative : nullptr},
                                  s.restirDerivative);
    for (size_t t = 0; t < terms.size(); ++t) {
      Stopwatch termClock;
      const BoundaryView bv{view, s.adjoints[k], *estimator, opt_.boundary.samplesFor(boundaryTerms_[t]->name, scene_.width, scene_.height),
                            streamSeed(req.seed, boundaryTerms_[t]->stream()), req.step,
                            *scratch_, s.out.gradient, req.cancel, opt_.sampler, req.derivativeImage};
      const BoundaryPassStats b = terms[t]->run(bv);
      totals[t].candidateEdges += b.candidateEdges;
      totals[t].samples += b.samples;
      s.rays += b.rays;
      s.drops.boundary += b.dropped;
      seconds[t] += termClock.seconds();
    }
  }
  for (size_t t = 0; t < terms.size(); ++t) {
    Stopwatch termClock;
    std::vector<std::pair<std::string, uint64_t>> counters;
    terms[t]->endStep(s.rays, counters);
    terms[t].reset();
    v1::BoundaryTermStats& ts = (*st.mutable_boundary())[boundaryTerms_[t]->name];
    ts.set_seconds(seconds[t] + termClock.seconds());
    ts.set_candidate_edges(totals[t].candidateEdges);
    ts.set_samples(totals[t].samples);
    for (const auto& [name, value] : counters) (*ts.mutable_counters())[name] = value;
  }
  st.set_seconds_boundary(clock.seconds());
}

void GradientEngine::variancePass(Step& s) {
  // Variance pass (Yan et al. 2024): fresh paths, each paired with the primal render as the
  // independent estimate of its pixel's mean (Eq. 18).
  const GradientRequest& req = s.req;
  if (!opt_.variance.enabled || req.renderOnly || req.derivativeImage) return;
  Stopwatch clock;
  v1::GradientStats& st = s.out.stats;
  const bool timeAware = opt_.variance.cost == VarianceCost::Depth;
  const double norm = 1.0 / (double(s.pixels) * 3.0 * double(s.batchViews));
  double cost = 0, varianceTerm = 0;
  for (size_t k = 0; k < req.views.size(); ++k) {
    s.checkCancel();
    const int view = req.views[k];
    cost += s.costs[k].raysPerSample / double(s.batchViews);
    // L = L_bias + coef * V: coef = lambda / K, or lambda* t (Eq. 33).
    const double coef = timeAware ? opt_.variance.weight * s.costs[k].raysPerSample : opt_.variance.weight / opt_.variance.samples;
    const std::vector<float>* weights = s.weightsOf(k);
    Image adjointV(scene_.width, scene_.height, 3);
    for (size_t j = 0; j < s.pixels; ++j) {
      float a = float(coef * norm * (weights ? double((*weights)[j]) : 1.0));
      for (int c = 0; c < 3; ++c) adjointV.data()[j * 3 + size_t(c)] = a;
    }
    auto estimator = estimatorFor(opt_, {scene_, params_, opt_, view, opt_.variance.spp, nullptr}, false);
    PassSpec spec;
    spec.kind = PassKind::Variance;
    spec.view = view;
    spec.stream = streamSeed(req.seed, kVarianceStream);
    spec.sampler = opt_.sampler;
    spec.step = req.step;
    spec.spp = opt_.variance.spp;
    spec.batch = s.batchOf(k);
    spec.adjoint = &adjointV;
    spec.mean = &s.out.renders[k];
    spec.detached = opt_.variance.detached;
    spec.cancel = req.cancel;
    PassOutput pr = runPass(scene_, *estimator, spec, *scratch_, &s.out.gradient);
    s.count(pr);
    // Unbiased per pixel: E[mean F^2] - E[I1] E[mean F] = E[F^2] - I^2 (I1 independent).
    Image var(scene_.width, scene_.height, 3);
    double sum = 0;
    for (size_t j = 0; j < s.pixels; ++j) {
      const double w = weights ? double((*weights)[j]) : 1.0;
      for (int c = 0; c < 3; ++c) {
        const size_t i = j * 3 + size_t(c);
        const double v = double(pr.secondMoment.data()[i]) - double(s.out.renders[k].data()[i]) * double(pr.image.data()[i]);
        var.data()[i] = float(v);
        sum += w * v;
      }
    }
    varianceTerm += coef * sum * norm;
    // Eq. 35's other half, lambda* V dt/dq: survival changes the cost (Eq. 36). The job's check
    // (validateGradientJob) keeps every other parameter out of time-aware jobs.
    if (timeAware && params_.survivalOffset() >= 0)
      for (size_t i = 0; i < s.costs[k].dSurvival.size(); ++i)
        s.out.gradient[size_t(params_.survivalOffset()) + i] += opt_.variance.weight * sum * norm * s.costs[k].dSurvival[i];
    s.out.variances.push_back(std::move(var));
  }
  st.set_cost(cost);
  st.set_variance_term(varianceTerm);
  st.set_loss(st.loss() + varianceTerm);
  st.set_seconds_variance(clock.seconds());
}

void GradientEngine::storeReservoirs(Step& s) {
  // Next step's reservoirs: this step's, plus the old ones this step did not replace (Alg. 8).
  Stopwatch clock;
  const GradientRequest& req = s.req;
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
    const bool unmoved = scene_.geometryVersion() == 0 && scene_.cameraVersion() == 0;
    const bool everyPixel = s.batches.empty();
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
              if (!s.batches[k].contains(pixel)) {
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
  tbb::parallel_invoke([&] { if (s.restirPrimal) rebuild(s.session.primal, s.newPrimal, preserved[0], carried[0], treeUsed[0]); },
                       [&] { if (s.restirDerivative) rebuild(s.session.derivative, s.newDerivative, preserved[1], carried[1], treeUsed[1]); });
  v1::GradientStats& st = s.out.stats;
  st.set_reservoirs_preserved(preserved[0] + preserved[1]);
  st.set_reservoirs_carried(carried[0] + carried[1]);
  st.set_kd_trees_built(uint64_t(treeUsed[0] + treeUsed[1]));
  st.set_seconds_reservoir(st.seconds_reservoir() + clock.seconds());
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
  // Independent whatever the job's sampler: the Bessel-corrected spread of a pixel's samples below
  // estimates one sample's variance only when the samples are independent (stratified ones are
  // correlated).
  spec.sampler = SamplerKind::Independent;
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
  spec.sampler = opt_.sampler;
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
  spec.sampler = opt_.sampler;
  PassOutput deriv = runPass(scene_, *estimator, spec, *scratch_);
  drops += primal.drops;
  drops += deriv.drops;
  s.passes = 1;
  s.adjointAbs.resize(cellPixel.size() * 3);
  s.adjointSq.resize(cellPixel.size() * 3);
  s.derivSq.resize(cellPixel.size());
  for (size_t c = 0; c < cellPixel.size(); ++c) {
    for (int ch = 0; ch < 3; ++ch) {
      const float a = adjoint.data()[cellPixel[c] * 3 + size_t(ch)];
      s.adjointAbs[3 * c + size_t(ch)] = std::abs(a);
      s.adjointSq[3 * c + size_t(ch)] = a * a;
    }
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
