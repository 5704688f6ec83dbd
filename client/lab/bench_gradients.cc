// Benchmarks of the gradient estimators (Wang et al. 2023): equal-time gradient error, ReSTIR's
// overhead at equal samples, and equal-time reconstruction. Each prints a table or --json.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <memory>

#include "client/lab/bench.h"
#include "client/lab/lab_commands.h"
#include "client/common/job_argument.h"
#include "core/diff/edge_reservoir_boundary.h"
#include "core/diff/pixel_sampler.h"
#include "core/job/problem.h"
#include "core/job/zoo_jobs.h"
#include "core/scene/scene_builder.h"
#include "core/optim/equal_time.h"
#include "core/optim/optimization_loop.h"
#include "core/error.h"
#include "core/math/statistics.h"
#include "core/stopwatch.h"
#include "core/diff/parameter_kind.h"

namespace invr::cli {

namespace {


const GradientMethod kMethods[] = {GradientMethod::Pt, GradientMethod::Ris, GradientMethod::Restir};

struct Setup {
  Problem problem;
  std::vector<Image> targets;
};

// The zoo scene's job; --param replaces its parameters (names and starting values), as for `run`.
v1::JobSpec benchJob(const std::string& scene, const std::vector<std::string>& params) {
  if (params.empty()) return zooJob(scene);
  AssetResolver assets;
  SceneArgs args;
  args.params = params;
  return optimizationJobFromArgument(scene, assets, args);
}

Setup makeSetup(const std::string& scene, int targetSpp, const std::vector<std::string>& params = {}) {
  auto job = benchJob(scene, params);
  job.mutable_optimization()->set_target_spp(targetSpp);
  Setup s{buildProblem(job), {}};
  s.targets = renderTargets(s.problem);
  s.problem.params.write(s.problem.initial, *s.problem.scene);  // every evaluation here is at the start
  return s;
}

GradientOptions optionsFor(const Problem& p, GradientMethod m, int spp) {
  GradientOptions o = p.gradient;
  o.method = m;
  o.sppPrimal = spp;
  o.sppGradient = spp;
  return o;
}

// Seconds per gradient step for method m at spp (median of 3 after one warm-up step).
double stepSeconds(Setup& s, GradientMethod m, int spp, int burnIn) {
  GradientEngine engine(*s.problem.scene, s.problem.params, s.targets, optionsFor(s.problem, m, spp));
  EngineSession session;
  GradientRequest r;
  r.views = viewsForStep(s.problem, 0);
  for (int b = 0; b < burnIn; ++b) {
    GradientRequest rb = r;
    rb.renderOnly = true;
    rb.step = uint64_t(b);
    engine.evaluate(rb, session);
  }
  std::vector<double> t;
  for (int i = 0; i < 4; ++i) {
    r.step = uint64_t(burnIn + i);
    Stopwatch clock;
    engine.evaluate(r, session);
    if (i > 0) t.push_back(clock.seconds());
  }
  std::sort(t.begin(), t.end());
  return t[1];
}

double relativeSquaredError(const std::vector<double>& g, const std::vector<double>& ref) {
  double num = 0, den = 0;
  for (size_t i = 0; i < g.size(); ++i) {
    num += (g[i] - ref[i]) * (g[i] - ref[i]);
    den += ref[i] * ref[i];
  }
  return num / den;
}

}  // namespace

BenchReport benchGradients(const GradientsArgs& a) {
  Setup s = makeSetup(a.scene, a.targetSpp, a.params);
  if (a.neighbours > 0) s.problem.gradient.restir.neighbours = a.neighbours;
  if (a.mCap > 0) s.problem.gradient.restir.mCap = float(a.mCap);
  if (a.radiusPixels > 0) s.problem.gradient.radiusPixels = float(a.radiusPixels);
  if (a.edgeNeighbours >= 0) s.problem.gradient.boundary.term<EdgeFirstAreaShadowOptions>().edgeNeighbours = a.edgeNeighbours;
  if (!a.sampler.empty()) s.problem.gradient.sampler = samplerKindFromName(a.sampler, "--sampler");
  const auto views = viewsForStep(s.problem, 0);
  // Reference: not the method under test's own chain but independent RIS evaluations at high spp
  // (RIS is checked against finite differences in tests/core/diff), averaged in two halves.
  // |A - B|^2 is about 4x the full reference's error, which we print as the noise floor that
  // every measured relMSE includes. A ReSTIR bias would show against it; against a ReSTIR
  // reference it would cancel.
  auto reference = [&](uint64_t seed, double* noiseFloor) {
    std::vector<double> ref(s.problem.params.size(), 0.0), half(s.problem.params.size(), 0.0);
    GradientOptions refOptions = optionsFor(s.problem, GradientMethod::Ris, a.refSpp);
    refOptions.sampler = SamplerKind::Independent;  // one reference whatever --sampler says
    GradientEngine engine(*s.problem.scene, s.problem.params, s.targets, refOptions);
    for (int i = 0; i < a.refEvaluations; ++i) {
      EngineSession session;
      GradientRequest r;
      r.views = views;
      r.seed = seed + uint64_t(i);
      auto g = engine.evaluate(r, session).gradient;
      for (size_t k = 0; k < g.size(); ++k) {
        ref[k] += g[k] / a.refEvaluations;
        if (i < a.refEvaluations / 2) half[k] += g[k] / (a.refEvaluations / 2);
      }
    }
    std::vector<double> otherHalf(ref.size());
    for (size_t k = 0; k < ref.size(); ++k) otherHalf[k] = 2 * ref[k] - half[k];
    *noiseFloor = relativeSquaredError(half, otherHalf) / 4;
    return ref;
  };
  double floor = 0;
  const std::vector<double> ref = reference(900001, &floor);
  // Equal time per step: the budget is ReSTIR's step at 1 spp; PT and RIS get as many spp as fit.
  double budget = stepSeconds(s, GradientMethod::Restir, 1, 2);
  BenchReport rep("gradients");
  rep.text("scene", a.scene);
  rep.text("sampler", samplerKindName(s.problem.gradient.sampler));
  rep.number("parameters", double(s.problem.params.size()));
  rep.number("restir_neighbours", s.problem.gradient.restir.neighbours);
  rep.number("restir_m_cap", s.problem.gradient.restir.mCap);
  rep.number("restir_radius_pixels", s.problem.gradient.radiusPixels);
  rep.number("budget_seconds_per_step", budget, "s (ReSTIR at 1 spp)");
  // Each method's relMSE is a mean over `reps` gradient evaluations, with its standard error.
  // Consecutive ReSTIR steps share reservoirs and so are correlated; ReSTIR therefore runs
  // `restirChains` independent chains (own seed, own burn-in) and its standard error comes from the
  // chain means, which are independent. measure(): relMSE of one setting over `reps` evaluations,
  // its standard error and the seconds per step.
  auto measure = [&](const GradientOptions& o) {
    GradientEngine engine(*s.problem.scene, s.problem.params, s.targets, o);
    const bool restir = o.method == GradientMethod::Restir;
    const int chains = restir ? std::max(1, std::min(a.restirChains, a.reps)) : a.reps;
    const int perChain = std::max(1, a.reps / chains);
    std::vector<double> groupMeans;
    double secs = 0;
    for (int c = 0; c < chains; ++c) {
      EngineSession session;
      GradientRequest r;
      r.views = views;
      r.seed = 12345 + uint64_t(c) * 7919;
      const int burn = restir ? a.burnIn : 0;
      for (int b = 0; b < burn; ++b) {
        GradientRequest rb = r;
        rb.renderOnly = true;
        rb.step = uint64_t(b);
        engine.evaluate(rb, session);
      }
      double groupErr = 0;
      for (int i = 0; i < perChain; ++i) {
        r.step = uint64_t(burn + i);
        Stopwatch clock;
        auto g = engine.evaluate(r, session).gradient;
        secs += clock.seconds();
        groupErr += relativeSquaredError(g, ref) / perChain;
      }
      groupMeans.push_back(groupErr);
    }
    MeanSe m;
    for (double e : groupMeans) m.add(e);
    return std::array<double, 3>{m.mean(), groupMeans.size() > 1 ? m.se() : 0.0, secs / double(chains * perChain)};
  };
  std::vector<double> relmse(3), relmseSe(3), seconds(3);
  for (int mi = 0; mi < 3; ++mi) {
    GradientMethod m = kMethods[mi];
    int spp = 1;
    if (m != GradientMethod::Restir) spp = std::max(1, int(std::lround(budget / stepSeconds(s, m, 1, 0))));
    const auto result = measure(optionsFor(s.problem, m, spp));
    relmse[size_t(mi)] = result[0];
    relmseSe[size_t(mi)] = result[1];
    seconds[size_t(mi)] = result[2];
    std::string name = gradientMethodName(m);
    rep.number("spp_" + name, spp);
    rep.number("seconds_per_step_" + name, seconds[size_t(mi)], "s");
  }
  auto pm = [&](int i) { return BenchReport::fmt(relmse[size_t(i)]) + " +- " + BenchReport::fmt(relmseSe[size_t(i)]); };
  rep.value("relmse", {{"pt", relmse[0]}, {"ris", relmse[1]}, {"restir", relmse[2]}},
            "pt " + pm(0) + ", ris " + pm(1) + ", restir " + pm(2) + " (+- one standard error)");
  rep.value("relmse_standard_error", {{"pt", relmseSe[0]}, {"ris", relmseSe[1]}, {"restir", relmseSe[2]}},
            "pt " + BenchReport::fmt(relmseSe[0]) + ", ris " + BenchReport::fmt(relmseSe[1]) + ", restir " + BenchReport::fmt(relmseSe[2]));
  // Standard error of a ratio of independent means (delta method).
  auto ratioSe = [&](int i, int j) {
    double r = relmse[size_t(i)] / relmse[size_t(j)];
    return r * std::hypot(relmseSe[size_t(i)] / relmse[size_t(i)], relmseSe[size_t(j)] / relmse[size_t(j)]);
  };
  {
    // The first 16 values: enough to see a reference that is mostly noise (small, or signs that
    // change between runs), without printing a texture's worth.
    BenchReport::Json values = BenchReport::Json::array();
    for (size_t k = 0; k < ref.size() && k < 16; ++k) values.push_back(ref[k]);
    const std::string shown = BenchReport::line(values);
    rep.value("reference_gradient", std::move(values),
              shown + (ref.size() > 16 ? " (first 16 of " + std::to_string(ref.size()) + ")" : ""));
  }
  rep.number("reference_noise_floor", floor, "(relMSE the reference itself contributes; keep it well below restir's)");
  rep.number("ratio_ris_over_restir", relmse[1] / relmse[2],
             "+- " + BenchReport::fmt(ratioSe(1, 2)) +
                 (s.problem.params.hasShapeParameters() ? " (target >= 3 on shape jobs)" : " (target >= 10 on ajar or oxalis)"));
  rep.number("ratio_ris_over_restir_standard_error", ratioSe(1, 2));
  rep.number("ratio_pt_over_restir", relmse[0] / relmse[2],
             "+- " + BenchReport::fmt(ratioSe(0, 2)) + (s.problem.params.hasShapeParameters() ? " (target >= 10 on shape jobs)" : ""));
  // Step times match only to within one spp; relMSE x seconds compares work-normalised efficiency.
  rep.number("efficiency_ratio_ris_over_restir", relmse[1] * seconds[1] / (relmse[2] * seconds[2]),
             "+- " + BenchReport::fmt(ratioSe(1, 2) * seconds[1] / seconds[2]) + " (relMSE x seconds)");
  rep.number("efficiency_ratio_pt_over_restir", relmse[0] * seconds[0] / (relmse[2] * seconds[2]),
             "+- " + BenchReport::fmt(ratioSe(0, 2) * seconds[0] / seconds[2]) + " (relMSE x seconds)");

  // Shape jobs (Fig. 7): ReSTIR with one boundary term or edge importance switched off, and RIS
  // with the light-points-first shadow sampling, at the same settings and steps as ReSTIR above. A
  // term switched off shows as bias: its relMSE stays high however many steps are averaged.
  if (s.problem.params.hasShapeParameters() && a.ablations) {
    BenchReport::Json rows = BenchReport::Json::object();
    std::string line;
    auto row = [&](const std::string& name, const GradientOptions& o) {
      const auto m = measure(o);
      rows[name] = {{"relmse", m[0]}, {"relmse_standard_error", m[1]}, {"seconds_per_step", m[2]}};
      line += (line.empty() ? "" : ", ") + name + " " + BenchReport::fmt(m[0]) + " +- " + BenchReport::fmt(m[1]);
      return m;
    };
    const GradientOptions full = optionsFor(s.problem, GradientMethod::Restir, 1);
    GradientOptions o = full;
    o.boundary.primary = o.boundary.secondary = false;
    row("interior_only", o);
    o = full;
    o.boundary.primary = false;
    row("without_primary", o);
    o = full;
    o.boundary.secondary = false;
    row("without_secondary", o);
    o = full;
    o.boundary.term<EdgeFirstAreaShadowOptions>().edgeImportance = false;
    const auto noImportance = row("without_edge_importance", o);
    o = full;
    const int neighbours = full.boundary.termOr<EdgeFirstAreaShadowOptions>().edgeNeighbours;
    o.boundary.term<EdgeFirstAreaShadowOptions>().edgeNeighbours = neighbours > 0 ? 0 : 1;
    row(neighbours > 0 ? "without_edge_neighbours" : "with_one_edge_neighbour", o);
    o = optionsFor(s.problem, GradientMethod::Ris, 1);
    o.boundary.areaSampling = BoundaryOptions::AreaSampling::LightPoints;
    row("ris_light_points_1spp", o);
    rep.value("ablations", std::move(rows), "relMSE of ReSTIR at 1 spp with one part off (+- one SE): " + line);
    const double r = noImportance[0] / relmse[2], rSe = r * std::hypot(noImportance[1] / noImportance[0], relmseSe[2] / relmse[2]);
    rep.number("ratio_without_edge_importance_over_restir", r, "+- " + BenchReport::fmt(rSe) + " (target >= 2 when area-light shadows carry the gradient)");
  }

  // The case ReSTIR exists for: theta changes every step. Each chain alternates between the
  // start and a point 10 % of the way to the truth, so every measured step (at the start) reuses
  // reservoirs made at the other parameters. PT and RIS keep no state, so their figures above hold.
  {
    const std::vector<float> start = s.problem.initial;
    std::vector<float> other = start;
    for (size_t k = 0; k < other.size(); ++k) other[k] += 0.1f * (s.problem.truth[k] - start[k]);
    s.problem.params.clampToBounds(other);
    GradientEngine engine(*s.problem.scene, s.problem.params, s.targets, optionsFor(s.problem, GradientMethod::Restir, 1));
    const int chains = std::max(1, std::min(a.restirChains, a.reps)), perChain = std::max(1, a.reps / chains);
    std::vector<double> groupMeans;
    for (int c = 0; c < chains; ++c) {
      EngineSession session;
      GradientRequest r;
      r.views = views;
      r.seed = 54321 + uint64_t(c) * 7919;
      uint64_t step = 0;
      for (int b = 0; b < a.burnIn; ++b, ++step) {
        s.problem.params.write(b % 2 ? start : other, *s.problem.scene);
        GradientRequest rb = r;
        rb.renderOnly = true;
        rb.step = step;
        engine.evaluate(rb, session);
      }
      double groupErr = 0;
      for (int i = 0; i < perChain; ++i) {
        s.problem.params.write(other, *s.problem.scene);  // a step at the other parameters first
        r.step = step++;
        engine.evaluate(r, session);
        s.problem.params.write(start, *s.problem.scene);
        r.step = step++;
        groupErr += relativeSquaredError(engine.evaluate(r, session).gradient, ref) / perChain;
      }
      groupMeans.push_back(groupErr);
    }
    MeanSe m;
    for (double e : groupMeans) m.add(e);
    const double mean = m.mean(), se = groupMeans.size() > 1 ? m.se() : 0.0;
    rep.number("relmse_restir_changing_theta", mean, "+- " + BenchReport::fmt(se) + " (theta alternating every step)");
    const double r = relmse[1] / mean, rSe = r * std::hypot(relmseSe[1] / relmse[1], se / mean);
    rep.number("ratio_ris_over_restir_changing_theta", r, "+- " + BenchReport::fmt(rSe));
  }
  return rep;
}

BenchReport benchOverhead(const OverheadArgs& a) {
  Setup s = makeSetup(a.scene, a.targetSpp);
  // Equal samples: the same M candidates and spp; ReSTIR adds the neighbour search, combination
  // and reservoir bookkeeping. Two ReSTIR variants: the default, which finds neighbours among last
  // step's pixels when last step rendered the view (here: always), and the kd-tree search that
  // multi-view batches use (a tree built per chain per step). Interleaved to share the machine's
  // noise.
  struct Variant {
    std::string name;
    GradientOptions options;
    EngineSession session;
    std::vector<double> seconds;
    double split[4] = {0, 0, 0, 0};  // mean primal, derivative, upkeep seconds; shadow rays
  };
  std::vector<Variant> v(3);
  v[0].name = "ris";
  v[0].options = optionsFor(s.problem, GradientMethod::Ris, 1);
  v[1].name = "restir";
  v[1].options = optionsFor(s.problem, GradientMethod::Restir, 1);
  v[2].name = "restir_kd_tree";
  v[2].options = v[1].options;
  v[2].options.pixelNeighbours = false;
  std::vector<std::unique_ptr<GradientEngine>> engines;
  for (auto& x : v) engines.push_back(std::make_unique<GradientEngine>(*s.problem.scene, s.problem.params, s.targets, x.options));
  GradientRequest r;
  r.views = viewsForStep(s.problem, 0);
  for (int b = 0; b < 4; ++b) {
    r.step = uint64_t(b);
    r.renderOnly = true;
    for (size_t k = 1; k < v.size(); ++k) engines[k]->evaluate(r, v[k].session);
  }
  r.renderOnly = false;
  for (int i = 0; i < a.steps; ++i) {
    r.step = uint64_t(4 + i);
    for (size_t k = 0; k < v.size(); ++k) {
      Stopwatch clock;
      const v1::GradientStats st = engines[k]->evaluate(r, v[k].session).stats;
      v[k].seconds.push_back(clock.seconds());
      v[k].split[0] += st.seconds_primal() / a.steps;
      v[k].split[1] += st.seconds_derivative() / a.steps;
      v[k].split[2] += st.seconds_reservoir() / a.steps;
      v[k].split[3] += double(st.rays().shadow()) / a.steps;
    }
  }
  BenchReport rep("overhead");
  rep.text("scene", a.scene);
  std::vector<double> median;
  for (auto& x : v) {
    std::sort(x.seconds.begin(), x.seconds.end());
    median.push_back(x.seconds[x.seconds.size() / 2]);
    rep.number(x.name + "_seconds_per_step", median.back(), "s (median)");
  }
  // Where the time goes: the two passes and, for ReSTIR, the reservoir upkeep (kd-tree builds,
  // Alg. 8, the next step's store).
  for (auto& x : v) {
    rep.number(x.name + "_seconds_primal", x.split[0], "s (mean)");
    rep.number(x.name + "_seconds_derivative", x.split[1], "s (mean)");
    if (x.name != "ris") rep.number(x.name + "_seconds_reservoir_upkeep", x.split[2], "s (mean)");
    rep.number(x.name + "_shadow_rays_per_step", x.split[3]);
  }
  rep.number("restir_overhead_fraction", (median[1] - median[0]) / median[1], "(target <= 0.20)");
  rep.number("restir_kd_tree_overhead_fraction", (median[2] - median[0]) / median[2], "(neighbours from the kd-tree, as in multi-view batches)");
  return rep;
}

namespace {

struct ReconstructArgs {
  std::string scene = "oxalis";
  double seconds = 60;
  std::string loss;        // override the scene job's loss
  std::string optimizer;   // override the scene job's optimizer
  double learningRate = 0; // override every parameter's learning rate
  std::string csv = "reconstruct.csv";
  std::vector<std::string> pixelSamplers;  // compare these pixel samplers instead of light sampling
  int pixelSamples = 0;
  int stage1History = 0;  // > 0: the stage-1 samplers' maps average this many passes
  std::vector<std::string> params;  // --param: replaces the zoo job's parameters
  std::vector<std::string> sets;    // --set FIELD.PATH=VALUE: any job field (e.g. optimization.pixel_refresh=5)
  int seeds = 1;                     // runs per method (job seed, seed + 1, ...); medians reported
  int imageErrorSpp = 16;            // the image-error meter's samples per pixel (reference and measurements)
  std::vector<std::string> methods{"pt", "ris", "restir"};  // also: forward_only, derivative_only
  // Wang et al. 2023's protocol (docs/evaluation.md): fixed iterations, per-method samples, the
  // burn-in, and the primal and derivative from one sample.
  int steps = 0;                  // > 0: this many steps per run instead of --seconds
  std::vector<std::string> spp;   // METHOD=N: that variant's spp_primal and spp_gradient
  int burnIn = -1;                // ReSTIR's render-only steps; -1: the job's
  bool correlatedPrimal = false;  // the derivative pass draws the primal pass's random numbers
  std::vector<double> lrSweep;    // factors of every parameter's learning rate, each run per variant
  bool targetFloor = false;       // also run each variant from the truth: the targets' own floor
  int targetSpp = 256;
  bool json = false;
};

// "pt=4" -> ("pt", 4); the variant must be one compared.
std::map<std::string, int> sppPerVariant(const std::vector<std::string>& specs, const std::vector<std::string>& variants) {
  std::map<std::string, int> out;
  for (const std::string& spec : specs) {
    const size_t eq = spec.find('=');
    const std::string name = spec.substr(0, eq);
    int n = 0;
    try {
      n = eq == std::string::npos ? 0 : std::stoi(spec.substr(eq + 1));
    } catch (const std::exception&) {
      n = 0;
    }
    if (n < 1 || n > 4096) throw InputError("--spp '" + spec + "': give METHOD=N with N in 1..4096");
    if (std::find(variants.begin(), variants.end(), name) == variants.end())
      throw InputError("--spp '" + spec + "': '" + name + "' is not among the variants compared");
    out[name] = n;
  }
  return out;
}

// Texture texels by what lights them (Wang et al.'s oxalis regions): per albedo texel of an image
// texture, whether a spot light reaches its centre (its cone, facing and an unblocked shadow ray),
// found where the texture's uv maps onto the meshes that wear it. Texels no mesh shows are left
// out (-1).
struct TexelRegions {
  std::vector<uint32_t> spotLit, others;  // parameter indices (every channel of a texel)
};

TexelRegions texelRegionsBySpots(const Problem& p) {
  TexelRegions out;
  const Scene& scene = *p.scene;
  bool anySpot = false;
  for (const Light& l : scene.lights) anySpot |= l.kind == LightKind::Spot;
  if (!anySpot) return out;
  for (const ParameterSlot& sl : p.params.slots()) {
    if (std::string(sl.kind->name()) != "albedo" || sl.width <= 0 || sl.height <= 0 || sl.material < 0) continue;
    std::vector<int> lit(size_t(sl.width) * size_t(sl.height), -1);
    for (size_t m = 0; m < scene.meshes.size(); ++m) {
      const TriangleMesh& mesh = scene.meshes[m];
      if (scene.meshMaterial[m] != sl.material || mesh.uvs.empty()) continue;
      for (size_t t = 0; t < mesh.triangleCount(); ++t) {
        const uint32_t i0 = mesh.indices[3 * t], i1 = mesh.indices[3 * t + 1], i2 = mesh.indices[3 * t + 2];
        const Vec2 a = mesh.uvs[i0], b = mesh.uvs[i1], c = mesh.uvs[i2];
        const float det = (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
        if (!(std::abs(det) > 0.f)) continue;
        for (int y = 0; y < sl.height; ++y)
          for (int x = 0; x < sl.width; ++x) {
            // The texel's centre in uv (texture.h: v = 0 at the bottom row).
            const Vec2 uv((float(x) + 0.5f) / float(sl.width), 1.f - (float(y) + 0.5f) / float(sl.height));
            const float w1 = ((uv.x - a.x) * (c.y - a.y) - (c.x - a.x) * (uv.y - a.y)) / det;
            const float w2 = ((b.x - a.x) * (uv.y - a.y) - (uv.x - a.x) * (b.y - a.y)) / det;
            if (w1 < 0.f || w2 < 0.f || w1 + w2 > 1.f) continue;
            const Vec3 q = mesh.positions[i0] * (1.f - w1 - w2) + mesh.positions[i1] * w1 + mesh.positions[i2] * w2;
            const Vec3 n = mesh.faceNormals[t];
            int& mark = lit[size_t(y) * size_t(sl.width) + size_t(x)];
            mark = std::max(mark, 0);
            for (uint32_t li = 0; li < scene.lights.size(); ++li) {
              const Light& l = scene.lights[li];
              if (l.kind != LightKind::Spot) continue;
              const LightSample ls = sampleLight(l, scene, q, Vec2(0.5f, 0.5f), li);
              if (!(ls.radiance.x + ls.radiance.y + ls.radiance.z > 0.f) || dot(ls.wi, n) <= 0.f) continue;
              Vec3 dir;
              float tmax;
              if (!scene.occludedSegment(Scene::shadowOrigin(q, n, ls.wi), l.position, dir, tmax)) mark = 1;
            }
          }
      }
    }
    for (size_t k = 0; k < lit.size(); ++k)
      for (int ch = 0; ch < sl.channels; ++ch) {
        if (lit[k] < 0) continue;
        (lit[k] ? out.spotLit : out.others).push_back(sl.offset + uint32_t(k) * uint32_t(sl.channels) + uint32_t(ch));
      }
  }
  return out;
}

// The mean of theta - truth over `indices` (NaN when there are none).
double meanSignedError(const Problem& p, const std::vector<float>& theta, const std::vector<uint32_t>& indices) {
  if (indices.empty()) return std::numeric_limits<double>::quiet_NaN();
  double sum = 0;
  for (uint32_t k : indices) sum += double(theta[k]) - double(p.truth[k]);
  return sum / double(indices.size());
}

void runBenchReconstruct(const ReconstructArgs& a) {
  if (a.steps < 0) throw InputError("--steps must be positive");
  if (a.steps == 0 && !(a.seconds > 0)) throw InputError("--seconds must be positive");
  for (double f : a.lrSweep)
    if (!(f > 0) || !std::isfinite(f)) throw InputError("--lr-sweep: every factor must be a positive number");
  if (a.targetSpp < 1) throw InputError("--target-spp must be positive");
  auto job = benchJob(a.scene, a.params);
  job.mutable_optimization()->set_target_spp(a.targetSpp);
  applySets(job, a.sets);
  if (!a.loss.empty()) job.mutable_optimization()->set_loss(a.loss);
  if (!a.optimizer.empty()) job.mutable_optimization()->set_optimizer(a.optimizer);
  if (a.learningRate > 0)
    for (auto& p : *job.mutable_optimization()->mutable_parameters()) p.set_learning_rate(a.learningRate);
  Setup s{buildProblem(job), {}};
  if (a.burnIn >= 0) s.problem.burnIn = a.burnIn;
  s.targets = renderTargets(s.problem);
  ConvergenceCsv csv(a.csv);
  try {
    csv.write();
  } catch (const InputError&) {
    throw InputError("--csv: cannot write '" + a.csv + "'");
  }
  ImageErrorMeter meter(s.problem, 1, a.imageErrorSpp);
  BenchReport rep("reconstruct");
  rep.text("scene", a.scene);
  if (a.steps > 0) rep.number("steps_per_method", a.steps, "steps (fixed iterations)");
  else rep.number("seconds_per_method", a.seconds, "s");
  rep.number("target_spp", job.optimization().target_spp());  // --target-spp, or a --set of it
  if (a.correlatedPrimal) rep.text("correlated_primal", "yes: the derivative pass draws the primal pass's random numbers (Alg. 4)");
  if (a.burnIn >= 0) rep.number("burn_in", a.burnIn, "ReSTIR's render-only steps");
  // Variants: the three light-sampling methods, or (--pixel-samplers) the listed pixel samplers
  // with the job's own method.
  struct Variant {
    std::string name;
    GradientOptions options;
  };
  std::vector<Variant> variants;
  if (a.pixelSamplers.empty()) {
    for (const std::string& name : a.methods) {
      if (name == "forward_only" || name == "derivative_only") {
        // ReSTIR in one pass only; the other samples with plain RIS.
        GradientOptions o = s.problem.gradient;
        o.method = GradientMethod::Restir;
        o.forwardOnly = name == "forward_only";
        o.derivativeOnly = name == "derivative_only";
        variants.push_back({name, o});
      } else {
        // The job's own samples per pixel (spp_primal, spp_gradient, --set included).
        GradientOptions o = s.problem.gradient;
        o.method = gradientMethodFromName(name);
        variants.push_back({name, o});
      }
    }
  } else {
    for (const auto& name : a.pixelSamplers) {
      GradientOptions o = s.problem.gradient;
      o.pixels.sampler = &pixelSampler(name);
      if (a.pixelSamples > 0) o.pixels.samplesPerView = a.pixelSamples;
      if (a.stage1History > 0) o.pixels.stage1History = a.stage1History;
      variants.push_back({name, o});
    }
  }
  {
    std::vector<std::string> names;
    for (const Variant& v : variants) names.push_back(v.name);
    for (const auto& [name, n] : sppPerVariant(a.spp, names))
      for (Variant& v : variants)
        if (v.name == name) v.options.sppPrimal = v.options.sppGradient = n;
  }
  for (Variant& v : variants) v.options.correlatedPrimal = a.correlatedPrimal;
  // Rotation components (shape and group rotations, degrees): their final error is reported in
  // degrees, the RMSE over those components.
  std::vector<uint32_t> rotation;
  for (const ParameterSlot& sl : s.problem.params.slots())
    if (std::string(sl.kind->name()) == "rotation")
      for (uint32_t i = 0; i < sl.size; ++i) rotation.push_back(sl.offset + i);
  auto degreesOff = [&](const std::vector<float>& theta) {
    double sum = 0;
    for (uint32_t k : rotation) sum += double(theta[k] - s.problem.truth[k]) * double(theta[k] - s.problem.truth[k]);
    return std::sqrt(sum / double(rotation.size()));
  };
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  };
  if (a.seeds < 1) throw InputError("--seeds must be at least 1");
  // Each method runs once per seed (the job's seed, then the next ones); the figures are medians.
  std::vector<double> errors, tails, shapeErrors, floors;
  BenchReport::Json methods = BenchReport::Json::object();
  // Meshes recovered vertex by vertex (from another start mesh: no parameter error) are judged by
  // their shape error, the chamfer distance to the truth over its bounding-box diagonal.
  const bool shapes = shapeError(s.problem, s.problem.initial) >= 0;
  const bool parameters = parameterError(s.problem, s.problem.initial) >= 0;
  const uint64_t firstSeed = s.problem.seed;
  if (a.targetFloor && !parameters) throw InputError("--target-floor: the scene's job has no known parameter truth to start from");
  // Texture texels a spot light reaches and those it does not (oxalis: the spots' and the fill's).
  const TexelRegions regions = parameters ? texelRegionsBySpots(s.problem) : TexelRegions{};
  if (!regions.spotLit.empty())
    rep.text("texel_regions", std::to_string(regions.spotLit.size()) + " texel values a spot light reaches, " + std::to_string(regions.others.size()) +
                                  " none reaches (mean_signed_error_spot_lit, mean_signed_error_others per method)");
  // Learning-rate factors (--lr-sweep): each variant runs at each, and is judged at its best (the
  // lowest median last-quarter error), so no method is judged at another's rate.
  const std::vector<double> factors = a.lrSweep.empty() ? std::vector<double>{1.0} : a.lrSweep;
  std::vector<float> baseRates;
  for (const ParameterSlot& sl : s.problem.params.slots()) baseRates.push_back(sl.learningRate);
  auto setRates = [&](double factor) {
    for (size_t i = 0; i < baseRates.size(); ++i) s.problem.params.setLearningRate(i, float(double(baseRates[i]) * factor));
  };
  EqualTimeOptions budget;
  budget.seconds = a.seconds;
  budget.steps = a.steps;
  struct SeedRuns {
    std::vector<double> finalErrors, finalDegrees, tailErrors, finalShape, tailShape;
    std::vector<double> signedSpotLit, signedOthers;  // mean signed texel error by region, per seed
    int firstSteps = 0;
    double firstImageError = 0;
  };
  const bool judgeShapes = shapes && !parameters;
  auto runSeeds = [&](const Variant& v, const std::string& name) {
    SeedRuns r;
    for (int k = 0; k < a.seeds; ++k) {
      s.problem.seed = firstSeed + uint64_t(k);
      const std::string label = a.seeds > 1 ? name + "_seed" + std::to_string(k) : name;
      EqualTimeRun run = runEqualTime(s.problem, s.targets, v.options, budget, &meter,
                                      [&](const EqualTimePoint& pt) { csv.add(convergenceRow(label, pt)); });
      csv.write();
      r.finalErrors.push_back(run.history.back().parameterError);
      r.tailErrors.push_back(tailParameterError(run.history, budget));  // where it settled
      if (!regions.spotLit.empty()) {
        r.signedSpotLit.push_back(meanSignedError(s.problem, run.theta, regions.spotLit));
        r.signedOthers.push_back(meanSignedError(s.problem, run.theta, regions.others));
      }
      if (!rotation.empty()) r.finalDegrees.push_back(degreesOff(run.theta));
      if (shapes) {
        r.finalShape.push_back(run.history.back().shapeError);
        r.tailShape.push_back(tailShapeError(run.history, budget));
        std::cerr << "[" << a.scene << "] " << label << ": " << run.history.back().step << " steps, shape error "
                  << BenchReport::fmt(run.history.front().shapeError) << " -> " << BenchReport::fmt(r.finalShape.back()) << "\n";
      }
      if (k == 0) {
        r.firstSteps = run.history.back().step;
        r.firstImageError = run.history.back().imageError;
      }
      if (!run.failure.empty()) rep.text("failure_" + label, run.failure);
    }
    s.problem.seed = firstSeed;
    return r;
  };
  auto score = [&](const SeedRuns& r) { return median(judgeShapes ? r.tailShape : r.tailErrors); };
  for (const Variant& v : variants) {
    SeedRuns best;
    double bestFactor = factors.front(), bestScore = std::numeric_limits<double>::infinity();
    BenchReport::Json sweep = BenchReport::Json::object();
    for (double factor : factors) {
      setRates(factor);
      const std::string name = a.lrSweep.empty() ? v.name : v.name + "_lr" + BenchReport::fmt(factor);
      SeedRuns r = runSeeds(v, name);
      const double sc = score(r);
      sweep[BenchReport::fmt(factor)] = sc;
      if (sc < bestScore || !std::isfinite(bestScore)) bestScore = sc, bestFactor = factor, best = std::move(r);
    }
    std::vector<double>& finalErrors = best.finalErrors;
    std::vector<double>& finalDegrees = best.finalDegrees;
    std::vector<double>& tailErrors = best.tailErrors;
    std::vector<double>& finalShape = best.finalShape;
    std::vector<double>& tailShape = best.tailShape;
    rep.number("steps_" + v.name, best.firstSteps);
    rep.number("image_error_" + v.name, best.firstImageError);
    // The targets' own floor for this variant: the same runs started from the truth, at its rate.
    double floor = -1;
    if (a.targetFloor) {
      setRates(bestFactor);
      const std::vector<float> initial = s.problem.initial;
      s.problem.initial = s.problem.truth;
      floor = median(runSeeds(v, v.name + "_from_truth").tailErrors);
      s.problem.initial = initial;
    }
    setRates(1.0);
    s.problem.seed = firstSeed;
    errors.push_back(median(finalErrors));
    BenchReport::Json m = BenchReport::Json::object();
    tails.push_back(median(tailErrors));
    if (parameters) {
      m["median_final_param_error"] = errors.back();
      m["final_param_error"] = finalErrors;
      m["median_param_error_tail"] = tails.back();
      m["param_error_tail"] = tailErrors;
    }
    if (!rotation.empty()) {
      m["median_final_error_degrees"] = median(finalDegrees);
      m["final_error_degrees"] = finalDegrees;
    }
    if (shapes) {
      shapeErrors.push_back(median(finalShape));
      m["median_shape_error"] = shapeErrors.back();
      m["shape_error"] = finalShape;
      m["median_shape_error_tail"] = median(tailShape);
      m["shape_error_tail"] = tailShape;
    }
    // The variant's samples per pixel (the job's, --set and --spp included).
    m["spp_primal"] = v.options.sppPrimal;
    m["spp_gradient"] = v.options.sppGradient;
    if (!a.lrSweep.empty()) {
      m["learning_rate_factor"] = bestFactor;
      m["lr_sweep"] = std::move(sweep);  // factor -> median last-quarter error
    }
    if (!best.signedSpotLit.empty()) {
      m["mean_signed_error_spot_lit"] = median(best.signedSpotLit);
      m["mean_signed_error_others"] = median(best.signedOthers);
    }
    if (floor >= 0) m["floor_param_error"] = floor;
    floors.push_back(floor);
    methods[v.name] = std::move(m);
  }
  rep.number("seeds", a.seeds);
  // One figure per variant, as a JSON object and as "name value, ..." in the table.
  auto perVariant = [&](const std::string& key, const std::vector<double>& values, const std::string& note) {
    BenchReport::Json json = BenchReport::Json::object();
    std::string shown;
    for (size_t i = 0; i < variants.size(); ++i) {
      json[variants[i].name] = values[i];
      shown += std::string(i ? ", " : "") + variants[i].name + " " + BenchReport::fmt(values[i]);
    }
    rep.value(key, std::move(json), shown + " " + note);
  };
  if (!rotation.empty()) {
    std::vector<double> degrees;
    for (const Variant& v : variants) degrees.push_back(methods[v.name]["median_final_error_degrees"].get<double>());
    perVariant("median_final_error_degrees", degrees, "(median over seeds of the final rotation RMSE)");
  }
  rep.value("methods", std::move(methods),
            shapes ? "per method: final and last-quarter shape (and parameter) errors per seed and their medians"
                   : "per method: final and last-quarter parameter errors per seed and their medians");
  auto indexOf = [&](const std::string& n) {
    for (size_t i = 0; i < variants.size(); ++i)
      if (variants[i].name == n) return int(i);
    return -1;
  };
  if (shapes) {
    perVariant("median_shape_error", shapeErrors,
               "(median over seeds of the final chamfer distance over the truth's bounding-box diagonal; target <= 0.01 for restir)");
    for (const char* baseline : {"pt", "ris", "forward_only", "derivative_only"})
      if (indexOf(baseline) >= 0 && indexOf("restir") >= 0)
        rep.number(std::string("shape_error_ratio_") + baseline + "_over_restir",
                   shapeErrors[size_t(indexOf(baseline))] / shapeErrors[size_t(indexOf("restir"))],
                   a.scene == "relief" && (std::string(baseline) == "pt" || std::string(baseline) == "ris") ? "(target >= 2 on the relief)" : "");
  }
  if (!parameters) {
    rep.text("csv", a.csv);
    rep.print(a.json);
    return;
  }
  perVariant("param_error", errors, "(RMSE of the parameters)");
  perVariant("param_error_tail", tails, "(median over seeds of the RMS parameter error over the last quarter of the budget)");
  if (a.targetFloor)
    perVariant("floor_param_error", floors, "(the same, started from the truth: what these targets and this method's noise leave at best)");
  for (const char* baseline : {"pt", "ris", "forward_only", "derivative_only"})
    if (indexOf(baseline) >= 0 && indexOf("restir") >= 0)
      rep.number(std::string("ratio_") + baseline + "_over_restir", errors[size_t(indexOf(baseline))] / errors[size_t(indexOf("restir"))],
                 std::string(baseline) == "pt" ? "(target >= 3)" : a.scene == "tree" ? "(target >= 3 on the tree)" : "");
  for (const char* baseline : {"pt", "ris", "forward_only", "derivative_only"})
    if (indexOf(baseline) >= 0 && indexOf("restir") >= 0)
      rep.number(std::string("tail_ratio_") + baseline + "_over_restir", tails[size_t(indexOf(baseline))] / tails[size_t(indexOf("restir"))]);
  if (indexOf("uniform") >= 0 && indexOf("adaptive") >= 0) {
    rep.number("ratio_uniform_over_adaptive", errors[size_t(indexOf("uniform"))] / errors[size_t(indexOf("adaptive"))]);
    rep.number("tail_ratio_uniform_over_adaptive", tails[size_t(indexOf("uniform"))] / tails[size_t(indexOf("adaptive"))]);
  }
  rep.text("csv", a.csv);
  rep.print(a.json);
}

struct VertexStepArgs {
  std::string scene = "relief";
  std::string shape;  // a shape of the scene to move instead of the job's vertex parameter's
  bool smooth = false;  // that shape smooth-shaded (vertex normals recomputed as it deforms)
  int steps = 12;
  std::vector<std::string> methods{"pt", "ris", "restir"};
  bool json = false;
};

// What moving a mesh by its vertices costs over moving it rigidly: whole optimisation steps
// (gradient, optimiser update with the Large Steps solve, the mesh deformed or moved and its BVH
// refit) on the scene's own mesh, with the zoo job's vertex parameter (its start mesh dropped, so
// both move the same mesh) against the same shape's translation. The two runs alternate step by
// step to share the machine's noise.
BenchReport benchVertexStep(const VertexStepArgs& a) {
  if (a.steps < 2) throw InputError("--steps must be at least 2");
  v1::JobSpec zoo = zooJob(a.scene);
  const v1::ParameterSpec* vertexSpec = nullptr;
  if (!a.shape.empty()) {
    // Another scene's shape: its vertices under the mesh jobs' optimiser settings.
    zoo.mutable_optimization()->clear_parameters();
    auto* ps = zoo.mutable_optimization()->add_parameters();
    ps->set_name("shapes/" + a.shape + "/vertices");
    ps->set_large_steps_lambda(10);
    zoo.mutable_optimization()->set_optimizer("adam_uniform");
  }
  if (a.smooth) {
    if (a.shape.empty()) throw InputError("--smooth needs --shape");
    smoothShadeShapes(zoo, {a.shape}, "--shape");
  }
  for (const auto& ps : zoo.optimization().parameters())
    if (ps.name().size() > 9 && ps.name().compare(ps.name().size() - 9, 9, "/vertices") == 0) vertexSpec = &ps;
  if (!vertexSpec) throw InputError("--scene " + a.scene + ": its job has no vertex parameter (use octagon or relief, or name a shape with --shape)");
  const std::string shapePath = vertexSpec->name().substr(0, vertexSpec->name().size() - 9);  // shapes/<s>
  v1::JobSpec vertexJob = zoo, rigidJob = zoo;
  vertexJob.mutable_optimization()->mutable_parameters(0)->clear_initial_mesh();
  vertexJob.mutable_optimization()->mutable_parameters(0)->set_learning_rate(1e-4);  // small moves: the mesh stays near itself
  rigidJob.mutable_optimization()->clear_parameters();
  auto* t = rigidJob.mutable_optimization()->add_parameters();
  t->set_name(shapePath + "/translation");
  t->set_learning_rate(1e-4);
  rigidJob.mutable_optimization()->set_optimizer("adam");
  for (v1::JobSpec* j : {&vertexJob, &rigidJob}) j->mutable_optimization()->set_target_spp(16);  // targets are not timed
  struct Run {
    std::string name;
    Setup setup;
  };
  Run runs[2] = {{"vertex", {buildProblem(vertexJob), {}}}, {"rigid", {buildProblem(rigidJob), {}}}};
  for (Run& r : runs) r.setup.targets = renderTargets(r.setup.problem);
  BenchReport rep("vertex-step");
  rep.text("scene", a.scene);
  rep.text("shading", runs[0].setup.problem.scene->meshes[size_t(runs[0].setup.problem.params.slots()[0].shape)].normals.empty() ? "flat" : "smooth");
  rep.text("parameters", vertexSpec->name() + " (" + std::to_string(runs[0].setup.problem.params.size()) + " values) against " + shapePath +
                             "/translation");
  rep.number("triangles", double(runs[0].setup.problem.scene->meshes.empty() ? 0 : [&] {
               size_t n = 0;
               for (const auto& m : runs[0].setup.problem.scene->meshes) n += m.triangleCount();
               return n;
             }()));
  for (const std::string& name : a.methods) {
    const GradientMethod m = gradientMethodFromName(name);
    std::vector<double> seconds[2];
    std::unique_ptr<LocalEvaluator> eval[2];
    std::unique_ptr<OptimizationLoop> loop[2];
    for (int k = 0; k < 2; ++k) {
      Problem& p = runs[k].setup.problem;
      eval[k] = std::make_unique<LocalEvaluator>(p, runs[k].setup.targets, optionsFor(p, m, 1));
      LoopState begin;
      begin.theta = p.initial;
      loop[k] = std::make_unique<OptimizationLoop>(p, std::move(begin), m == GradientMethod::Restir ? p.burnIn : 0, 0);
    }
    for (int i = 0; i < a.steps + 1; ++i)
      for (int k = 0; k < 2; ++k) {
        std::optional<GradientResult> g;
        double used = 0;
        do {  // burn-in evaluations are not steps
          Stopwatch clock;
          g = loop[k]->next(std::ref(*eval[k]));
          used = clock.seconds();
        } while (!g);
        if (i > 0) seconds[k].push_back(used);  // the first step warms caches and allocations
      }
    double median[2];
    for (int k = 0; k < 2; ++k) {
      std::sort(seconds[k].begin(), seconds[k].end());
      median[k] = seconds[k][seconds[k].size() / 2];
      rep.number(name + "_" + runs[k].name + "_step_seconds", median[k], "s (median of " + std::to_string(a.steps) + ")");
    }
    rep.number(name + "_ratio_vertex_over_rigid", median[0] / median[1], "(target <= 1.5)");
    for (Run& r : runs) r.setup.problem.params.write(r.setup.problem.initial, *r.setup.problem.scene);
  }
  return rep;
}

}  // namespace

void addBenchGradientCommands(CLI::App& bench, int& exitCode) {
  auto ga = std::make_shared<GradientsArgs>();
  auto* g = bench.add_subcommand("gradients", "Equal-time gradient error (relative MSE vs a high-sample reference): PT, RIS, ReSTIR");
  g->add_option("--scene", ga->scene, "zoo scene (ajar or oxalis; tree, knot or pose: shape gradients)")->capture_default_str();
  g->add_option("--reps", ga->reps, "gradient evaluations averaged per method")->capture_default_str();
  g->add_option("--restir-chains", ga->restirChains, "independent ReSTIR chains the reps are split over (for the standard error)")
      ->capture_default_str();
  g->add_option("--burn-in", ga->burnIn, "ReSTIR render-only steps before measuring")->capture_default_str();
  g->add_option("--ref-evaluations", ga->refEvaluations, "reference: independent RIS evaluations averaged (not the method under test)")->capture_default_str();
  g->add_option("--ref-spp", ga->refSpp, "reference: spp of each evaluation")->capture_default_str();
  g->add_option("--sampler", ga->sampler, "every pass's sampler: independent or sobol (default: the job's)")
      ->check(CLI::IsMember({"independent", "sobol"}));
  g->add_option("--neighbours", ga->neighbours, "ReSTIR neighbours (default: the scene job's)");
  g->add_option("--m-cap", ga->mCap, "ReSTIR confidence cap (default: the scene job's, 2 x M)");
  g->add_option("--radius-pixels", ga->radiusPixels, "ReSTIR neighbour radius in pixel footprints (default: the job's)");
  g->add_option("--edge-neighbours", ga->edgeNeighbours,
                 "shape jobs: edge reservoirs merged per secondary-boundary sample, 0..8 (default: the job's)");
  g->add_flag("!--no-ablations", ga->ablations, "shape jobs: skip the per-term and edge-importance rows");
  g->add_option("--param", ga->params,
                 "NAME[=V[,V,V]]: measure this parameter's gradient instead of the job's, at the values given (e.g. "
                 "shapes/knot/translation=0.05,0,0; repeatable)")
      ->allow_extra_args(false);
  g->add_flag("--json", ga->json, "print one JSON object");
  g->callback([ga, &exitCode] { benchGradients(*ga).print(ga->json); exitCode = 0; });

  auto oa = std::make_shared<OverheadArgs>();
  auto* o = bench.add_subcommand("overhead", "ReSTIR's overhead over RIS at equal sample counts, as a fraction of step time");
  o->add_option("--scene", oa->scene, "zoo scene")->capture_default_str();
  o->add_option("--steps", oa->steps, "timed steps of each")->capture_default_str();
  o->add_flag("--json", oa->json, "print one JSON object");
  o->callback([oa, &exitCode] { benchOverhead(*oa).print(oa->json); exitCode = 0; });

  auto ra = std::make_shared<ReconstructArgs>();
  auto* rc = bench.add_subcommand("reconstruct", "Equal-time reconstruction of the scene's parameters: PT, RIS, ReSTIR (or pixel samplers)");
  rc->add_option("--scene", ra->scene, "zoo scene")->capture_default_str();
  rc->add_option("--seconds", ra->seconds, "wall time per method")->capture_default_str();
  rc->add_option("--loss", ra->loss, "override the loss (l2, relative_l2, l1)");
  rc->add_option("--lr", ra->learningRate, "override every parameter's learning rate");
  rc->add_option("--optimizer", ra->optimizer, "override the optimizer (adam, sgd)");
  std::string samplerNames;
  for (const PixelSampler* ps : pixelSamplers()) samplerNames += std::string(samplerNames.empty() ? "" : ", ") + ps->name();
  rc->add_option("--pixel-samplers", ra->pixelSamplers, "compare these pixel samplers (" + samplerNames + ") with the job's method")
      ->delimiter(',');
  rc->add_option("--pixel-samples", ra->pixelSamples, "pixel samples per view for the mini-batch samplers");
  rc->add_option("--stage1-history", ra->stage1History, "with --pixel-samplers: loss_grad's and adaptive's maps average this many stage-1 passes (default: the job's)")
      ->check(CLI::Range(1, 1024));
  rc->add_option("--set", ra->sets,
                 "FIELD.PATH=VALUE: set any field of the scene's job before the runs, e.g. optimization.pixel_refresh=5, "
                 "optimization.pixel_defensive=0.5, optimization.method=pt (repeatable)");
  rc->add_option("--csv", ra->csv, "convergence data: method, step, seconds, loss, param_error, image_error, then one column per statistic")->capture_default_str();
  rc->add_option("--param", ra->params, "NAME[=V[,V,V]]: recover this parameter instead of the job's, from the values given (repeatable)")
      ->allow_extra_args(false);
  rc->add_option("--methods", ra->methods, "light-sampling methods to compare: pt, ris, restir, forward_only (ReSTIR in the primal pass only), derivative_only (in the derivative pass only)")
      ->delimiter(',')
      ->check(CLI::IsMember({"pt", "ris", "restir", "forward_only", "derivative_only"}))
      ->capture_default_str();
  rc->add_option("--seeds", ra->seeds, "runs per method, with the job's seed and the next ones; final errors are medians")
      ->capture_default_str();
  rc->add_option("--image-error-spp", ra->imageErrorSpp, "samples per pixel of the image error (its reference render and each measurement, off the clock)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  rc->add_option("--steps", ra->steps, "fixed iterations per run instead of --seconds (Wang et al. 2023's protocol; burn-in not counted)");
  rc->add_option("--spp", ra->spp, "METHOD=N: that variant's samples per pixel in the primal and derivative passes, e.g. pt=8 (repeatable)");
  rc->add_option("--burn-in", ra->burnIn, "ReSTIR's render-only steps before the first gradient (default: the job's)");
  rc->add_flag("--correlated-primal", ra->correlatedPrimal,
               "the derivative pass draws the primal pass's random numbers (Alg. 4: primal and derivative from one sample; biased for L2)");
  rc->add_option("--lr-sweep", ra->lrSweep, "factors of every parameter's learning rate, e.g. 0.3,1,3: each variant runs at each and is judged at its best")
      ->delimiter(',');
  rc->add_flag("--target-floor", ra->targetFloor, "also run each variant from the truth (floor_param_error: the targets' and the method's own floor)");
  rc->add_option("--target-spp", ra->targetSpp, "samples per pixel of the rendered targets")->capture_default_str();
  rc->add_flag("--json", ra->json, "print one JSON object");
  rc->callback([ra, &exitCode] { runBenchReconstruct(*ra); exitCode = 0; });

  auto va = std::make_shared<VertexStepArgs>();
  auto* vs = bench.add_subcommand("vertex-step", "A whole optimisation step with a mesh's vertices as the parameter against its rigid translation, same mesh");
  vs->add_option("--scene", va->scene, "zoo scene whose job has a vertex parameter (octagon or relief), or any with --shape")->capture_default_str();
  vs->add_option("--shape", va->shape, "move this shape of the scene instead (e.g. --scene knot --shape knot; Large Steps lambda 10, adam_uniform)");
  vs->add_flag("--smooth", va->smooth, "with --shape: that shape smooth-shaded (angle-weighted vertex normals, recomputed as it deforms)");
  vs->add_option("--steps", va->steps, "timed steps of each (after one untimed)")->capture_default_str();
  vs->add_option("--methods", va->methods, "pt, ris, restir")->delimiter(',')->check(CLI::IsMember({"pt", "ris", "restir"}))->capture_default_str();
  vs->add_flag("--json", va->json, "print one JSON object");
  vs->callback([va, &exitCode] { benchVertexStep(*va).print(va->json); exitCode = 0; });
}

}  // namespace invr::cli
