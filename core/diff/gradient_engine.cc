#include "core/diff/gradient_engine.h"

#include <tbb/blocked_range2d.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>

#include "core/diff/bsdf_adjoint.h"
#include "core/diff/gradient_sink.h"
#include "core/diff/path_replay.h"
#include "core/error.h"
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

// Stage-1 passes (pixel-sampling maps) draw on random streams of their own.
enum Pass { kPrimal = 0, kDerivative = 1, kStage1Primal = 2, kStage1Derivative = 3 };

// Everything one camera sample produces.
struct CameraSample {
  bool hit = false;
  SurfaceHit surface;
  Bsdf bsdf;
  int material = -1;
  int count = 0;
  DirectPath paths[4];
  bool hasReservoir = false;
  StoredReservoir reservoir;

  void add(const DirectPath& p) {
    if (count < 4) paths[count++] = p;
  }
  Rgb value() const {
    Rgb v(0.f);
    for (int i = 0; i < count; ++i) v += paths[i].contribution();
    return v;
  }
};

DirectPath emissionPath(Rgb weight, Rgb emission, const LightSampleRef& ref, float perUnit) {
  DirectPath p;
  p.weight = weight;
  p.bsdfValue = Rgb(1.f);
  p.emission = emission;
  p.throughBsdf = false;
  p.light = ref;
  p.emissionPerUnit = perUnit;
  return p;
}

// Emission reached by ray (o, d): an environment on a miss, a front-facing area light on a hit.
// With MIS, `from` is the shading point the ray left (the NEE half computes its pdf from there
// too, so the two weights sum to one) and misPdfBsdf the direction's BSDF pdf.
bool emissionAlong(const Scene& scene, Vec3 o, Vec3 d, Rgb weight, CameraSample& cs, bool useMis = false,
                   Vec3 from = Vec3(0.f), float misPdfBsdf = 0.f) {
  SurfaceHit h;
  bool any = scene.intersect(o, d, h);
  const auto& sel = scene.lightSelection();
  if (!any) {
    bool added = false;
    for (uint32_t li : scene.infiniteLights()) {
      const Light& l = scene.lights[li];
      Rgb Le = environmentRadiance(l, d);
      if (isBlack(Le)) continue;
      float w = useMis ? powerHeuristic(misPdfBsdf, sel.pmf(li) * environmentPdf(l, d)) : 1.f;
      LightSampleRef ref;
      ref.light = li;
      ref.setDirection(d);
      cs.add(emissionPath(weight * w, Le, ref, l.kind == LightKind::ConstantEnvironment ? l.scale : 0.f));
      added = true;
    }
    return added;
  }
  int li = scene.meshLight[h.mesh];
  if (li < 0) return false;
  const Light& l = scene.lights[size_t(li)];
  Rgb Le = areaEmission(l, h.ng, -d);
  if (isBlack(Le)) return false;
  float w = useMis ? powerHeuristic(misPdfBsdf, sel.pmf(size_t(li)) * areaLightPdf(l, from, h.p, h.ng)) : 1.f;
  LightSampleRef ref;
  ref.light = uint32_t(li);
  ref.tri = h.tri;
  ref.b1 = h.b1;
  ref.b2 = h.b2;
  cs.add(emissionPath(weight * w, Le, ref, l.scale));
  return true;
}

}  // namespace

bool visibleFromCamera(const Scene& scene, const Camera& cam, Vec3 p, Vec3 n) {
  Vec3 d = p - cam.eye;
  float z = dot(d, cam.forward);
  if (!(z > 0.f)) return false;
  float aspect = float(scene.width) / float(scene.height);
  float sx = dot(d, cam.right) / z, sy = dot(d, cam.up) / z;
  if (std::abs(sx) > cam.tanHalfFovY * aspect || std::abs(sy) > cam.tanHalfFovY) return false;
  Vec3 o = offsetOrigin(p, n, -d);
  Vec3 dir;
  float tmax;
  return !scene.occludedSegment(o, cam.eye, dir, tmax);
}

