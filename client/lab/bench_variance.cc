// invr-lab bench variance: the figures of Yan et al. 2024 on the zoo's variance-aware jobs.
//   rings     dV/d roughness, unbiased against detached at equal time, against a long
//             central-difference reference (common random numbers, h checked against h/2);
//             and the K sweep of the variance-aware reconstruction (Fig. 6).
//   spot      the mean per-pixel variance at the per-pixel probabilities the job reaches, against
//             selection by power and against the best single global probability; the map against
//             an oracle scan of p on random cells (Fig. 8).
//   roulette  time x variance (rays per sample x variance) at the survival the job reaches,
//             against q = 1 and throughput roulette (Fig. 9).
//   every     the variance pass's cost per sample over the plain derivative pass's.
// Every figure is measured in the run that prints it; nothing here fails on a figure.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>

#include "client/lab/bench.h"
#include "client/lab/lab_commands.h"
#include "core/diff/interior_estimator.h"
#include "core/diff/pass_driver.h"
#include "core/job/problem.h"
#include "core/job/zoo_jobs.h"
#include "core/error.h"
#include "core/math/statistics.h"
#include "core/stopwatch.h"
#include "core/lights/light_selection.h"
#include "core/math/rng.h"
#include "core/optim/local_run.h"

namespace invr::cli {

namespace {

// A pass over every pixel (or a batch) with the job's PT estimator at the scene's current state.
PassOutput tracePass(const Problem& p, int view, uint64_t stream, uint64_t step, int spp, const PixelBatch* batch = nullptr,
                     bool squares = false) {
  GradientScratchPool pool(p.params.size());
  auto est = makePtEstimator({*p.scene, p.params, p.gradient, view, spp, nullptr});
  PassSpec s;
  s.kind = PassKind::Primal;
  s.squares = squares;
  s.view = view;
  s.stream = stream;
  s.step = step;
  s.spp = spp;
  s.batch = batch;
  return runPass(*p.scene, *est, s, pool);
}

// V: the mean over pixels and channels of one sample's variance, unbiased: mean(F^2) - I1 mean(F)
// with I1 an independent render (Eq. 18).
double varianceEstimate(const PassOutput& independent, const PassOutput& squares) {
  double v = 0;
  for (size_t i = 0; i < squares.image.data().size(); ++i)
    v += double(squares.secondMoment.data()[i]) - double(independent.image.data()[i]) * double(squares.image.data()[i]);
  return v / double(squares.image.data().size());
}

// Per-pixel Bessel variance of one sample over `spp` samples, averaged over the pixels of `batch`
// (all pixels when null) and channels.
double besselVariance(const PassOutput& pr, int spp, const PixelBatch* batch) {
  double v = 0;
  size_t n = 0;
  for (size_t px = 0; px < pr.image.data().size() / 3; ++px) {
    if (batch && !batch->contains(px)) continue;
    for (int c = 0; c < 3; ++c) {
      const double m = pr.image.data()[px * 3 + size_t(c)];
      v += (double(pr.secondMoment.data()[px * 3 + size_t(c)]) - m * m) * double(spp) / double(spp - 1);
    }
    n += 3;
  }
  return v / double(std::max<size_t>(1, n));
}

// dV/dtheta from the variance pass (unit weight per pixel and channel), I1 a 1-spp primal render.
std::vector<double> varianceGradient(const Problem& p, uint64_t seed, uint64_t step, bool detached, GradientOptions o) {
  const Scene& s = *p.scene;
  o.variance.detached = detached;
  PassOutput primal = tracePass(p, 0, streamSeed(seed, kPrimalStream), step, 1);
  GradientScratchPool pool(p.params.size());
  auto est = makePtEstimator({s, p.params, o, 0, o.variance.spp, nullptr});
  Image adjoint(s.width, s.height, 3);
  const float a = float(1.0 / (double(s.width) * double(s.height) * 3.0));
  std::fill(adjoint.data().begin(), adjoint.data().end(), a);
  PassSpec spec;
  spec.kind = PassKind::Variance;
  spec.stream = streamSeed(seed, kVarianceStream);
  spec.step = step;
  spec.spp = o.variance.spp;
  spec.adjoint = &adjoint;
  spec.mean = &primal.image;
  spec.detached = detached;
  std::vector<double> g(p.params.size(), 0.0);
  runPass(s, *est, spec, pool, &g);
  return g;
}

// The variance pass's cost per sample over the derivative pass's, medians of interleaved steps.
double overheadRatio(Problem& p, const std::vector<Image>& targets, int steps) {
  GradientEngine engine(*p.scene, p.params, targets, p.gradient);
  EngineSession session;
  std::vector<double> ratios;
  for (int i = 0; i < steps; ++i) {
    GradientRequest r;
    r.views = viewsForStep(p, uint64_t(i));
    r.step = uint64_t(i);
    r.seed = p.seed;
    GradientResult g = engine.evaluate(r, session);
    if (i == 0) continue;  // warm-up
    ratios.push_back((g.stats.seconds_variance() / p.gradient.variance.spp) / (g.stats.seconds_derivative() / p.gradient.sppGradient));
  }
  std::sort(ratios.begin(), ratios.end());
  return ratios.empty() ? NAN : ratios[ratios.size() / 2];
}

BenchReport benchRings(const VarianceBenchArgs& a) {
  BenchReport rep("variance");
  rep.text("scene", "rings");
  Problem p = buildProblem(zooJob("rings"));
  std::vector<Image> targets = renderTargets(p);
  p.params.write(p.initial, *p.scene);
  const double theta0 = p.initial[0];
  rep.number("roughness", theta0);

  // Reference: central differences of V with common random numbers, at h and h/2.
  const double h = a.fdStep;
  MeanSe fd, fdHalf, richardson;
  Stopwatch t0;
  for (int r = 0; r < a.fdReps; ++r) {
    double v[4];
    const double at[4] = {theta0 + h, theta0 - h, theta0 + h / 2, theta0 - h / 2};
    for (int k = 0; k < 4; ++k) {
      std::vector<float> th = p.initial;
      th[0] = float(at[k]);
      p.params.write(th, *p.scene);
      PassOutput i1 = tracePass(p, 0, streamSeed(a.seed, kPrimalStream), uint64_t(r), a.fdSpp);
      PassOutput sq = tracePass(p, 0, streamSeed(a.seed, kVarianceStream), uint64_t(r), a.fdSpp, nullptr, true);
      v[k] = varianceEstimate(i1, sq);
    }
    const double full = (v[0] - v[1]) / (2 * h), half = (v[2] - v[3]) / h;
    fd.add(full);
    fdHalf.add(half);
    // Richardson: the O(h^2) error of central differences cancels; per evaluation, so the
    // standard error counts the two steps' correlation.
    richardson.add((4 * half - full) / 3);
  }
  p.params.write(p.initial, *p.scene);
  rep.number("reference_seconds", t0.seconds(), "s");
  rep.value("fd_steps", {{"h", h}, {"mean_h", fd.mean()}, {"se_h", fd.se()}, {"mean_half_h", fdHalf.mean()}, {"se_half_h", fdHalf.se()}},
            "h = " + BenchReport::fmt(h) + ": " + BenchReport::fmt(fd.mean()) + " +- " + BenchReport::fmt(fd.se()) + ", h/2: " +
                BenchReport::fmt(fdHalf.mean()) + " +- " + BenchReport::fmt(fdHalf.se()) + " (" + std::to_string(a.fdReps) + " x " +
                std::to_string(a.fdSpp) + " spp, common random numbers)");
  rep.value("fd_reference", {{"mean", richardson.mean()}, {"se", richardson.se()}},
            BenchReport::fmt(richardson.mean()) + " +- " + BenchReport::fmt(richardson.se()) + " (Richardson extrapolation of h and h/2)");
  const MeanSe& ref = richardson;

  // Equal time: each estimator gets `seconds`.
  auto run = [&](bool detached, MeanSe& m, double& sqErr, double& seconds) {
    Stopwatch t;
    int i = 0;
    while (t.seconds() < a.seconds || i < 4) {
      double g = varianceGradient(p, a.seed + 1, uint64_t(i), detached, p.gradient)[0];
      m.add(g);
      sqErr += (g - ref.mean()) * (g - ref.mean());
      ++i;
    }
    seconds = t.seconds();
  };
  MeanSe unb, det;
  double sqU = 0, sqD = 0, secU = 0, secD = 0;
  run(false, unb, sqU, secU);
  run(true, det, sqD, secD);
  const double ref2 = ref.mean() * ref.mean();
  auto biasSe = [&](const MeanSe& m) { return (m.mean() - ref.mean()) / std::hypot(m.se(), ref.se()); };
  rep.value("unbiased", {{"mean", unb.mean()}, {"se", unb.se()}, {"evaluations", double(unb.count())}, {"seconds", secU}},
            BenchReport::fmt(unb.mean()) + " +- " + BenchReport::fmt(unb.se()) + " (" + BenchReport::fmt(double(unb.count())) + " evaluations)");
  rep.value("detached", {{"mean", det.mean()}, {"se", det.se()}, {"evaluations", double(det.count())}, {"seconds", secD}},
            BenchReport::fmt(det.mean()) + " +- " + BenchReport::fmt(det.se()) + " (" + BenchReport::fmt(double(det.count())) + " evaluations)");
  rep.number("unbiased_bias_se", biasSe(unb), "SE from the reference (target: within 2)");
  rep.number("detached_bias_se", biasSe(det), "SE from the reference (target: beyond 6)");
  rep.number("relmse_unbiased", sqU / double(unb.count()) / ref2, "per evaluation, equal time");
  rep.number("relmse_detached", sqD / double(det.count()) / ref2, "per evaluation, equal time");
  rep.number("overhead_ratio", overheadRatio(p, targets, a.overheadSteps), "variance pass / derivative pass, per sample (target <= 1.5)");

  // K sweep: the recovered roughness against K (Fig. 6).
  if (!a.ksweep.empty()) {
    BenchReport::Json sweep = BenchReport::Json::object();
    std::string shown;
    std::vector<double> rough;
    for (int K : a.ksweep) {
      v1::JobSpec job = zooJob("rings");
      job.mutable_optimization()->mutable_variance()->set_samples(K);
      if (a.ksweepSteps > 0) job.mutable_optimization()->set_steps(a.ksweepSteps);
      Problem pk = buildProblem(job);
      LocalRunResult res = runLocally(pk);
      rough.push_back(res.theta[0]);
      sweep[std::to_string(K)] = res.theta[0];
      shown += (shown.empty() ? "" : ", ") + std::string("K=") + std::to_string(K) + ": " + BenchReport::fmt(res.theta[0]);
    }
    bool monotone = true;
    for (size_t i = 1; i < rough.size(); ++i) monotone = monotone && rough[i] <= rough[i - 1];
    rep.value("ksweep_roughness", sweep, shown + " (truth " + BenchReport::fmt(p.truth[0]) + ")");
    rep.value("ksweep_monotonic", monotone, monotone ? "yes: larger K, closer to the truth" : "no");
  }
  return rep;
}

void setGlobalSelection(Scene& s, double pSpot) {
  s.sampling.pixelLogits.clear();
  s.sampling.lightLogits = {float(std::log(pSpot)), float(std::log(1 - pSpot))};
  s.updateLightSelection();
}

// Runs a zoo job in this process (`steps` > 0 overrides its steps); leaves its result in p's scene.
LocalRunResult optimiseZooJob(const std::string& name, int steps, Problem& p, BenchReport& rep) {
  v1::JobSpec job = zooJob(name);
  if (steps > 0) job.mutable_optimization()->set_steps(steps);
  p = buildProblem(job);
  Stopwatch t0;
  LocalRunResult res = runLocally(p);
  rep.number("optimisation_seconds", t0.seconds(), "s (" + std::to_string(p.steps) + " steps)");
  return res;
}

BenchReport benchSpot(const VarianceBenchArgs& a) {
  BenchReport rep("variance");
  rep.text("scene", "spot");
  Problem p;
  LocalRunResult res = optimiseZooJob("spot", a.spotSteps, p, rep);
  if (p.scene->lights.size() != 2) throw std::logic_error("bench variance: spot should have two lights");
  const int spp = a.measureSpp;
  const uint64_t stream = streamSeed(a.seed, kVarianceMapStream);
  auto meanVariance = [&] { return besselVariance(tracePass(p, 0, stream, 0, spp, nullptr, true), spp, nullptr); };
  // At the optimised map (runLocally left theta in the scene).
  const double vOpt = meanVariance();
  const SamplingState optimised = p.scene->sampling;
  // By power: the default rule.
  p.scene->sampling.pixelLogits.clear();
  p.scene->sampling.lightLogits.clear();
  p.scene->updateLightSelection();
  const double pPower = p.scene->lightSelection().pmf(0);
  const double vPower = meanVariance();
  // The best single global probability of the spot.
  double vGlobal = INFINITY, pGlobal = 0;
  for (int k = 1; k < 50; ++k) {
    setGlobalSelection(*p.scene, k / 50.0);
    double v = meanVariance();
    if (v < vGlobal) vGlobal = v, pGlobal = k / 50.0;
  }
  rep.number("variance_optimized", vOpt, "mean per-pixel variance of one sample");
  rep.number("variance_power", vPower, "selection by power (p_spot = " + BenchReport::fmt(pPower) + ")");
  rep.number("variance_best_global", vGlobal, "p_spot = " + BenchReport::fmt(pGlobal));
  rep.number("ratio_power_over_optimized", vPower / vOpt, "(target >= 3)");
  rep.number("ratio_global_over_optimized", vGlobal / vOpt, "(target >= 1.3)");

  // Oracle: on random cells of the map, scan p and compare the map's cell with the best one.
  const Scene& s = *p.scene;
  const auto& map = optimised.pixelLogits.at(0);
  Sampler pick(RngKey{a.seed, 7, 0, 0, 0});
  MeanSe ratio, pErr;
  BenchReport::Json cells = BenchReport::Json::array();
  int tried = 0;
  while (int(ratio.count()) < a.oracleCells && tried++ < 50 * a.oracleCells) {
    const int cx = int(pick.nextBits() % uint64_t(map.width)), cy = int(pick.nextBits() % uint64_t(map.height));
    PixelBatch batch;
    batch.weight.assign(size_t(s.width) * size_t(s.height), 0.f);
    batch.draws.assign(batch.weight.size(), 0);
    for (int y = cy * s.height / map.height; y < (cy + 1) * s.height / map.height; ++y)
      for (int x = cx * s.width / map.width; x < (cx + 1) * s.width / map.width; ++x) {
        batch.draws[size_t(y) * size_t(s.width) + size_t(x)] = 1;
        batch.weight[size_t(y) * size_t(s.width) + size_t(x)] = 1.f;
      }
    auto cellVariance = [&] { return besselVariance(tracePass(p, 0, stream, 1, a.oracleSpp, &batch, true), a.oracleSpp, &batch); };
    double best = INFINITY, pBest = 0;
    for (int k = 1; k < 50; ++k) {
      setGlobalSelection(*p.scene, k / 50.0);
      double v = cellVariance();
      if (v < best) best = v, pBest = k / 50.0;
    }
    if (!(best > 1e-8)) continue;  // no light-selection noise in this cell (sky, or unlit)
    p.scene->sampling = optimised;
    p.scene->updateLightSelection();
    const double vMap = cellVariance();
    const size_t n = p.scene->lights.size();
    std::vector<float> pmf = softmax(std::span<const float>(map.logits.data() + (size_t(cy) * size_t(map.width) + size_t(cx)) * n, n));
    ratio.add(vMap / best);
    pErr.add(std::abs(double(pmf[0]) - pBest));
    cells.push_back({{"cell", {cx, cy}}, {"p_map", pmf[0]}, {"p_oracle", pBest}, {"variance_ratio", vMap / best}});
  }
  p.scene->sampling = optimised;
  p.scene->updateLightSelection();
  rep.value("oracle_cells", cells, std::to_string(int(ratio.count())) + " cells of " + std::to_string(a.oracleSpp) + " spp per pixel, p on a 1/50 grid");
  rep.number("oracle_variance_ratio", ratio.mean(), "+- " + BenchReport::fmt(ratio.se()) + " mean over cells of V(map) / V(oracle p) (target <= 1.1)");
  rep.number("oracle_p_abs_error", pErr.mean(), "mean |p_map - p_oracle|");
  rep.number("overhead_ratio", overheadRatio(p, res.targets, a.overheadSteps), "variance pass / derivative pass, per sample (target <= 1.5)");
  return rep;
}

BenchReport benchRoulette(const VarianceBenchArgs& a) {
  BenchReport rep("variance");
  rep.text("scene", "roulette");
  Problem p;
  LocalRunResult res = optimiseZooJob("roulette", a.rouletteSteps, p, rep);
  std::string q;
  for (float x : p.scene->sampling.survival) q += (q.empty() ? "" : ", ") + BenchReport::fmt(x);
  rep.value("survival", std::vector<float>(p.scene->sampling.survival), q);
  struct Cost {
    double rays, variance, seconds;
  };
  const int spp = a.measureSpp;
  auto measure = [&] {
    Stopwatch t;
    PassOutput pr = tracePass(p, 0, streamSeed(a.seed, kVarianceMapStream), 0, spp, nullptr, true);
    return Cost{double(pr.rays.total()) / double(pr.rays.camera), besselVariance(pr, spp, nullptr), t.seconds()};
  };
  const std::vector<float> optimised = p.scene->sampling.survival;
  Cost opt = measure();
  p.scene->sampling.survival.assign(optimised.size(), 1.f);
  Cost one = measure();
  p.scene->sampling.survival.clear();  // throughput roulette after russian_roulette_depth bounces
  Cost thr = measure();
  p.scene->sampling.survival = optimised;
  auto show = [](const Cost& c) {
    return BenchReport::fmt(c.rays) + " rays/sample x " + BenchReport::fmt(c.variance) + " = " + BenchReport::fmt(c.rays * c.variance);
  };
  rep.value("optimized", {{"rays_per_sample", opt.rays}, {"variance", opt.variance}, {"seconds", opt.seconds}}, show(opt));
  rep.value("constant_one", {{"rays_per_sample", one.rays}, {"variance", one.variance}, {"seconds", one.seconds}}, show(one));
  rep.value("throughput_rr", {{"rays_per_sample", thr.rays}, {"variance", thr.variance}, {"seconds", thr.seconds}}, show(thr));
  rep.number("ratio_constant_over_optimized", (one.rays * one.variance) / (opt.rays * opt.variance), "time x variance, q = 1 over optimised (target >= 1.1)");
  rep.number("ratio_throughput_over_optimized", (thr.rays * thr.variance) / (opt.rays * opt.variance),
             "time x variance, throughput roulette over optimised (target >= 1)");
  rep.number("ratio_constant_over_optimized_wallclock", (one.seconds * one.variance) / (opt.seconds * opt.variance),
             "the same with measured seconds instead of rays (noisy)");
  rep.number("overhead_ratio", overheadRatio(p, res.targets, a.overheadSteps), "variance pass / derivative pass, per sample (target <= 1.5)");
  return rep;
}

}  // namespace

std::vector<BenchReport> benchVariance(const VarianceBenchArgs& a) {
  std::vector<BenchReport> out;
  for (const std::string& s : {std::string("rings"), std::string("spot"), std::string("roulette")}) {
    if (a.scene != "all" && a.scene != s) continue;
    out.push_back(s == "rings" ? benchRings(a) : s == "spot" ? benchSpot(a) : benchRoulette(a));
  }
  return out;
}

VarianceBenchArgs quickVarianceBenchArgs() {
  VarianceBenchArgs a;
  a.fdReps = 24;
  a.seconds = 2;
  a.ksweep = {1, 64};
  a.ksweepSteps = 60;
  a.spotSteps = 60;
  a.rouletteSteps = 60;
  a.measureSpp = 16;
  a.oracleCells = 2;
  a.oracleSpp = 64;
  a.overheadSteps = 4;
  return a;
}

void addBenchVarianceCommand(CLI::App& bench, int& exitCode) {
  auto a = std::make_shared<VarianceBenchArgs>();
  auto quick = std::make_shared<bool>(false);
  auto* c = bench.add_subcommand("variance", "Variance-aware rendering (Yan et al. 2024): rings, spot and roulette figures");
  c->add_option("--scene", a->scene, "rings, spot, roulette or all")->check(CLI::IsMember({"rings", "spot", "roulette", "all"}))->capture_default_str();
  c->add_option("--seconds", a->seconds, "rings: time per estimator at equal time")->check(CLI::Range(0.1, 3600.0))->capture_default_str();
  c->add_option("--fd-reps", a->fdReps, "rings: central-difference evaluations of the reference")->check(CLI::Range(2, 1000000))->capture_default_str();
  c->add_option("--seed", a->seed, "random seed of the measurements")->capture_default_str();
  c->add_flag("--quick", *quick, "short runs (smoke test; figures are noisy)");
  c->add_flag("--json", a->json, "print one JSON object per scene, one per line");
  c->callback([a, quick, &exitCode] {
    VarianceBenchArgs args = *a;
    if (*quick) {
      VarianceBenchArgs q = quickVarianceBenchArgs();
      q.scene = args.scene;
      q.seed = args.seed;
      q.json = args.json;
      args = q;
    }
    for (const BenchReport& r : benchVariance(args)) r.print(args.json);
    exitCode = 0;
  });
}

}  // namespace invr::cli
