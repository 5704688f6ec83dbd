// invr-lab bench sampler: how long the forward renderer needs to reach a given error with independent
// samples and with Owen-scrambled Sobol points (core/math/rng.h), at each path depth asked for.
//
// Error: RMSE against a converged reference (two independent renders at half the reference's spp;
// their difference estimates the reference's own error, which is subtracted from every MSE), over
// all pixels and over the pixels inside regions (3x3 neighbourhoods with one first-hit surface:
// the same normal and albedo and depth within 2 %, so silhouettes and material edges are out;
// shadow borders stay in). Each sampler renders at 1, 2, 4, ... spp (the fastest of --repeats
// runs, interleaved with the other sampler's, is its time); the target is the independent
// sampler's error at --target-spp; the spp at which each sampler reaches it is interpolated on
// its error-against-spp curve in log-log, and its time at that spp on its time-against-spp curve.
#include <cmath>
#include <iostream>
#include <limits>
#include <map>

#include "client/lab/lab_commands.h"
#include "client/common/bench_report.h"
#include "core/error.h"
#include "core/render/renderer.h"
#include "core/scene/scene_builder.h"
#include "core/scene/zoo.h"

namespace invr::cli {

namespace {

struct SamplerBenchArgs {
  std::string scene = "cornell";
  std::vector<int> depths = {1, 4};
  int resolution = 128;
  int referenceSpp = 4096;
  int maxSpp = 256;
  int targetSpp = 64;
  int repeats = 2;
  bool json = false;
};

struct Curve {
  std::vector<int> spp;
  std::vector<double> seconds, mseAll, mseInterior;
};

// Pixels inside regions: every 3x3 neighbour sees the same surface as the centre.
std::vector<uint8_t> interiorMask(const Aovs& a) {
  const int W = a.albedo.width(), H = a.albedo.height();
  std::vector<uint8_t> m(size_t(W) * size_t(H), 0);
  for (int y = 1; y + 1 < H; ++y)
    for (int x = 1; x + 1 < W; ++x) {
      const float d = a.depth.at(x, y, 0);
      if (!(d > 0.f)) continue;  // background
      bool same = true;
      for (int dy = -1; dy <= 1 && same; ++dy)
        for (int dx = -1; dx <= 1 && same; ++dx) {
          const Rgb n0 = a.normal.rgb(x, y), n1 = a.normal.rgb(x + dx, y + dy);
          const Rgb a0 = a.albedo.rgb(x, y), a1 = a.albedo.rgb(x + dx, y + dy);
          const float d1 = a.depth.at(x + dx, y + dy, 0);
          same = n0.x * n1.x + n0.y * n1.y + n0.z * n1.z > 0.999f && std::abs(a0.x - a1.x) + std::abs(a0.y - a1.y) + std::abs(a0.z - a1.z) < 1e-3f &&
                 std::abs(d1 - d) < 0.02f * d;
        }
      m[size_t(y) * size_t(W) + size_t(x)] = same;
    }
  return m;
}

// Mean squared difference over the pixels (and channels) the mask keeps (all when null).
double mse(const Image& a, const Image& b, const std::vector<uint8_t>* mask) {
  double s = 0;
  size_t n = 0;
  const size_t pixels = size_t(a.width()) * size_t(a.height());
  for (size_t p = 0; p < pixels; ++p) {
    if (mask && !(*mask)[p]) continue;
    for (size_t c = 0; c < 3; ++c) {
      const double d = double(a.data()[3 * p + c]) - double(b.data()[3 * p + c]);
      s += d * d;
    }
    n += 3;
  }
  return n ? s / double(n) : std::numeric_limits<double>::quiet_NaN();
}

// Samples per pixel at which the curve's MSE reaches `target`: log-log interpolation between the
// renders around it, the last segment's slope past the last; never fewer than the first render's
// (no render has fewer), and a render whose error is below the reference's own reaches it. NaN
// if the error never falls.
double sppToReach(const std::vector<int>& spp, const std::vector<double>& e, double target) {
  if (!(target > 0)) return std::numeric_limits<double>::quiet_NaN();
  if (e[0] <= target) return spp[0];
  for (size_t i = 1; i < e.size(); ++i) {
    if (e[i] > target && i + 1 < e.size()) continue;
    if (!(e[i] > 0)) return spp[i];
    if (!(e[i] < e[i - 1])) return std::numeric_limits<double>::quiet_NaN();
    const double slope = std::log(e[i] / e[i - 1]) / std::log(double(spp[i]) / double(spp[i - 1]));
    return double(spp[i - 1]) * std::exp(std::log(target / e[i - 1]) / slope);
  }
  return std::numeric_limits<double>::quiet_NaN();
}

// The render time at (fractional) spp s, interpolated in log-log between the measured renders
// (time is nearly linear in spp, so this is close whatever the noise of one render).
double timeAt(const std::vector<int>& spp, const std::vector<double>& t, double s) {
  if (!std::isfinite(s)) return std::numeric_limits<double>::quiet_NaN();
  size_t i = 1;
  while (i + 1 < spp.size() && double(spp[i]) < s) ++i;
  const double a = std::log(t[i] / t[i - 1]) / std::log(double(spp[i]) / double(spp[i - 1]));
  return t[i - 1] * std::pow(s / double(spp[i - 1]), a);
}

BenchReport::Json curveJson(const Curve& c) {
  BenchReport::Json o = BenchReport::Json::object();
  o["spp"] = c.spp;
  o["seconds"] = c.seconds;
  std::vector<double> all, interior;
  for (double v : c.mseAll) all.push_back(std::sqrt(std::max(0.0, v)));
  for (double v : c.mseInterior) interior.push_back(std::sqrt(std::max(0.0, v)));
  o["rmse_all"] = all;
  o["rmse_interior"] = interior;
  return o;
}

void runBenchSampler(const SamplerBenchArgs& a) {
  if (a.resolution <= 0 || a.referenceSpp < 2 || a.maxSpp < 2 || a.targetSpp <= 0 || a.targetSpp > a.maxSpp || a.repeats <= 0)
    throw InputError("bench sampler: --resolution and --repeats must be positive, --max-spp at least 2, --reference-spp at least 2, --target-spp in 1..--max-spp");
  if ((a.targetSpp & (a.targetSpp - 1)) != 0) throw InputError("bench sampler: --target-spp must be a power of two (got " + std::to_string(a.targetSpp) + ")");
  if (a.referenceSpp < 8 * a.maxSpp) throw InputError("bench sampler: --reference-spp must be at least 8x --max-spp (the reference must converge further)");
  auto spec = zooScene(a.scene);
  const double aspect = double(spec.film().height()) / double(spec.film().width());
  spec.mutable_film()->set_width(a.resolution);
  spec.mutable_film()->set_height(std::max(1, int(std::lround(a.resolution * aspect))));
  auto scene = buildScene(spec);
  const std::vector<uint8_t> interior = interiorMask(renderAovs(*scene, 0));
  size_t inside = 0;
  for (uint8_t v : interior) inside += v;

  BenchReport rep("sampler");
  rep.text("scene", a.scene);
  rep.number("width", scene->width);
  rep.number("height", scene->height);
  rep.number("interior_pixels", double(inside));
  rep.number("target_spp", a.targetSpp, "(the target error: the independent sampler's at this spp)");
  for (int depth : a.depths) {
    RenderOptions base;
    base.maxDepth = depth;
    base.estimator = LightEstimator::NeeMis;
    // The reference: two independent halves; their difference measures its own error.
    RenderOptions ro = base;
    ro.spp = a.referenceSpp / 2;
    ro.seed = 0xfeed0001;
    std::cerr << "bench sampler: reference, depth " << depth << ", 2 x " << ro.spp << " spp\n";
    const Image refA = renderView(*scene, 0, ro).image;
    ro.seed = 0xfeed0002;
    const Image refB = renderView(*scene, 0, ro).image;
    Image ref = refA;
    for (size_t i = 0; i < ref.data().size(); ++i) ref.data()[i] = 0.5f * (refA.data()[i] + refB.data()[i]);
    const double refMseAll = mse(refA, refB, nullptr) / 4, refMseInterior = mse(refA, refB, &interior) / 4;

    std::map<SamplerKind, Curve> curves;
    for (int spp = 1; spp <= a.maxSpp; spp *= 2) {
      // The repeats interleave the two samplers (a shared machine); each keeps its fastest.
      std::map<SamplerKind, double> best;
      std::map<SamplerKind, Image> image;
      for (int r = 0; r < a.repeats; ++r)
        for (SamplerKind kind : {SamplerKind::Independent, SamplerKind::Sobol}) {
          RenderOptions o = base;
          o.spp = spp;
          o.sampler = kind;
          o.seed = 1000 + uint64_t(spp);
          RenderResult res = renderView(*scene, 0, o);
          best[kind] = r == 0 ? res.seconds : std::min(best[kind], res.seconds);
          image[kind] = std::move(res.image);  // the same image every repeat (same seed)
        }
      for (SamplerKind kind : {SamplerKind::Independent, SamplerKind::Sobol}) {
        Curve& c = curves[kind];
        c.spp.push_back(spp);
        c.seconds.push_back(best[kind]);
        c.mseAll.push_back(mse(image[kind], ref, nullptr) - refMseAll);
        c.mseInterior.push_back(mse(image[kind], ref, &interior) - refMseInterior);
      }
    }
    const Curve& ind = curves[SamplerKind::Independent];
    const Curve& sob = curves[SamplerKind::Sobol];
    size_t ti = 0;
    while (ind.spp[ti] != a.targetSpp) ++ti;  // a power of two up to --max-spp (checked above)
    BenchReport::Json d = BenchReport::Json::object();
    std::string display;
    for (const char* region : {"all", "interior"}) {
      const bool all = std::string(region) == "all";
      const double target = all ? ind.mseAll[ti] : ind.mseInterior[ti];
      const double tInd = timeAt(ind.spp, ind.seconds, sppToReach(ind.spp, all ? ind.mseAll : ind.mseInterior, target));
      const double tSob = timeAt(sob.spp, sob.seconds, sppToReach(sob.spp, all ? sob.mseAll : sob.mseInterior, target));
      d[std::string("target_rmse_") + region] = std::sqrt(std::max(0.0, target));
      d[std::string("reference_rmse_") + region] = std::sqrt(std::max(0.0, all ? refMseAll : refMseInterior));
      d[std::string("seconds_to_target_independent_") + region] = tInd;
      d[std::string("seconds_to_target_sobol_") + region] = tSob;
      d[std::string("ratio_time_independent_over_sobol_") + region] = tInd / tSob;
      display += std::string(display.empty() ? "" : ", ") + region + " " + BenchReport::fmt(tInd / tSob) + " (" + BenchReport::fmt(tInd) +
                 " s / " + BenchReport::fmt(tSob) + " s)";
    }
    d["independent"] = curveJson(ind);
    d["sobol"] = curveJson(sob);
    if (a.depths.size() == 1) {
      for (const auto& [k, v] : d.items())
        if (k.rfind("ratio_", 0) != 0) rep.value(k, v, BenchReport::line(v));
      rep.number("max_depth", depth);
      rep.number("ratio_time_independent_over_sobol_all", d["ratio_time_independent_over_sobol_all"].get<double>(),
                 "(time to the target error, independent / sobol, all pixels)");
      rep.number("ratio_time_independent_over_sobol_interior", d["ratio_time_independent_over_sobol_interior"].get<double>(),
                 "(inside regions)");
    } else {
      rep.value("depth_" + std::to_string(depth), d, "time to target, independent / sobol: " + display);
    }
  }
  rep.print(a.json);
}

}  // namespace

void addBenchSamplerCommand(CLI::App& bench, int& exitCode) {
  auto a = std::make_shared<SamplerBenchArgs>();
  auto* c = bench.add_subcommand("sampler", "Time to a given error against a converged reference: independent samples against Owen-scrambled Sobol points");
  c->add_option("--scene", a->scene, "zoo scene (view 0)")->capture_default_str();
  c->add_option("--max-depth", a->depths, "path vertices after the camera (repeatable; default 1 and 4)")->check(CLI::Range(1, 64));
  c->add_option("--resolution", a->resolution, "film width (the height keeps the scene's aspect)")->capture_default_str()->check(CLI::Range(8, 4096));
  c->add_option("--reference-spp", a->referenceSpp, "samples per pixel of the reference (two independent halves)")->capture_default_str();
  c->add_option("--max-spp", a->maxSpp, "largest spp of the measured renders (1, 2, 4, ... up to it)")->capture_default_str();
  c->add_option("--target-spp", a->targetSpp, "the target error is the independent sampler's at this spp (a power of two)")->capture_default_str();
  c->add_option("--repeats", a->repeats, "timed runs of each render (the fastest kept)")->capture_default_str();
  c->add_flag("--json", a->json, "print one JSON object");
  c->callback([a, &exitCode] {
    runBenchSampler(*a);
    exitCode = 0;
  });
}

}  // namespace invr::cli
