// invr-lab bench gradient-vector: a job's loss gradient at its starting point, as a vector with a
// standard error per component: the mean of independent evaluations per method (PT, RIS,
// ReSTIR after its burn-in) and, optionally, central finite differences of invr's own forward
// renders. deploy/peers.sh compares these with Mitsuba 3's gradient of the same scene and loss.
#include <algorithm>
#include <filesystem>
#include <cmath>
#include <iostream>
#include <memory>
#include <random>

#include "client/common/job_argument.h"
#include "client/common/bench_report.h"
#include "client/lab/lab_commands.h"
#include "core/diff/gradient_engine.h"
#include "core/error.h"
#include "core/job/problem.h"
#include "core/render/renderer.h"
#include "core/stopwatch.h"

namespace invr::cli {

namespace {

using Json = BenchReport::Json;

struct GradientVectorArgs {
  std::string job;
  SceneArgs sceneArgs;
  std::vector<std::string> methods{"pt", "ris", "restir"};
  int evaluations = 16;
  int spp = 0;  // 0: the job's spp_primal and spp_gradient
  int fdEvaluations = 0;
  int fdSpp = 4;
  double fdScale = 1.0;
  int fdComponents = 48;  // vectors longer than this get one directional difference
  uint64_t seed = 1000;
  std::string targetsOut;  // folder: target_view<k>.exr, the images the loss compares with
  bool perEvaluation = false;  // also every evaluation's vector (for sums over groups of values)
  bool json = false;
};

// Mean and standard error of the mean per component.
struct Moments {
  std::vector<double> sum, sumSq;
  int n = 0;
  explicit Moments(size_t size) : sum(size, 0.0), sumSq(size, 0.0) {}
  void add(const std::vector<double>& x) {
    for (size_t k = 0; k < x.size(); ++k) {
      sum[k] += x[k];
      sumSq[k] += x[k] * x[k];
    }
    ++n;
  }
  Json mean() const {
    Json a = Json::array();
    for (double s : sum) a.push_back(s / n);
    return a;
  }
  Json standardError() const {
    Json a = Json::array();
    for (size_t k = 0; k < sum.size(); ++k) {
      const double m = sum[k] / n, var = n > 1 ? std::max(0.0, (sumSq[k] - n * m * m) / (n - 1)) : 0.0;
      a.push_back(std::sqrt(var / n));
    }
    return a;
  }
};

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// Unbiased loss of the expected image at theta (two independent renders per view, loss.h), on
// rep r's random numbers: the same numbers at theta + h and theta - h (common random numbers).
double lossAt(Problem& p, const std::vector<Image>& targets, const std::vector<int>& views, const std::vector<float>& theta, int spp,
              uint64_t rep) {
  p.params.write(theta, *p.scene, /*refreshSampling=*/false);
  double loss = 0;
  for (int v : views) {
    RenderOptions a = transportRenderOptions(p, spp, kFinalRenderStream), b = a;
    a.seed = mix64(a.seed + 2 * rep + 1);
    b.seed = mix64(b.seed + 2 * rep + 2);
    const Image ia = renderView(*p.scene, v, a).image, ib = renderView(*p.scene, v, b).image;
    const std::vector<float>* mask =
        size_t(v) < p.gradient.lossMasks.size() && !p.gradient.lossMasks[size_t(v)].empty() ? &p.gradient.lossMasks[size_t(v)] : nullptr;
    loss += unbiasedImageLoss(p.gradient.loss, ia, ib, targets[size_t(v)], int(views.size()), mask);
  }
  return loss;
}

void runGradientVector(const GradientVectorArgs& a) {
  if (a.evaluations < 2) throw InputError("bench gradient-vector: --evaluations must be at least 2 (a standard error needs two)");
  if (a.fdEvaluations == 1) throw InputError("bench gradient-vector: --fd-evaluations must be 0 (none) or at least 2");
  AssetResolver assets;
  const v1::JobSpec job = optimizationJobFromArgument(a.job, assets, a.sceneArgs);
  Problem p = buildProblem(job, assets);
  const std::vector<Image> targets = renderTargets(p);
  if (!a.targetsOut.empty()) {
    std::filesystem::create_directories(a.targetsOut);
    for (size_t v = 0; v < targets.size(); ++v)
      writeImage(std::filesystem::path(a.targetsOut) / ("target_view" + std::to_string(v) + ".exr"), targets[v]);
  }
  const std::vector<float> theta = p.initial;
  p.params.write(theta, *p.scene);
  std::vector<int> views(p.scene->cameras.size());
  for (size_t v = 0; v < views.size(); ++v) views[v] = int(v);

  BenchReport rep("gradient-vector");
  rep.text("job", a.job);
  rep.number("views", double(views.size()));
  rep.text("loss", lossName(p.gradient.loss));
  rep.number("max_depth", p.gradient.maxDepth);
  rep.number("rr_depth", p.gradient.russianRouletteDepth);
  rep.text("job_method", gradientMethodName(p.gradient.method));
  rep.number("job_spp_primal", p.gradient.sppPrimal);
  rep.number("job_spp_gradient", p.gradient.sppGradient);
  rep.number("views_per_step", p.viewsPerStep);
  rep.number("learning_rate_half_life", p.schedule.halfLifeSteps);
  Json params = Json::array();
  for (const auto& s : p.params.slots())
    params.push_back({{"name", s.name},
                      {"offset", s.offset},
                      {"size", s.size},
                      {"width", s.width},
                      {"height", s.height},
                      {"channels", s.channels},
                      {"learning_rate", s.learningRate},
                      {"lower", s.lower},
                      {"upper", s.upper}});
  rep.value("parameters", params, std::to_string(p.params.slots().size()) + " parameters, " + std::to_string(p.params.size()) + " values");
  rep.value("theta", Json(std::vector<double>(theta.begin(), theta.end())), "(the job's starting values)");
  if (p.groundTruthKnown()) rep.value("truth", Json(std::vector<double>(p.truth.begin(), p.truth.end())), "(the scene as described)");

  Json methods = Json::object(), skipped = Json::object();
  for (const std::string& name : a.methods) {
    GradientOptions o = p.gradient;
    o.method = gradientMethodFromName(name);
    if (o.maxDepth > 1 && o.method != GradientMethod::Pt) {  // as jobs refuse it (parseGradientOptions)
      skipped[name] = "paths longer than direct illumination are differentiated with pt only";
      continue;
    }
    if (a.spp > 0) o.sppPrimal = o.sppGradient = a.spp;
    const int burnIn = o.method == GradientMethod::Restir ? std::max(p.burnIn, 0) : 0;
    GradientEngine engine(*p.scene, p.params, targets, o);
    Moments m(p.params.size());
    Json samples = Json::array();
    std::vector<double> seconds;
    double first = 0;
    for (int i = 0; i < a.evaluations; ++i) {
      EngineSession session;  // independent chains: a fresh session and seed per evaluation
      GradientRequest r;
      r.views = views;
      r.allSessionViews = true;
      r.seed = a.seed + uint64_t(i);
      for (int b = 0; b < burnIn; ++b) {
        GradientRequest rb = r;
        rb.renderOnly = true;
        rb.step = uint64_t(b);
        engine.evaluate(rb, session);
      }
      r.step = uint64_t(burnIn);
      Stopwatch clock;
      const GradientResult g = engine.evaluate(r, session);
      const double t = clock.seconds();
      if (i == 0) first = t;  // caches and allocations warm up: reported apart
      else seconds.push_back(t);
      m.add(g.gradient);
      if (a.perEvaluation) samples.push_back(g.gradient);
    }
    methods[name] = {{"gradient", m.mean()},
                     {"se", m.standardError()},
                     {"evaluations", a.evaluations},
                     {"spp_primal", o.sppPrimal},
                     {"spp_gradient", o.sppGradient},
                     {"burn_in", burnIn},
                     {"step_seconds", median(seconds)},
                     {"first_step_seconds", first}};
    if (a.perEvaluation) methods[name]["samples"] = std::move(samples);
    std::cerr << "gradient-vector: " << name << " " << a.evaluations << " evaluations, step " << median(seconds) << " s\n";
  }
  rep.value("methods", methods, std::to_string(methods.size()) + " methods");
  if (!skipped.empty()) rep.value("skipped_methods", skipped, std::to_string(skipped.size()) + " skipped");

  if (a.fdEvaluations > 0) {
    // Central differences of the unbiased loss: per component for short vectors, else along one
    // random +-1 direction u (compare with g.u). h is fdScale times each value's learning rate,
    // the scale of one optimisation step.
    const size_t n = p.params.size();
    const bool perComponent = n <= size_t(a.fdComponents);
    std::vector<double> h(n);
    for (const auto& s : p.params.slots())
      for (uint32_t k = 0; k < s.size; ++k) h[s.offset + k] = a.fdScale * double(s.learningRate);
    std::vector<std::vector<double>> directions;
    if (perComponent) {
      for (size_t k = 0; k < n; ++k) {
        std::vector<double> d(n, 0.0);
        d[k] = 1.0;
        directions.push_back(std::move(d));
      }
    } else {
      std::mt19937_64 rng(a.seed);
      std::vector<double> d(n);
      for (auto& x : d) x = (rng() & 1) ? 1.0 : -1.0;
      directions.push_back(std::move(d));
    }
    Json values = Json::array(), ses = Json::array();
    for (const auto& d : directions) {
      Moments m(1);
      for (int r = 0; r < a.fdEvaluations; ++r) {
        std::vector<float> plus = theta, minus = theta;
        double scale = 1e30;  // one h along a direction: the smallest of its components'
        for (size_t k = 0; k < n; ++k)
          if (d[k] != 0) scale = std::min(scale, h[k]);
        for (size_t k = 0; k < n; ++k) {
          plus[k] = float(double(theta[k]) + scale * d[k]);
          minus[k] = float(double(theta[k]) - scale * d[k]);
        }
        const double lp = lossAt(p, targets, views, plus, a.fdSpp, uint64_t(r)), lm = lossAt(p, targets, views, minus, a.fdSpp, uint64_t(r));
        m.add({(lp - lm) / (2 * scale)});
      }
      values.push_back(m.mean()[0]);
      ses.push_back(m.standardError()[0]);
    }
    p.params.write(theta, *p.scene);
    Json fd = {{"mode", perComponent ? "components" : "direction"}, {"evaluations", a.fdEvaluations}, {"spp", a.fdSpp}, {"scale", a.fdScale},
               {"values", values}, {"se", ses}};
    if (!perComponent) fd["direction"] = directions[0];
    rep.value("fd", fd, std::string("finite differences (") + (perComponent ? "per component" : "along one direction") + ")");
  }
  rep.print(a.json);
}

}  // namespace

void addBenchGradientVectorCommand(CLI::App& bench, int& exitCode) {
  auto args = std::make_shared<GradientVectorArgs>();
  auto* c = bench.add_subcommand("gradient-vector",
                                 "A job's loss gradient at its start, per component with standard errors: PT, RIS and ReSTIR over "
                                 "independent evaluations, and finite differences (the input of deploy/peers.sh)");
  c->add_option("job", args->job, "zoo scene name, job file or Mitsuba scene (with --param)")->required();
  addSceneArgs(c, args->sceneArgs, true);
  c->add_option("--methods", args->methods, "pt, ris, restir (comma-separated)")->delimiter(',')->check(CLI::IsMember({"pt", "ris", "restir"}));
  c->add_option("--evaluations", args->evaluations, "independent evaluations per method (ReSTIR: a fresh chain each, after the job's burn-in)")
      ->capture_default_str();
  c->add_option("--spp", args->spp, "samples per pixel of the primal and the derivative pass (0: the job's)")->capture_default_str();
  c->add_option("--fd-evaluations", args->fdEvaluations, "central differences per component (0: none)")->capture_default_str();
  c->add_option("--fd-spp", args->fdSpp, "spp of each render of a difference (two renders per side, common random numbers)")
      ->capture_default_str();
  c->add_option("--fd-scale", args->fdScale, "h as a multiple of each value's learning rate")->capture_default_str();
  c->add_option("--fd-components", args->fdComponents, "longer vectors get one difference along a random +-1 direction")
      ->capture_default_str();
  c->add_option("--seed", args->seed, "seed of the first evaluation (the next ones count up)")->capture_default_str();
  c->add_option("--targets-out", args->targetsOut, "DIR: write the target images (target_view<k>.exr) there");
  c->add_flag("--per-evaluation", args->perEvaluation, "also print every evaluation's gradient (methods.<m>.samples)");
  c->add_flag("--json", args->json, "print one JSON object");
  c->callback([args, &exitCode] {
    runGradientVector(*args);
    exitCode = 0;
  });
}

}  // namespace invr::cli