GradientEngine::GradientEngine(Scene& scene, const ParameterRegistry& params, std::vector<Image> targets, GradientOptions options)
    : scene_(scene), params_(params), targets_(std::move(targets)), opt_(options),
      scratch_(std::make_unique<Scratch>(GradientScratch(params.size()))) {
  if (opt_.sppPrimal <= 0 || opt_.sppGradient <= 0) throw InputError("spp_primal and spp_gradient must be positive");
  if (opt_.restir.candidates <= 0) throw InputError("ris_candidates must be positive");
  if (!(opt_.radiusPixels > 0.f)) throw InputError("restir radius_pixels must be positive");
  if (opt_.maxDepth < 1) throw InputError("max_depth must be at least 1");
  if (opt_.maxDepth > 1 && opt_.method != GradientMethod::Pt)
    throw InputError("max_depth > 1 (path replay) needs method pt: NEE + MIS at every vertex");
}

// Per-thread dense gradient accumulators, kept across passes (no per-pass allocation).
struct GradientEngine::Scratch : tbb::enumerable_thread_specific<GradientScratch> {
  using tbb::enumerable_thread_specific<GradientScratch>::enumerable_thread_specific;
};

GradientEngine::~GradientEngine() = default;

struct GradientEngine::PassResult {
  Image image;
  uint64_t nonFinite = 0;
  RayStats rays;
  RestirCounters restir;
};

