// invr-lab bench pixel-variance: gradient variance at a fixed theta for each pixel sampler at equal
// path budget (Yan et al. 2025, Fig. 3): the scene's built-in job, `--reps` independent gradient
// evaluations per sampler, one session per sampler so stage-1 maps are refreshed every
// `refresh` steps as in an optimisation. Variance = sum over parameter components of the
// per-component variance. Also stage 1's share of the adaptive sampler's time.
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <cmath>
#include <map>
#include <iostream>

#include "client/lab/bench.h"
#include "client/lab/lab_commands.h"
#include "core/job/problem.h"
#include "core/job/zoo_jobs.h"
#include "core/stopwatch.h"

namespace invr::cli {

namespace {

struct SamplerRun {
  double variance = 0, seconds = 0, stage1 = 0;
  // Standard error of `variance`: sqrt(sum_k (m4_k - s_k^4) / n), from each component's fourth
  // central moment (components treated as independent). Heavy-tailed derivatives (low-roughness
  // GGX) make it large: ratios are only as good as this.
  double varianceSe = 0;
  PixelMap lastMap;  // view 0's map after the last evaluation
};

// A map's probabilities as an image, relative to uniform (1 = 1/P): .exr values, and a .png
// scaled so the 99th percentile is white.
void writePixelMap(const std::filesystem::path& dir, const std::string& name, const PixelMap& m, int width, int height) {
  if (!m.valid()) return;
  const double uniform = 1.0 / double(m.p.size());
  Image exr(width, height, 1), png(width, height, 3);
  std::vector<float> sorted(m.p);
  std::sort(sorted.begin(), sorted.end());
  const double top = std::max(1e-30, double(sorted[std::min(sorted.size() - 1, size_t(0.99 * double(sorted.size())))]));
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const double v = m.p[size_t(y) * size_t(width) + size_t(x)];
      exr.at(x, y, 0) = float(v / uniform);
      png.setRgb(x, y, Rgb(float(std::min(1.0, v / top))));
    }
  writeImage(dir / (name + "_map.exr"), exr);
  writeImage(dir / (name + "_map.png"), png);
}

// ratio a/b and its standard error, to first order.
std::string ratioWithSe(const SamplerRun& a, const SamplerRun& b) {
  double r = a.variance / b.variance;
  double rel = std::sqrt(std::pow(a.varianceSe / a.variance, 2) + std::pow(b.varianceSe / b.variance, 2));
  return BenchReport::fmt(r) + " +- " + BenchReport::fmt(r * rel);
}

// `preset`: fixed maps per view (never refreshed) instead of the sampler's own stage 1.
SamplerRun measure(Problem& p, const std::vector<Image>& targets, const PixelSampler& sampler, int samples, int reps, double defensive,
                   int stage1History, int stage1Stride, int levels, const std::map<int, PixelMap>* preset = nullptr) {
  GradientOptions o = p.gradient;
  if (defensive > 0) o.pixels.defensive = float(defensive);
  o.pixels.sampler = &sampler;
  o.pixels.samplesPerView = samples;
  if (stage1History > 0) o.pixels.stage1History = stage1History;
  if (stage1Stride > 0) o.pixels.stage1Stride = stage1Stride;
  if (levels > 0) o.pixels.levels = levels;
  if (preset) o.pixels.refreshEvery = 1 << 30;
  GradientEngine engine(*p.scene, p.params, targets, o);
  EngineSession session;
  if (preset) session.pixelMaps = *preset;
  std::vector<double> sum(p.params.size(), 0.0), sumSq(p.params.size(), 0.0), sum3(p.params.size(), 0.0), sum4(p.params.size(), 0.0);
  SamplerRun out;
  Stopwatch clock;
  for (int i = 0; i < reps; ++i) {
    GradientRequest r;
    r.views = viewsForStep(p, uint64_t(i));
    r.step = uint64_t(i);
    r.seed = p.seed;
    GradientResult g = engine.evaluate(r, session);
    out.stage1 += g.stats.seconds_stage1();
    for (size_t k = 0; k < sum.size(); ++k) {
      sum[k] += g.gradient[k];
      double g2 = g.gradient[k] * g.gradient[k];
      sumSq[k] += g2;
      sum3[k] += g2 * g.gradient[k];
      sum4[k] += g2 * g2;
    }
  }
  out.seconds = clock.seconds();
  double varOfVariance = 0;
  for (size_t k = 0; k < sum.size(); ++k) {
    double m = sum[k] / reps, e2 = sumSq[k] / reps, e3 = sum3[k] / reps, e4 = sum4[k] / reps;
    double var = e2 - m * m;
    double m4 = e4 - 4 * m * e3 + 6 * m * m * e2 - 3 * m * m * m * m;
    out.variance += var * reps / std::max(1, reps - 1);
    varOfVariance += std::max(0.0, m4 - var * var) / reps;
  }
  out.varianceSe = std::sqrt(varOfVariance);
  if (auto it = session.pixelMaps.find(0); it != session.pixelMaps.end()) out.lastMap = it->second;
  return out;
}

// Reference maps: the second moments E[|dL/dI_j|^2] and E[sum_k (dI_j/dtheta_k)^2] of Eq. 12 and
// 16 averaged over `samples` stage-1 passes at every pixel (no upsampling, no levels). With many
// samples, sqrt of their product is the variance-optimal p_j for one parameter, so its variance
// bounds what any stage 1 could reach: it separates the sampler's design from stage-1 noise.
std::map<int, PixelMap> referenceMaps(Problem& p, const std::vector<Image>& targets, bool adaptive, int samples, double defensive) {
  GradientOptions o = p.gradient;
  o.pixels.stage1Stride = 1;
  GradientEngine engine(*p.scene, p.params, targets, o);
  p.params.write(p.initial, *p.scene);
  std::map<int, PixelMap> maps;
  const size_t pixels = size_t(p.scene->width) * size_t(p.scene->height);
  for (size_t v = 0; v < p.scene->cameras.size(); ++v) {
    std::vector<double> adjSq(pixels, 0.0), derivSq(pixels, 0.0);
    for (int i = 0; i < samples; ++i) {
      GradientRequest r;
      r.step = uint64_t(i);
      r.seed = p.seed ^ 0x0a11ce5ull;  // not the measured runs' streams
      Stage1 s = engine.measureStage1(int(v), r);
      for (size_t j = 0; j < pixels; ++j) {
        for (int c = 0; c < 3; ++c) adjSq[j] += double(s.adjointSq[3 * j + size_t(c)]);
        derivSq[j] += double(s.derivSq[j]);
      }
    }
    std::vector<float> q(pixels);
    for (size_t j = 0; j < pixels; ++j) q[j] = float(adaptive ? std::sqrt(adjSq[j] * derivSq[j]) : std::sqrt(adjSq[j]));
    PixelMap m;
    m.setProbabilities(defensiveMixture(q, float(defensive > 0 ? defensive : p.gradient.pixels.defensive)));
    maps[int(v)] = std::move(m);
  }
  return maps;
}

}  // namespace

