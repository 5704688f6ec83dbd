// `invr-lab bench derivative-images`: Wang et al. 2023's own measure (Fig. 6, "up to 100x lower
// relative error at equal frame time"). One scalar parameter moves along an animation of N
// frames; each frame, PT, RIS and ReSTIR estimate the per-pixel derivative image dI/dtheta (the
// derivative pass and every boundary term, GradientRequest::derivativeImage), ReSTIR reusing its
// reservoirs from frame to frame, PT and RIS given as many samples as fit in ReSTIR's frame time.
// Each is compared with an independent high-sample RIS reference of the same frame.
//
// The reference is two independent halves R1, R2. Against their mean R, an estimate X's squared
// error sum |X - R|^2 overstates its true error by the reference's own variance, which
// |R1 - R2|^2 / 4 estimates without bias; the figures subtract it (and the raw ones, a lower bound
// on every ratio, are printed beside them). relMSE is the image's relative squared error,
// sum (X - R)^2 / sum R^2, so the ratio of two methods' relMSE is the ratio of their MSEs.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <limits>
#include <memory>
#include <regex>

#include "client/common/bench_report.h"
#include "client/common/job_argument.h"
#include "client/lab/bench.h"
#include "client/lab/lab_commands.h"
#include "core/diff/gradient_engine.h"
#include "core/error.h"
#include "core/image/image.h"
#include "core/job/problem.h"
#include "core/job/zoo_jobs.h"
#include "core/scene/scene_builder.h"
#include "core/stopwatch.h"