// One pass over all pixels of one view. pass = kPrimal renders; kDerivative backpropagates
// `adjoint` (dL/dI) into `gradient`. `store` (if set) receives one reservoir per pixel sample.
GradientEngine::PassResult GradientEngine::runPass(int view, int pass, const GradientRequest& req, const ReservoirStore* prev,
                                                   StoredReservoir* store, const Image* adjoint,
                                                   std::vector<double>* gradient, const PixelBatch* batch,
                                                   std::vector<float>* derivSq) {
  const int W = scene_.width, H = scene_.height;
  const int spp = pass == kPrimal ? opt_.sppPrimal : pass == kDerivative ? opt_.sppGradient : 1;
  const bool backprop = gradient || derivSq;
  const Camera& cam = scene_.cameras[size_t(view)];
  const bool useRestir = opt_.method == GradientMethod::Restir && !(pass == kDerivative && opt_.forwardOnly);
  // Where ReSTIR looks for a neighbour (one, by default) when last step rendered this view:
  //  1. the reservoir a random pixel within the reuse radius left behind (offsets uniform over the
  //     disk one pixel short of the radius, so that sub-pixel jitter rarely fails the world-space
  //     test). Random rather than this pixel's own predecessor: on ajar (150 Adam steps, seeds
  //     1-3) the own predecessor ended at 1.01-1.04x the starting parameter error, the kd-tree's
  //     nearest at 0.94-0.96x and a random neighbour at 0.88-0.91x: mixing keeps one lucky sample
  //     from pushing the same texel step after step;
  //  2. this pixel's own predecessor;
  //  3. a search: last step's pixels around this one when they hold every stored reservoir (one
  //     view, nothing preserved, unmoved geometry), else the kd-tree. A point within the world
  //     radius R px * t of this one projects at most R (t/z)(1 + |x/z|) pixels away per axis
  //     (pinhole camera), plus one pixel for the two points' jitter: that bounds the window.
  const uint32_t* probeItems = useRestir && prev && opt_.pixelNeighbours ? prev->pixelSlots(view) : nullptr;
  const bool windowSearch = probeItems && prev->slotsCover(view);
  std::vector<std::pair<int, int>> probeOffsets;
  int windowHalf = 0;
  if (probeItems) {
    const int r = std::max(0, int(std::floor(opt_.radiusPixels - 1.f)));
    for (int dy = -r; dy <= r; ++dy)
      for (int dx = -r; dx <= r; ++dx)
        if (dx * dx + dy * dy <= r * r) probeOffsets.push_back({dx, dy});
    const float tx = cam.tanHalfFovY * float(W) / float(H), ty = cam.tanHalfFovY;
    windowHalf = int(std::ceil(opt_.radiusPixels * (1.f + std::max(tx, ty)) * std::sqrt(1.f + tx * tx + ty * ty))) + 1;
  }
  const float pixelFootprint = opt_.radiusPixels * 2.f * cam.tanHalfFovY / float(H);  // world radius per unit distance
  // Independent random streams per pass: the same step never reuses primal numbers for derivatives.
  const uint64_t passSeed = mix64(req.seed * 2 + uint64_t(pass) + 0x51ed27u);
  constexpr int kTile = 16;
  const int tilesX = (W + kTile - 1) / kTile, tilesY = (H + kTile - 1) / kTile;
  std::vector<TileGradient> tiles(gradient ? size_t(tilesX) * size_t(tilesY) : 0);
  PassResult res;
  res.image = Image(W, H, 3);
  std::mutex mergeMutex;
  // Stage 1 measures one path's squared parameter derivatives per pixel instead of summing them.
  auto finishPath = [&](PathGradient& pg, GradientScratch& scratch, uint64_t pixel) {
    if (derivSq) {
      double sq = 0;
      for (const auto& e : pg.entries()) sq += double(e.second) * double(e.second);
      if (std::isfinite(sq)) (*derivSq)[size_t(pixel)] += float(sq);
      pg.clear();
    } else {
      scratch.commit(pg);
    }
  };

  std::atomic<bool> cancelled{false};
  tbb::parallel_for(tbb::blocked_range<int>(0, tilesX * tilesY), [&](const tbb::blocked_range<int>& range) {
    RayStats rays;
    RestirCounters counters;
    uint64_t nonFinite = 0;
    PathContext ctx{&rays, nullptr};
    PathGradient pathGrad;
    GradientScratch& scratch = scratch_->local();
    for (int tile = range.begin(); tile < range.end(); ++tile) {
      // Cancellation is checked per 16x16 tile (TBB's chunks hold many tiles).
      if (cancelled.load(std::memory_order_relaxed) || (req.cancel && req.cancel->load(std::memory_order_relaxed))) {
        cancelled = true;
        break;
      }
      int tx = tile % tilesX, ty = tile / tilesX;
      for (int y = ty * kTile; y < std::min(H, (ty + 1) * kTile); ++y)
        for (int x = tx * kTile; x < std::min(W, (tx + 1) * kTile); ++x) {
          const uint64_t pixel = uint64_t(y) * uint64_t(W) + uint64_t(x);
          if (batch && !batch->contains(size_t(pixel))) {  // not in this mini-batch
            if (store)
              for (int s = 0; s < spp; ++s) store[size_t(pixel) * size_t(spp) + size_t(s)].mesh = UINT32_MAX;
            continue;
          }
          const uint64_t pixelHash = RngKey{passSeed, req.step, uint64_t(view), pixel, 0}.pixelHash();
          double acc[3] = {0, 0, 0};
          // A pixel drawn c times into the mini-batch gets c times the samples, each on streams of
          // its own (see PixelBatch); only the first draw's reservoirs are stored.
          const int samples = spp * int(batch ? batch->draws[size_t(pixel)] : 1u);
          Rgb pixelAdjoint = adjoint ? adjoint->rgb(x, y) / float(samples) : Rgb(0.f);
          for (int sample = 0; sample < samples; ++sample) {
            const int s = sample % spp;  // the reservoir slot this sample reads its hints from
            Sampler sampler(RngKey::withSample(pixelHash, uint64_t(sample)));
            Vec3 d = cam.direction(float(x) + sampler.next1D(), float(y) + sampler.next1D(), W, H);
            if (opt_.maxDepth > 1) {  // multi-bounce: path tracing, derivatives by path replay
              PathReplaySettings prs;
              prs.maxDepth = opt_.maxDepth;
              Rgb v = pathReplayRadiance(scene_, cam.eye, d, sampler, prs, &rays);
              if (!isFinite(v)) {
                ++nonFinite;
                continue;
              }
              acc[0] += v.x; acc[1] += v.y; acc[2] += v.z;
              if (!backprop) continue;
              pathReplayBackprop(scene_, params_, cam.eye, d, sampler, prs, v, pixelAdjoint, pathGrad, &rays);
              finishPath(pathGrad, scratch, pixel);
              continue;
            }
            CameraSample cs;
            ++rays.camera;
            SurfaceHit& hit = cs.surface;
            if (!scene_.intersect(cam.eye, d, hit)) {
              emissionAlong(scene_, cam.eye, d, Rgb(1.f), cs);
            } else {
              cs.hit = true;
              if (int li = scene_.meshLight[hit.mesh]; li >= 0) {
                const Light& l = scene_.lights[size_t(li)];
                Rgb Le = areaEmission(l, hit.ng, -d);
                if (!isBlack(Le)) {
                  LightSampleRef ref;
                  ref.light = uint32_t(li);
                  ref.tri = hit.tri;
                  ref.b1 = hit.b1;
                  ref.b2 = hit.b2;
                  cs.add(emissionPath(Rgb(1.f), Le, ref, l.scale));
                }
              }
              cs.material = scene_.meshMaterial[hit.mesh];
              cs.bsdf = scene_.materials[size_t(cs.material)].at(hit.uv);
              ShadingPoint sp{&hit, &cs.bsdf, Frame(hit.ns), Vec3(), -d};
              sp.wo = sp.frame.toLocal(-d);
              if (cs.bsdf.isDelta()) {
                // Direct illumination through a delta lobe: only the emission it reaches.
                auto bs = cs.bsdf.sample(sp.wo, sampler.next1D(), {sampler.next1D(), sampler.next1D()});
                if (bs) {
                  Vec3 wi = sp.frame.toWorld(bs->wi);
                  ++rays.bounce;
                  emissionAlong(scene_, offsetOrigin(hit.p, hit.ng, wi), wi, bs->weight, cs);
                }
              } else if (opt_.method == GradientMethod::Pt) {
                DirectPath p;
                if (sampleDirectNee(scene_, sp, sampler, &ctx, p)) cs.add(p);
                // The BSDF-sampled half of MIS.
                auto bs = cs.bsdf.sample(sp.wo, sampler.next1D(), {sampler.next1D(), sampler.next1D()});
                if (bs && !bs->delta) {
                  Vec3 wi = sp.frame.toWorld(bs->wi);
                  if (dot(wi, hit.ng) * dot(-d, hit.ng) > 0.f) {
                    ++rays.bounce;
                    int before = cs.count;
                    Rgb f = cs.bsdf.eval(sp.wo, bs->wi);
                    if (emissionAlong(scene_, offsetOrigin(hit.p, hit.ng, wi), wi, Rgb(1.f / bs->pdf), cs, true, hit.p, bs->pdf)) {
                      for (int i = before; i < cs.count; ++i) {
                        cs.paths[i].throughBsdf = true;
                        cs.paths[i].bsdfValue = f;
                        cs.paths[i].wiLocal = bs->wi;
                      }
                    }
                  }
                }
              } else if (!useRestir) {
                DirectPath p;
                if (sampleDirectRis(scene_, sp, sampler, opt_.restir.candidates, opt_.restir.visibilityInTarget, &ctx, p)) cs.add(p);
              } else {
                DirectPath p;
                Reservoir r;
                RestirSettings settings = opt_.restir;
                settings.radius = pixelFootprint * hit.t;
                uint32_t tryFirst[2] = {UINT32_MAX, UINT32_MAX};
                NeighbourHints hints;
                if (probeItems) {
                  const auto& o = probeOffsets[std::min(probeOffsets.size() - 1, size_t(sampler.next1D() * float(probeOffsets.size())))];
                  int px = x + o.first, py = y + o.second;
                  if (px >= 0 && py >= 0 && px < W && py < H) tryFirst[0] = probeItems[(size_t(py) * size_t(W) + size_t(px)) * size_t(spp) + size_t(s)];
                  tryFirst[1] = probeItems[size_t(pixel) * size_t(spp) + size_t(s)];
                  hints.items = tryFirst;
                  hints.count = 2;
                  if (windowSearch) {
                    hints.slots = probeItems;
                    hints.x = x;
                    hints.y = y;
                    hints.width = W;
                    hints.height = H;
                    hints.spp = spp;
                    hints.half = windowHalf;
                  }
                }
                uint8_t deltaKnown = 0, deltaVisible = 0;
                if (sampleDirectRestir(scene_, sp, sampler, settings, prev, &ctx, p, r, &counters, &hints, &deltaKnown, &deltaVisible))
                  cs.add(p);
                cs.reservoir.deltaKnown = deltaKnown;
                cs.reservoir.deltaVisible = deltaVisible;
                cs.hasReservoir = true;
                cs.reservoir.r = StoredSample(r);
                cs.reservoir.mesh = hit.mesh;
                cs.reservoir.tri = hit.tri;
                cs.reservoir.b1 = hit.b1;
                cs.reservoir.b2 = hit.b2;
                cs.reservoir.view = uint16_t(view);
                cs.reservoir.p = hit.p;
                cs.reservoir.setNormal(hit.ns);
              }
            }
            if (store && sample < spp) {
              StoredReservoir& slot = store[size_t(pixel) * size_t(spp) + size_t(s)];
              slot = cs.reservoir;
              if (!cs.hasReservoir) slot.r = StoredSample();  // misses and delta surfaces: empty (M = 0)
              if (!cs.hasReservoir) slot.mesh = UINT32_MAX;
            }
            Rgb v = cs.value();
            if (!isFinite(v)) {
              ++nonFinite;
              continue;
            }
            acc[0] += v.x; acc[1] += v.y; acc[2] += v.z;
            if (!backprop) continue;
            // Backpropagate dL/dI through each path's parameter-dependent factors.
            for (int i = 0; i < cs.count; ++i) {
              const DirectPath& p = cs.paths[i];
              if (p.throughBsdf && hasBsdfParameters(params_, cs.material)) {
                Vec3 wo = Frame(hit.ns).toLocal(-d);
                addBsdfGradient(params_, scene_, cs.material, hit.uv, cs.bsdf.evalDerivatives(wo, p.wiLocal),
                                pixelAdjoint * p.weight * p.emission, pathGrad);
              }
              int lOff = params_.intensityOffset(int(p.light.light));
              if (lOff >= 0 && p.emissionPerUnit > 0.f) {
                Rgb g = pixelAdjoint * p.weight * p.bsdfValue * p.emissionPerUnit;
                for (int c = 0; c < 3; ++c) pathGrad.add(uint32_t(lOff + c), g[c]);
              }
              finishPath(pathGrad, scratch, pixel);
            }
          }
          res.image.setRgb(x, y, Rgb(float(acc[0] / samples), float(acc[1] / samples), float(acc[2] / samples)));
        }
      if (gradient) scratch.flush(tiles[size_t(tile)]);
    }
    std::lock_guard lock(mergeMutex);  // integer counters: order does not matter
    res.rays += rays;
    res.nonFinite += nonFinite;
    res.restir.neighboursUsed += counters.neighboursUsed;
    res.restir.shadingPoints += counters.shadingPoints;
    res.restir.sumM += counters.sumM;
  });
  if (cancelled) throw EvaluationCancelled{};
  if (gradient) {
    for (auto& t : tiles) {  // fixed tile order: deterministic for any thread count
      t.reduceInto(*gradient);
      res.nonFinite += t.nonFinite();
    }
  }
  return res;
}

