// invr bench pixel-variance: gradient variance at a fixed theta for each pixel sampler at equal
// path budget (Yan et al. 2025, Fig. 3): the scene's built-in job, `--reps` independent gradient
// evaluations per sampler, one session per sampler so stage-1 maps are refreshed every
// `refresh` steps as in an optimisation. Variance = sum over parameter components of the
// per-component variance. Also stage 1's share of the adaptive sampler's time.
#include <chrono>
#include <iostream>

#include "client/bench_report.h"
#include "client/commands.h"
#include "core/diff/problem.h"
#include "core/diff/zoo_jobs.h"

namespace invr::cli {

namespace {

struct PixelBenchArgs {
  std::string scene = "mirror";
  int reps = 1024;
  double defensive = 0;  // override the job's uniform share
  int samples = 0;  // pixel samples per view; 0: a fifth of the pixels (the paper: ~100K paths for 512^2)
  bool json = false;
};

struct SamplerRun {
  double variance = 0, seconds = 0, stage1 = 0;
};

SamplerRun measure(Problem& p, const std::vector<Image>& targets, PixelSampler sampler, int samples, int reps, double defensive) {
  GradientOptions o = p.gradient;
  if (defensive > 0) o.pixels.defensive = float(defensive);
  o.pixels.sampler = sampler;
  o.pixels.samplesPerView = samples;
  GradientEngine engine(*p.scene, p.params, targets, o);
  EngineSession session;
  std::vector<double> sum(p.params.size(), 0.0), sumSq(p.params.size(), 0.0);
  SamplerRun out;
  auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < reps; ++i) {
    GradientRequest r;
    r.views = viewsForStep(p, uint64_t(i));
    r.step = uint64_t(i);
    r.seed = p.seed;
    GradientResult g = engine.evaluate(p.initial, r, session);
    out.stage1 += g.stats.secondsStage1;
    for (size_t k = 0; k < sum.size(); ++k) {
      sum[k] += g.gradient[k];
      sumSq[k] += g.gradient[k] * g.gradient[k];
    }
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (size_t k = 0; k < sum.size(); ++k) {
    double m = sum[k] / reps;
    out.variance += (sumSq[k] / reps - m * m) * reps / std::max(1, reps - 1);
  }
  return out;
}

void run(const PixelBenchArgs& a) {
  auto job = zooJob(a.scene);
  Problem p = buildProblem(job);
  std::cerr << "rendering targets (" << p.targetSpp << " spp)...\n";
  std::vector<Image> targets = renderTargets(p);
  int pixels = p.scene->width * p.scene->height;
  int n = a.samples > 0 ? a.samples : std::max(1, pixels / 5);
  BenchReport rep("pixel-variance");
  rep.text("scene", a.scene);
  rep.number("pixel_samples_per_view", n);
  rep.number("repetitions", a.reps);
  rep.number("defensive", a.defensive > 0 ? a.defensive : double(p.gradient.pixels.defensive));
  SamplerRun runs[3];
  const PixelSampler kinds[3] = {PixelSampler::Uniform, PixelSampler::LossGrad, PixelSampler::Adaptive};
  std::string js = "{";
  for (int i = 0; i < 3; ++i) {
    runs[i] = measure(p, targets, kinds[i], n, a.reps, a.defensive);
    std::cerr << pixelSamplerName(kinds[i]) << ": variance " << runs[i].variance << ", " << runs[i].seconds << " s\n";
    js += std::string(i ? ", " : "") + "\"" + pixelSamplerName(kinds[i]) + "\": " + BenchReport::fmt(runs[i].variance);
  }
  js += "}";
  rep.raw("variance", js, js);
  rep.number("ratio_loss_grad_over_adaptive", runs[1].variance / runs[2].variance, "(target >= 3)");
  rep.number("ratio_uniform_over_adaptive", runs[0].variance / runs[2].variance);
  rep.number("stage1_overhead_fraction", runs[2].stage1 / runs[2].seconds, "(target <= 0.10)");
  rep.print(a.json);
}

}  // namespace

void addBenchPixelCommand(CLI::App& bench, int& exitCode) {
  auto a = std::make_shared<PixelBenchArgs>();
  auto* c = bench.add_subcommand("pixel-variance", "Gradient variance per pixel sampler at equal path budget (uniform, loss_grad, adaptive)");
  c->add_option("--scene", a->scene, "zoo scene (its built-in job)")->capture_default_str();
  c->add_option("--reps", a->reps, "gradient evaluations per sampler")->capture_default_str()->check(CLI::Range(2, 1000000));
  c->add_option("--samples", a->samples, "pixel samples per view (default: a fifth of the pixels)");
  c->add_option("--defensive", a->defensive, "uniform share of the sampling mixture (default: the job's, 0.2)")->check(CLI::Range(1e-6, 1.0));
  c->add_flag("--json", a->json, "print the figures as JSON");
  c->callback([a, &exitCode] {
    run(*a);
    exitCode = 0;
  });
}

}  // namespace invr::cli