namespace invr::cli {

namespace {

struct DerivativeImagesArgs {
  std::string scene = "knot";
  std::string param;  // NAME or NAME[i]; empty: the scene's own (defaultParameter)
  int frames = 16;
  double to = std::numeric_limits<double>::quiet_NaN();  // the value's end point; NaN: see trajectory()
  int view = 0;
  int restirSpp = 1;
  int refSpp = 64;   // per half of the reference
  int burnIn = -1;   // ReSTIR's render-only steps before frame 0; -1: the job's
  std::vector<std::string> methods = {"pt", "ris", "restir"};
  std::string out;   // folder for the last frame's images
  std::vector<std::string> smooth;  // shapes to smooth-shade
  std::vector<std::string> sets;    // --set FIELD.PATH=VALUE on the scene's job
  bool interiorOnly = false;  // boundary terms off, in the methods and the reference (Fig. 7's b1)
  bool equalSpp = false;  // every method at --restir-spp (equal samples, not equal time)
  uint64_t seed = 7;
  bool json = false;
};

// The scalar each zoo scene of the paper's figure is measured for.
std::string defaultParameter(const std::string& scene, const v1::JobSpec& job) {
  if (scene == "knot") return "shapes/knot/translation[0]";  // translates horizontally (Fig. 6, top)
  if (scene == "key") return "groups/key/rotation[1]";       // turns about the vertical (Fig. 6, bottom)
  if (scene == "oxalis") return "lights/spot_left/intensity[0]";
  if (job.optimization().parameters_size() == 0) throw InputError("--param: the scene's job has no parameters; name one");
  return job.optimization().parameters(0).name() + "[0]";
}

struct ChosenValue {
  std::string name;
  size_t component = 0;
};

ChosenValue parseValueName(const std::string& text) {
  static const std::regex indexed(R"(^(.+)\[([0-9]+)\]$)");
  std::smatch m;
  if (std::regex_match(text, m, indexed)) return {m[1].str(), size_t(std::stoul(m[2].str()))};
  return {text, 0};
}

struct FrameImage {
  std::vector<double> image;
  double seconds = 0;
};

// One frame's errors. relMSE is the rendering literature's per-pixel form, the mean over pixels of
// (X - R)^2 / (R^2 + eps), with eps a hundredth of the reference's mean R^2 (derivative images
// have no natural unit); the squared error is the image's, sum (X - R)^2 / sum R^2, which the
// pixels of largest derivative (silhouettes, shadow borders) dominate. Both subtract the
// reference's own noise, per pixel (R1 - R2)^2 / 4, from numerator and denominator.
struct FrameError {
  double relmse = 0, relmseRaw = 0;  // per-pixel form: reference noise subtracted, and as it is
  double floor = 0;                  // the reference's own per-pixel relMSE
  double squared = 0;                // image form, reference noise subtracted
};

FrameError frameError(const std::vector<double>& x, const std::vector<double>& r1, const std::vector<double>& r2) {
  double power = 0;
  for (size_t i = 0; i < x.size(); ++i) power += 0.25 * (r1[i] + r2[i]) * (r1[i] + r2[i]);
  const double eps = 0.01 * power / double(x.size());
  FrameError e;
  double err = 0, noise = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    const double r = 0.5 * (r1[i] + r2[i]), d = r1[i] - r2[i], n = 0.25 * d * d;
    const double sq = (x[i] - r) * (x[i] - r);
    const double den = std::max(r * r - n, 0.0) + eps;
    e.relmse += (sq - n) / den;
    e.relmseRaw += sq / (r * r + eps);
    e.floor += n / den;
    err += sq;
    noise += n;
  }
  e.relmse /= double(x.size());
  e.relmseRaw /= double(x.size());
  e.floor /= double(x.size());
  e.squared = (err - noise) / (power - noise);  // E[sum R^2] = sum (true)^2 + the same noise
  return e;
}

double finiteMedian(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// A derivative image as a picture: red where positive, blue where negative, white at +-scale.
Image derivativeFalseColour(const std::vector<double>& d, int w, int h, double scale) {
  Image img(w, h, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double v = std::clamp(d[size_t(y) * size_t(w) + size_t(x)] / scale, -1.0, 1.0);
      const float a = float(std::abs(v));
      img.setRgb(x, y, v >= 0 ? Rgb(a, a * a * 0.6f, a * a * 0.3f) : Rgb(a * a * 0.3f, a * a * 0.6f, a));
    }
  return img;
}

Image derivativeGreyImage(const std::vector<double>& d, int w, int h) {
  Image img(w, h, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) img.setRgb(x, y, Rgb(float(d[size_t(y) * size_t(w) + size_t(x)])));
  return img;
}

BenchReport benchDerivativeImages(const DerivativeImagesArgs& a) {
  if (a.frames < 1) throw InputError("--frames: at least 1");
  if (a.restirSpp < 1 || a.refSpp < 1) throw InputError("--restir-spp and --ref-spp: at least 1");
  v1::JobSpec job = zooJob(a.scene);
  const ChosenValue chosen = parseValueName(a.param.empty() ? defaultParameter(a.scene, job) : a.param);
  bool inJob = false;
  for (const auto& ps : job.optimization().parameters()) inJob = inJob || ps.name() == chosen.name;
  if (!inJob) {  // the value's own parameter, at the scene's value, replaces the job's
    AssetResolver assets;
    SceneArgs args;
    args.params = {chosen.name};
    job = optimizationJobFromArgument(a.scene, assets, args);
  }
  smoothShadeShapes(job, a.smooth, "--smooth");
  applySets(job, a.sets);
  Problem p = buildProblem(job);
  const ParameterSlot* slot = p.params.find(chosen.name);
  if (!slot) throw InputError("--param: " + chosen.name + " is not a parameter of " + a.scene);
  if (chosen.component >= slot->size)
    throw InputError("--param: " + chosen.name + " has " + std::to_string(slot->size) + " values; [" + std::to_string(chosen.component) + "] is past them");
  if (a.view < 0 || size_t(a.view) >= p.scene->cameras.size()) throw InputError("--view: out of range");
  const uint32_t index = slot->offset + uint32_t(chosen.component);
  const int W = p.scene->width, H = p.scene->height;

  // The trajectory: the value goes from the job's start to its truth (or to --to; when the two are
  // the same, to 1.5 times the start, or 0.1 from 0), every other value stays at the job's start.
  const double from = p.initial[index];
  double to = std::isfinite(a.to) ? a.to : double(p.truth[index]);
  if (!std::isfinite(a.to) && to == from) to = from != 0.0 ? 1.5 * from : 0.1;
  auto thetaAt = [&](int f) {
    std::vector<float> theta = p.initial;
    theta[index] = float(from + (to - from) * (a.frames > 1 ? double(f) / double(a.frames - 1) : 0.0));
    p.params.clampToBounds(theta);
    return theta;
  };
  const int burnIn = a.burnIn >= 0 ? a.burnIn : p.burnIn;
  const int baseBoundary = p.gradient.boundary.samplesFor(W, H);
  // Every sample count of a frame scales with spp: the camera samples and each boundary term's.
  auto optionsFor = [&](GradientMethod m, int spp) {
    GradientOptions o = p.gradient;
    o.method = m;
    o.forwardOnly = o.derivativeOnly = false;
    o.correlatedPrimal = false;
    o.sppPrimal = o.sppGradient = spp;
    o.boundary.samples = baseBoundary * spp;
    if (a.interiorOnly) o.boundary.primary = o.boundary.secondary = false;
    return o;
  };
  auto evaluateFrame = [&](GradientEngine& engine, EngineSession& session, uint64_t step, uint64_t seed) {
    PixelDerivativeSink sink;
    sink.index = index;
    GradientRequest r;
    r.views = {a.view};
    r.step = step;
    r.seed = seed;
    r.allSessionViews = true;
    r.derivativeImage = &sink;
    Stopwatch clock;
    engine.evaluate(r, session);
    return FrameImage{std::move(sink.image), clock.seconds()};
  };
  auto burn = [&](GradientEngine& engine, EngineSession& session, uint64_t seed) {
    for (int b = 0; b < burnIn; ++b) {
      GradientRequest r;
      r.views = {a.view};
      r.step = uint64_t(b);
      r.seed = seed;
      r.allSessionViews = true;
      r.renderOnly = true;
      engine.evaluate(r, session);
    }
  };
  std::vector<GradientMethod> methods;
  for (const std::string& m : a.methods) methods.push_back(gradientMethodFromName(m));
  const bool haveRestir = std::find(methods.begin(), methods.end(), GradientMethod::Restir) != methods.end();

  // Equal frame time: ReSTIR's frame at --restir-spp (median of 3 after burn-in) is the budget; PT
  // and RIS get the spp whose 1-spp frame time fits it (at least 1).
  p.params.write(thetaAt(0), *p.scene);
  auto frameSeconds = [&](GradientMethod m, int spp) {
    GradientEngine engine(*p.scene, p.params, {}, optionsFor(m, spp));
    EngineSession session;
    const bool restir = m == GradientMethod::Restir;
    if (restir) burn(engine, session, a.seed + 1000);
    std::vector<double> t;
    for (int i = 0; i < 4; ++i) {
      const double s = evaluateFrame(engine, session, uint64_t(burnIn + i), a.seed + 1000).seconds;
      if (i > 0) t.push_back(s);
    }
    return finiteMedian(t);
  };
  const double budget = frameSeconds(haveRestir ? GradientMethod::Restir : methods.front(), haveRestir ? a.restirSpp : 1);
  std::vector<int> spp;
  for (GradientMethod m : methods)
    spp.push_back(m == GradientMethod::Restir || a.equalSpp ? a.restirSpp : std::max(1, int(std::lround(budget / frameSeconds(m, 1)))));

  // The reference: two independent RIS halves per frame (RIS is checked against finite differences
  // in tests/core/diff; a ReSTIR bias would show against it).
  std::vector<std::vector<double>> ref1(size_t(a.frames)), ref2(size_t(a.frames));
  bool anySignal = false;
  {
    GradientEngine engine(*p.scene, p.params, {}, optionsFor(GradientMethod::Ris, a.refSpp));
    for (int f = 0; f < a.frames; ++f) {
      p.params.write(thetaAt(f), *p.scene);
      EngineSession s1, s2;
      ref1[size_t(f)] = evaluateFrame(engine, s1, uint64_t(f), a.seed + 900001).image;
      ref2[size_t(f)] = evaluateFrame(engine, s2, uint64_t(f), a.seed + 900002).image;
      for (size_t i = 0; i < ref1[size_t(f)].size(); ++i) anySignal = anySignal || ref1[size_t(f)][i] != 0.0 || ref2[size_t(f)][i] != 0.0;
    }
  }
  if (!anySignal)
    throw InputError("--param: " + chosen.name + "[" + std::to_string(chosen.component) + "] changes no pixel of view " + std::to_string(a.view) +
                     " (its derivative image is zero in every frame); pick a value the view sees");

  BenchReport rep("derivative-images");
  rep.text("scene", a.scene);
  rep.text("parameter", chosen.name + "[" + std::to_string(chosen.component) + "]");
  rep.value("trajectory", {{"from", from}, {"to", to}}, BenchReport::fmt(from) + " -> " + BenchReport::fmt(to) + " over the frames");
  rep.number("frames", a.frames);
  rep.number("pixels", double(W) * double(H));
  rep.number("burn_in", burnIn, "(ReSTIR render-only steps before frame 0, not timed)");
  rep.number("reference_spp", 2 * a.refSpp, "(RIS, two independent halves)");
  rep.number("budget_seconds_per_frame", budget, "s (ReSTIR's frame)");
  rep.text("comparison", a.equalSpp ? "equal samples per pixel" : "equal frame time");
  rep.text("components", a.interiorOnly ? "interior" : "interior and every boundary term");

  std::vector<std::vector<FrameError>> errors(methods.size());
  std::vector<double> frameTime(methods.size());
  std::vector<std::vector<double>> lastImage(methods.size());
  for (size_t k = 0; k < methods.size(); ++k) {
    GradientEngine engine(*p.scene, p.params, {}, optionsFor(methods[k], spp[k]));
    EngineSession session;
    p.params.write(thetaAt(0), *p.scene);
    burn(engine, session, a.seed);
    std::vector<double> seconds;
    for (int f = 0; f < a.frames; ++f) {
      p.params.write(thetaAt(f), *p.scene);
      FrameImage fi = evaluateFrame(engine, session, uint64_t(burnIn + f), a.seed);
      seconds.push_back(fi.seconds);
      errors[k].push_back(frameError(fi.image, ref1[size_t(f)], ref2[size_t(f)]));
      if (f + 1 == a.frames) lastImage[k] = std::move(fi.image);
    }
    const std::string name = gradientMethodName(methods[k]);
    std::vector<double> rel, rrmse;
    BenchReport::Json perFrame = BenchReport::Json::array();
    for (const FrameError& e : errors[k]) {
      rel.push_back(e.relmse);
      perFrame.push_back(e.relmse);
    }
    const double med = finiteMedian(rel);
    std::vector<double> sq;
    for (const FrameError& e : errors[k]) sq.push_back(e.squared);
    rep.number("spp_" + name, spp[k], "(boundary samples scaled alike)");
    frameTime[k] = finiteMedian(seconds);
    rep.number("seconds_per_frame_" + name, frameTime[k], "s (median)");
    rep.number("relmse_median_" + name, med);
    rep.number("relative_rmse_median_" + name, med > 0 ? std::sqrt(med) : std::numeric_limits<double>::quiet_NaN());
    rep.value("relmse_per_frame_" + name, perFrame, BenchReport::line(perFrame));
    rep.number("squared_error_median_" + name, finiteMedian(sq), "(sum (X - R)^2 / sum R^2)");
  }
  {
    std::vector<double> fl;
    for (const FrameError& e : errors.front()) fl.push_back(e.floor);
    rep.number("reference_floor_median", finiteMedian(fl), "(the reference's own relMSE, subtracted above; keep it well below restir's)");
    rep.number("relmse_epsilon", 0.01, "x the reference's mean squared derivative, per frame");
  }
  // Per-frame ratios against ReSTIR: median, and the largest with its frame.
  auto position = [&](GradientMethod m) { return size_t(std::find(methods.begin(), methods.end(), m) - methods.begin()); };
  if (haveRestir) {
    const size_t r = position(GradientMethod::Restir);
    for (GradientMethod m : {GradientMethod::Ris, GradientMethod::Pt}) {
      const size_t k = position(m);
      if (k == methods.size()) continue;
      std::vector<double> ratio, raw, squared;
      double best = -1;
      int bestFrame = -1;
      for (int f = 0; f < a.frames; ++f) {
        const FrameError& e = errors[k][size_t(f)];
        const FrameError& er = errors[r][size_t(f)];
        const double q = er.relmse > 0 && e.relmse > 0 ? e.relmse / er.relmse : std::numeric_limits<double>::quiet_NaN();
        ratio.push_back(q);
        raw.push_back(e.relmseRaw / er.relmseRaw);
        squared.push_back(er.squared > 0 && e.squared > 0 ? e.squared / er.squared : std::numeric_limits<double>::quiet_NaN());
        if (std::isfinite(q) && q > best) {
          best = q;
          bestFrame = f;
        }
      }
      const std::string key = "ratio_relmse_" + std::string(gradientMethodName(m)) + "_over_restir";
      const size_t unresolved = size_t(std::count_if(ratio.begin(), ratio.end(), [](double q) { return !std::isfinite(q); }));
      rep.number(key + "_median", finiteMedian(ratio),
                 unresolved ? "(" + std::to_string(unresolved) + " frames where restir's error is below the reference's noise left out)" : "");
      rep.number(key + "_max", best > 0 ? best : std::numeric_limits<double>::quiet_NaN(), "(frame " + std::to_string(bestFrame) + ")");
      rep.number(key + "_max_frame", bestFrame);
      rep.number(key + "_raw_median", finiteMedian(raw), "(reference noise not subtracted: a lower bound)");
      rep.number("ratio_squared_error_" + std::string(gradientMethodName(m)) + "_over_restir_median", finiteMedian(squared),
                 "(the image form: the ratio of MSEs)");
      // Frame times match only to within one spp: relMSE x seconds compares work-normalised efficiency.
      rep.number("efficiency_ratio_" + std::string(gradientMethodName(m)) + "_over_restir_median", finiteMedian(ratio) * frameTime[k] / frameTime[r],
                 "(relMSE x seconds per frame)");
    }
  }
  if (!a.out.empty()) {
    std::filesystem::create_directories(a.out);
    std::vector<double> ref(ref1.back().size());
    std::vector<double> mag;
    for (size_t i = 0; i < ref.size(); ++i) {
      ref[i] = 0.5 * (ref1.back()[i] + ref2.back()[i]);
      mag.push_back(std::abs(ref[i]));
    }
    std::sort(mag.begin(), mag.end());
    const double scale = std::max(1e-12, mag[std::min(mag.size() - 1, size_t(0.99 * double(mag.size())))]);
    const std::filesystem::path dir(a.out);
    writeImage(dir / "reference.exr", derivativeGreyImage(ref, W, H));
    writeImage(dir / "reference.png", derivativeFalseColour(ref, W, H, scale));
    for (size_t k = 0; k < methods.size(); ++k) {
      const std::string name = gradientMethodName(methods[k]);
      writeImage(dir / (name + ".exr"), derivativeGreyImage(lastImage[k], W, H));
      writeImage(dir / (name + ".png"), derivativeFalseColour(lastImage[k], W, H, scale));
    }
    rep.text("images", a.out + " (the last frame: reference and each method, .exr values and .png red +, blue -)");
  }
  return rep;
}

}  // namespace

void smoothShadeShapes(v1::JobSpec& job, const std::vector<std::string>& shapes, const std::string& flag) {
  if (shapes.empty()) return;
  // The scene inline, with the shapes' vertex normals (the zoo flat-shades meshes that move).
  v1::Scene scene = jobSceneSpec(job);
  for (const std::string& name : shapes) {
    bool found = false;
    for (auto& sh : *scene.mutable_shapes())
      if (sh.name() == name) {
        sh.set_face_normals(false);
        sh.set_smooth_normals(true);
        found = true;
      }
    if (!found) throw InputError(flag + " " + name + ": no such shape in the scene");
  }
  *job.mutable_scene() = scene;
}

void addBenchDerivativeImagesCommand(CLI::App& bench, int& exitCode) {
  auto a = std::make_shared<DerivativeImagesArgs>();
  auto* c = bench.add_subcommand("derivative-images",
                                 "Per-pixel derivative images of one scalar along an animation at equal frame time: PT, RIS, ReSTIR "
                                 "(reusing across frames) against a high-sample reference (Wang et al. 2023, Fig. 6)");
  c->add_option("--scene", a->scene, "zoo scene (knot, key, oxalis, or any)")->capture_default_str();
  c->add_option("--param", a->param,
                "NAME[i]: the parameter value to differentiate, value i of NAME, or a one-component name such as "
                "shapes/knot/translation/x (default: knot shapes/knot/translation[0], key "
                "groups/key/rotation[1], oxalis lights/spot_left/intensity[0], else the job's first value)");
  c->add_option("--frames", a->frames, "frames of the animation")->check(CLI::Range(1, 100000))->capture_default_str();
  c->add_option("--to", a->to, "the value's last frame (default: the job's truth; when that is its start, 1.5 x the start)");
  c->add_option("--view", a->view, "the scene's view")->capture_default_str();
  c->add_option("--restir-spp", a->restirSpp, "ReSTIR's samples per pixel (its frame time is the budget)")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  c->add_option("--ref-spp", a->refSpp, "samples per pixel of each half of the RIS reference")->check(CLI::Range(1, 4096))->capture_default_str();
  c->add_option("--burn-in", a->burnIn, "ReSTIR's render-only steps before frame 0 (default: the job's)");
  c->add_option("--methods", a->methods, "pt, ris, restir")->delimiter(',')->check(CLI::IsMember({"pt", "ris", "restir"}))->capture_default_str();
  c->add_option("--out", a->out, "write the last frame's derivative images here (reference and each method; .exr and .png)");
  c->add_option("--smooth", a->smooth, "SHAPE: smooth-shade this shape of the scene (vertex normals; repeatable), e.g. --smooth knot");
  c->add_option("--set", a->sets,
                "FIELD.PATH=VALUE: set any field of the scene's job first, e.g. optimization.restir.candidates=16 (repeatable)");
  c->add_flag("--interior-only", a->interiorOnly, "the interior term alone: every boundary term off, in the methods and the reference (Wang et al.'s Fig. 7, b1)");
  c->add_flag("--equal-spp", a->equalSpp, "every method at --restir-spp (equal samples instead of equal frame time)");
  c->add_option("--seed", a->seed, "random seed")->capture_default_str();
  c->add_flag("--json", a->json, "print one JSON object");
  c->callback([a, &exitCode] {
    benchDerivativeImages(*a).print(a->json);
    exitCode = 0;
  });
}

}  // namespace invr::cli