GradientResult GradientEngine::evaluate(const std::vector<float>& theta, const GradientRequest& req, EngineSession& session) {
  if (req.views.empty()) throw InputError("gradient request: no views");
  for (int v : req.views)
    if (v < 0 || size_t(v) >= scene_.cameras.size()) throw InputError("gradient request: view " + std::to_string(v) + " out of range");
  if (!req.renderOnly)
    for (int v : req.views)
      if (size_t(v) >= targets_.size() || targets_[size_t(v)].empty())
        throw InputError("gradient request: no target image for view " + std::to_string(v));
  params_.write(theta, scene_);
  GradientResult out;
  out.gradient.assign(params_.size(), 0.0);
  GradientStats& st = out.stats;
  const size_t pixels = size_t(scene_.width) * size_t(scene_.height);
  const bool restir = opt_.method == GradientMethod::Restir;
  const bool restirDerivative = restir && !opt_.forwardOnly;

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
        t0 = std::chrono::steady_clock::now();
        map = buildPixelMap(po, runStage1(v, req), req.step);
        st.secondsStage1 += secondsSince(t0);
      }
      batches.push_back(drawPixelBatch(map, n, RngKey{req.seed, req.step, uint64_t(v), 0x9e1ec7u, 0}));
    }
  }
  auto batchOf = [&](size_t k) { return batches.empty() ? nullptr : &batches[k]; };
  auto weightsOf = [&](size_t k) { return batches.empty() ? nullptr : &batches[k].weight; };

  // Primal pass: images, loss, dL/dI.
  t0 = std::chrono::steady_clock::now();
  // Next step's reservoirs, one slot per pixel sample, written in place by the passes into buffers
  // recycled from the step before last (no fresh pages to fault in each step). runPass writes
  // every slot (a reservoir, or mesh = UINT32_MAX), so the old contents never leak through.
  std::vector<StoredReservoir> newPrimal, newDerivative;
  if (restir) {
    newPrimal = session.primal.takeRecycled();
    newPrimal.resize(req.views.size() * pixels * size_t(opt_.sppPrimal));
  }
  std::vector<Image> adjoints(req.views.size());
  RestirCounters counters;
  auto checkCancel = [&] {
    if (req.cancel && req.cancel->load()) throw EvaluationCancelled{};
  };
  for (size_t k = 0; k < req.views.size(); ++k) {
    checkCancel();
    StoredReservoir* store = restir ? newPrimal.data() + k * pixels * size_t(opt_.sppPrimal) : nullptr;
    PassResult pr = runPass(req.views[k], kPrimal, req, restir ? &session.primal : nullptr, store, nullptr, nullptr, batchOf(k));
    st.pixelsTraced += batches.empty() ? pixels : size_t(std::count_if(batches[k].draws.begin(), batches[k].draws.end(), [](uint32_t c) { return c > 0; }));
    st.rays += pr.rays;
    st.nonFiniteSamples += pr.nonFinite;
    counters.neighboursUsed += pr.restir.neighboursUsed;
    counters.shadingPoints += pr.restir.shadingPoints;
    counters.sumM += pr.restir.sumM;
    if (!req.renderOnly) {
      int batch = req.batchViews > 0 ? req.batchViews : int(req.views.size());
      double l = imageLoss(opt_.loss, pr.image, targets_[size_t(req.views[k])], &adjoints[k], batch, weightsOf(k));
      st.viewLoss.push_back(l * double(batch));
      st.loss += l;
    }
    out.renders.push_back(std::move(pr.image));
  }
  st.secondsPrimal = secondsSince(t0);

  // Derivative pass: fresh paths weighted by dL/dI (or, during burn-in, only the reservoirs).
  t0 = std::chrono::steady_clock::now();
  if (!req.renderOnly || restirDerivative) {
    if (restirDerivative) {
      newDerivative = session.derivative.takeRecycled();
      newDerivative.resize(req.views.size() * pixels * size_t(opt_.sppGradient));
    }
    for (size_t k = 0; k < req.views.size(); ++k) {
      checkCancel();
      StoredReservoir* store = restirDerivative ? newDerivative.data() + k * pixels * size_t(opt_.sppGradient) : nullptr;
      PassResult pr = runPass(req.views[k], kDerivative, req, restirDerivative ? &session.derivative : nullptr, store,
                              req.renderOnly ? nullptr : &adjoints[k],
                              req.renderOnly ? nullptr : &out.gradient, batchOf(k));
      st.rays += pr.rays;
      st.nonFiniteSamples += pr.nonFinite;
    }
  }
  st.secondsDerivative = secondsSince(t0);

  // Next step's reservoirs: this step's, plus the old ones no view of the batch could see (Alg. 8).
  t0 = std::chrono::steady_clock::now();
  auto rebuild = [&](ReservoirStore& chain, std::vector<StoredReservoir>& fresh, size_t& preserved, int& treeUsed) {
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
    // Alg. 8: keep old reservoirs that no view of this batch can see. When the batch holds every
    // view and the geometry never moved, each old reservoir was seen by one of these views and is
    // visible still, so none would be kept: skip the visibility rays.
    bool allViews = (req.allSessionViews || req.views.size() == scene_.cameras.size()) && scene_.geometryVersion() == 0;
    if (opt_.preserveOccluded && !allViews) {
      // On unmoved geometry a reservoir is visible from the camera whose primary ray found it: no
      // ray when that view is in the batch. The others trace one ray per view until one sees
      // them, in parallel; the kept ones are appended in their old order (deterministic).
      const std::vector<StoredReservoir>& old = chain.items();
      const bool unmoved = scene_.geometryVersion() == 0;
      std::vector<uint8_t> keep(old.size());
      tbb::parallel_for(tbb::blocked_range<size_t>(0, old.size(), 2048), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i < range.end(); ++i) {
          const StoredReservoir& r = old[i];
          bool seen = unmoved && std::find(req.views.begin(), req.views.end(), int(r.view)) != req.views.end();
          for (size_t k = 0; !seen && k < req.views.size(); ++k)
            seen = visibleFromCamera(scene_, scene_.cameras[size_t(req.views[k])], r.p, r.n());
          keep[i] = !seen;
        }
      });
      for (size_t i = 0; i < old.size(); ++i)
        if (keep[i]) {
          next.push_back(old[i]);
          ++preserved;
        }
    }
    // Fresh items carry their hit's position; kept ones were re-placed by this step's refresh().
    treeUsed = chain.hasIndex() ? 1 : 0;
    chain.assignPlaced(std::move(next), scene_.geometryVersion(), std::move(slots));
  };
  // The two chains are independent: side by side.
  size_t preserved[2] = {0, 0};
  int treeUsed[2] = {0, 0};
  tbb::parallel_invoke([&] { if (restir) rebuild(session.primal, newPrimal, preserved[0], treeUsed[0]); },
                       [&] { if (restirDerivative) rebuild(session.derivative, newDerivative, preserved[1], treeUsed[1]); });
  st.reservoirsPreserved += preserved[0] + preserved[1];
  st.kdTreesBuilt += treeUsed[0] + treeUsed[1];
  st.secondsReservoirUpdate += secondsSince(t0);
  st.reservoirs = session.primal.size() + session.derivative.size();
  if (counters.shadingPoints) {
    st.meanNeighbours = double(counters.neighboursUsed) / double(counters.shadingPoints);
    st.meanM = counters.sumM / double(counters.shadingPoints);
  }
  return out;
}