BenchReport benchPixelVariance(const PixelBenchArgs& a) {
  auto job = zooJob(a.scene);
  if (a.targetSpp > 0) job.mutable_optimization()->set_target_spp(a.targetSpp);
  if (!a.loss.empty()) job.mutable_optimization()->set_loss(a.loss);
  if (a.refresh > 0) job.mutable_optimization()->set_pixel_refresh(a.refresh);
  Problem p = buildProblem(job);
  std::cerr << "rendering targets (" << p.targetSpp << " spp)...\n";
  std::vector<Image> targets = renderTargets(p);
  // The fixed theta: the job's start, or part of the way from the truth to it.
  for (size_t k = 0; k < p.initial.size(); ++k) p.initial[k] = p.truth[k] + float(a.thetaFraction) * (p.initial[k] - p.truth[k]);
  p.params.write(p.initial, *p.scene);  // every evaluation here is at that theta
  int pixels = p.scene->width * p.scene->height;
  int n = a.samples > 0 ? a.samples : std::max(1, pixels / 5);
  BenchReport rep("pixel-variance");
  rep.text("scene", a.scene);
  rep.text("loss", job.optimization().loss());
  rep.number("pixel_samples_per_view", n);
  rep.number("repetitions", a.reps);
  rep.number("theta_fraction", a.thetaFraction, "(0: the truth, 1: the job's initial parameters)");
  rep.number("param_error_at_theta", parameterError(p, p.initial));
  rep.number("defensive", a.defensive > 0 ? a.defensive : double(p.gradient.pixels.defensive));
  rep.number("refresh_every", p.gradient.pixels.refreshEvery, "steps between stage-1 passes");
  rep.number("stage1_history", a.stage1History > 0 ? a.stage1History : p.gradient.pixels.stage1History, "stage-1 passes the maps average");
  rep.number("stage1_stride", a.stage1Stride > 0 ? a.stage1Stride : p.gradient.pixels.stage1Stride, "stage-1 grid stride in pixels");
  rep.number("levels", a.levels > 0 ? a.levels : p.gradient.pixels.levels, "adaptive's resolution levels D");
  // Every registered mini-batch sampler, each against adaptive (Yan et al. 2025's).
  std::map<std::string, SamplerRun> runs;
  BenchReport::Json variance = BenchReport::Json::object(), varianceSe = BenchReport::Json::object();
  for (const PixelSampler* k : pixelSamplers()) {
    if (!k->miniBatch()) continue;
    SamplerRun& run = runs[k->name()] = measure(p, targets, *k, n, a.reps, a.defensive, a.stage1History, a.stage1Stride, a.levels);
    std::cerr << k->name() << ": variance " << run.variance << ", " << run.seconds << " s\n";
    variance[k->name()] = run.variance;
    varianceSe[k->name()] = run.varianceSe;
  }
  rep.value("variance", variance, BenchReport::line(variance));
  rep.value("variance_se", varianceSe, BenchReport::line(varianceSe) + " (standard errors)");
  const SamplerRun& adaptive = runs.at("adaptive");
  for (const PixelSampler* k : pixelSamplers()) {
    if (!k->miniBatch() || std::string(k->name()) == "adaptive") continue;
    const SamplerRun& run = runs.at(k->name());
    rep.number(std::string("ratio_") + k->name() + "_over_adaptive", run.variance / adaptive.variance,
               "= " + ratioWithSe(run, adaptive) + (std::string(k->name()) == "loss_grad" ? " (target >= 3)" : ""));
  }
  rep.number("stage1_overhead_fraction", adaptive.stage1 / adaptive.seconds, "(target <= 0.10)");
  if (!a.out.empty()) {
    std::filesystem::create_directories(a.out);
    for (const PixelSampler* k : pixelSamplers())
      if (k->usesStage1()) writePixelMap(a.out, k->name(), runs.at(k->name()).lastMap, p.scene->width, p.scene->height);
    rep.text("maps", a.out + " (each stage-1 sampler's last map of view 0: <name>_map.exr in units of 1/P, .png scaled to its 99th percentile)");
  }
  if (a.referenceSamples > 0) {
    std::cerr << "reference maps (" << a.referenceSamples << " stage-1 passes per view, every pixel)...\n";
    auto refAdaptive = referenceMaps(p, targets, true, a.referenceSamples, a.defensive);
    auto refLossGrad = referenceMaps(p, targets, false, a.referenceSamples, a.defensive);
    SamplerRun ra = measure(p, targets, pixelSampler("adaptive"), n, a.reps, a.defensive, 0, 0, 0, &refAdaptive);
    SamplerRun rl = measure(p, targets, pixelSampler("loss_grad"), n, a.reps, a.defensive, 0, 0, 0, &refLossGrad);
    rep.value("variance_reference_maps", {{"loss_grad", rl.variance}, {"adaptive", ra.variance}},
              "loss_grad " + BenchReport::fmt(rl.variance) + ", adaptive " + BenchReport::fmt(ra.variance) + " (maps from many stage-1 passes)");
    rep.number("reference_ratio_loss_grad_over_adaptive", rl.variance / ra.variance,
               "= " + ratioWithSe(rl, ra) + " (with maps from many stage-1 passes)");
    rep.value("variance_reference_maps_se", {{"loss_grad", rl.varianceSe}, {"adaptive", ra.varianceSe}},
              "loss_grad " + BenchReport::fmt(rl.varianceSe) + ", adaptive " + BenchReport::fmt(ra.varianceSe) + " (standard errors)");
    rep.number("reference_ratio_uniform_over_adaptive", runs.at("uniform").variance / ra.variance, "= " + ratioWithSe(runs.at("uniform"), ra));
    // What a perfect stage 1 would give the adaptive sampler against loss_grad as it runs: the
    // most the ratio above can reach by improving adaptive's maps alone.
    rep.number("ratio_loss_grad_over_reference_adaptive", runs.at("loss_grad").variance / ra.variance,
               "= " + ratioWithSe(runs.at("loss_grad"), ra) + " (loss_grad with its own stage 1, adaptive with reference maps)");
  }
  return rep;
}

void addBenchPixelCommand(CLI::App& bench, int& exitCode) {
  auto a = std::make_shared<PixelBenchArgs>();
  auto* c = bench.add_subcommand("pixel-variance", "Gradient variance of every mini-batch pixel sampler at equal path budget, against adaptive");
  c->add_option("--scene", a->scene, "zoo scene (its built-in job)")->capture_default_str();
  c->add_option("--reps", a->reps, "gradient evaluations per sampler")->capture_default_str()->check(CLI::Range(2, 1000000));
  c->add_option("--samples", a->samples, "pixel samples per view (default: a fifth of the pixels)");
  c->add_option("--defensive", a->defensive, "uniform share of the sampling mixture (default: the job's, 0.2)")->check(CLI::Range(1e-6, 1.0));
  c->add_option("--reference-maps", a->referenceSamples,
                "also measure adaptive and loss_grad with reference maps averaged over this many stage-1 passes at every pixel")
      ->check(CLI::Range(1, 100000));
  c->add_option("--stage1-history", a->stage1History,
                "loss_grad's and adaptive's maps average this many stage-1 passes, one per refresh (default: the job's, 1)")
      ->check(CLI::Range(1, 1024));
  c->add_option("--refresh", a->refresh, "steps between stage-1 refreshes (default: the job's pixel_refresh, 20)")->check(CLI::Range(1, 100000));
  c->add_option("--stage1-stride", a->stage1Stride, "stage 1 traces every stride-th pixel in x and y (default: the job's, 2)")->check(CLI::Range(1, 16));
  c->add_option("--levels", a->levels, "adaptive's resolution levels D of Eq. 18 (default: the job's, 4)")->check(CLI::Range(1, 8));
  c->add_option("--theta-fraction", a->thetaFraction, "measure at truth + f (initial - truth): 1 the start, small f near convergence")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  c->add_option("--loss", a->loss, "loss of the measured gradient (default: the job's)")->check(CLI::IsMember({"l2", "relative_l2", "l1"}));
  c->add_option("--out", a->out, "write each stage-1 sampler's last map of view 0 here (<name>_map.exr, relative to uniform, and .png)");
  c->add_flag("--json", a->json, "print the figures as JSON");
  c->callback([a, &exitCode] {
    benchPixelVariance(*a).print(a->json);
    exitCode = 0;
  });
}

}  // namespace invr::cli