Stage1 GradientEngine::runStage1(int view, const GradientRequest& req) {
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
  // dL/dI from one primal sample per cell (no reservoirs: stage 1 leaves the chains alone).
  PassResult primal = runPass(view, kStage1Primal, req, nullptr, nullptr, nullptr, nullptr, &cellPixels);
  Image adjoint;
  imageLoss(opt_.loss, primal.image, targets_[size_t(view)], &adjoint, 1, &cellPixels.weight);
  // Squared parameter derivatives of one path per cell (Eq. 16), with a unit adjoint.
  Image ones(s.width, s.height, 3);
  for (size_t p : cellPixel)
    for (int c = 0; c < 3; ++c) ones.data()[p * 3 + size_t(c)] = 1.f;
  std::vector<float> derivSq(pixels, 0.f);
  runPass(view, kStage1Derivative, req, nullptr, nullptr, &ones, nullptr, &cellPixels, &derivSq);
  s.adjoint.resize(cellPixel.size() * 3);
  s.derivSq.resize(cellPixel.size());
  for (size_t c = 0; c < cellPixel.size(); ++c) {
    for (int ch = 0; ch < 3; ++ch) s.adjoint[3 * c + size_t(ch)] = adjoint.data()[cellPixel[c] * 3 + size_t(ch)];
    s.derivSq[c] = derivSq[cellPixel[c]];
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
