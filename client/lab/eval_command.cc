// invr-lab eval: the speed-against-accuracy suite. Equal-time reconstructions on zoo scenes (every
// method gets the same wall-clock budget; the image error is measured with the clock stopped),
// then gradient-quality tables at fixed parameters. Writes, under --out:
//   summary.json, summary.md             final errors, seconds, ratios against each baseline
//   <scene>/convergence.csv              every method's (step, seconds, loss, param_error, image_error)
//   <scene>/convergence.png              parameter error against seconds, one line per method
//   <scene>/image_error.png              image error against seconds
//   <scene>/side_by_side.png             renders and parameter textures, initial / truth / each method
//   <scene>/images/*.png                 the grid's tiles
// --quick is the CI smoke run (a few minutes on 2 cores); the full mode is run by hand and its
// results are committed under docs/results/.
#include <sys/utsname.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <thread>

#include "client/lab/bench.h"
#include "client/lab/lab_commands.h"
#include "core/job/zoo_jobs.h"
#include "core/error.h"
#include "core/image/image.h"
#include "core/optim/equal_time.h"
#include "core/stopwatch.h"
#include "client/common/figures.h"

namespace invr::cli {

namespace {

namespace fs = std::filesystem;

struct EvalMethod {
  GradientMethod light;
  const PixelSampler* pixels;
  std::string name() const {
    std::string n = gradientMethodName(light);
    if (pixels->miniBatch()) n += std::string("+") + pixels->name();
    return n;
  }
};

struct EvalScene {
  std::string scene;
  double seconds;  // budget per method
  std::vector<EvalMethod> methods;  // the first is the baseline
};

struct Suite {
  std::vector<EvalScene> scenes;
  int targetSpp;       // targets' samples per pixel
  int imageErrorSpp;   // both renders of the image error
  int imageErrorViews;
  int checkpoints;     // image-error measurements per run
  GradientsArgs gradients;
  OverheadArgs overhead;
  PixelBenchArgs pixelVariance;
  VarianceBenchArgs variance;  // Yan et al. 2024: rings, spot and roulette
  std::vector<double> pixelThetaFractions = {1.0};  // measure the pixel samplers at each of these θ
  bool varianceTables = true;  // the variance-aware tables (rings, spot, roulette: zoo scale only)
};

constexpr GradientMethod kPt = GradientMethod::Pt, kRis = GradientMethod::Ris, kRestir = GradientMethod::Restir;
// Light sampling `light` on every pixel, each as a run of its own.
std::vector<EvalMethod> everyPixel(std::initializer_list<GradientMethod> lights) {
  std::vector<EvalMethod> out;
  for (GradientMethod l : lights) out.push_back({l, &pixelSampler("all")});
  return out;
}
// `light` with every registered mini-batch pixel sampler (and, with `all`, on every pixel too).
std::vector<EvalMethod> everySampler(GradientMethod light, bool all) {
  std::vector<EvalMethod> out;
  for (const PixelSampler* k : pixelSamplers())
    if (k->miniBatch() || all) out.push_back({light, k});
  return out;
}
std::vector<EvalMethod> join(std::vector<EvalMethod> a, const std::vector<EvalMethod>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

// Which comparisons are meaningful where: light sampling matters for direct illumination with
// many lights or hard visibility (cornell, oxalis, ajar, backlit, and the shape jobs tree and
// knot, whose gradients also carry boundary terms); pixel sampling for the
// multi-bounce mirror (path replay, so method pt) and the multi-view backlit. ReSTIR with pixel
// mini-batches is our combination, which neither paper ran.
Suite makePaperSuite(bool quick);

Suite makeSuite(bool quick, bool paper) {
  if (paper) return makePaperSuite(quick);
  Suite s;
  if (quick) {
    s.scenes = {{"cornell", 4, everyPixel({kPt, kRestir})},
                {"ajar", 8, everyPixel({kPt, kRestir})},
                {"mirror", 5, everySampler(kPt, false)}};
    s.targetSpp = 32;
    s.imageErrorSpp = 4;
    s.imageErrorViews = 1;
    s.checkpoints = 3;
    s.gradients.reps = 2;
    s.gradients.burnIn = 4;
    s.gradients.refEvaluations = 4;
    s.gradients.refSpp = 2;
    s.gradients.targetSpp = 32;
    s.overhead.steps = 2;
    s.overhead.targetSpp = 16;
    s.pixelVariance.reps = 16;
    s.pixelVariance.targetSpp = 16;
    s.variance = quickVarianceBenchArgs();
  } else {
    s.scenes = {{"cornell", 20, everyPixel({kPt, kRis, kRestir})},
                {"oxalis", 60, join(everyPixel({kPt, kRis, kRestir}), everySampler(kRestir, false))},
                {"ajar", 60, everyPixel({kPt, kRis, kRestir})},
                {"mirror", 40, everySampler(kPt, true)},
                {"backlit", 90, join(everyPixel({kPt, kRis, kRestir}), everySampler(kRestir, false))},
                // Shape parameters (Wang et al. 2023, §5-7): the tree's rotation from its shadow
                // under area lights, the knot's translation under spot and point lights.
                {"tree", 60, everyPixel({kPt, kRis, kRestir})},
                {"knot", 30, everyPixel({kPt, kRis, kRestir})}};
    s.targetSpp = 256;
    s.imageErrorSpp = 32;
    s.imageErrorViews = 2;
    s.checkpoints = 8;
    s.pixelVariance.reps = 512;
    s.pixelVariance.referenceSamples = 32;
    s.pixelThetaFractions = {1.0, 0.1};  // the job's start, and near convergence
  }
  s.gradients.scene = "ajar";
  s.overhead.scene = "oxalis";
  s.pixelVariance.scene = "mirror";
  return s;
}

// The papers' scale (issue 42): oxalis-hd (ReSTIR against PT and RIS on a 68K-triangle shadow,
// 196K texels), kitty (32 views, 16 a step) and gallery (16 views at 512 x 512, 2.4 % of the
// pixels a step), the last two with each mini-batch pixel sampler under PT and under ReSTIR (Yan
// et al. 2025's comparison). Long: about an hour on 2 cores at --budget-scale 1 (40 minutes at
// 0.6); --quick is a check that it runs.
Suite makePaperSuite(bool quick) {
  Suite s;
  const double t = quick ? 6 : 150;
  s.scenes = {{"oxalis-hd", t, everyPixel({kPt, kRis, kRestir})},
              {"kitty", t, join(everySampler(kPt, false), everySampler(kRestir, false))},
              {"gallery", t, join(everySampler(kPt, false), everySampler(kRestir, false))}};
  s.targetSpp = quick ? 4 : 64;
  s.imageErrorSpp = quick ? 1 : 8;
  s.imageErrorViews = 1;
  s.checkpoints = quick ? 2 : 6;
  s.gradients.scene = "oxalis-hd";
  s.gradients.reps = quick ? 2 : 8;
  s.gradients.burnIn = quick ? 2 : 8;
  s.gradients.refEvaluations = quick ? 2 : 8;
  s.gradients.refSpp = quick ? 1 : 4;
  s.gradients.targetSpp = s.targetSpp;
  s.overhead.scene = "oxalis-hd";
  s.overhead.steps = quick ? 2 : 10;
  s.overhead.targetSpp = s.targetSpp;
  s.pixelVariance.scene = "gallery";
  s.pixelVariance.reps = quick ? 4 : 64;
  s.pixelVariance.samples = 6400;  // the job's share of the pixels
  s.pixelVariance.targetSpp = quick ? 4 : 16;
  s.varianceTables = false;
  return s;
}

using Json = BenchReport::Json;

std::string fmt(double v) { return BenchReport::fmt(v); }

std::string firstLineOf(const std::string& file, const std::string& prefix) {
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(prefix, 0) == 0) return line.substr(prefix.size());
  return "";
}

struct Machine {
  std::string cpu, os, kernel;
  unsigned cores = 0;
  double memoryGiB = 0;
};

Machine describeMachine() {
  Machine m;
  m.cpu = firstLineOf("/proc/cpuinfo", "model name\t: ");
  m.os = firstLineOf("/etc/os-release", "PRETTY_NAME=");
  if (m.os.size() >= 2 && m.os.front() == '"') m.os = m.os.substr(1, m.os.size() - 2);
  utsname u{};
  if (uname(&u) == 0) m.kernel = std::string(u.sysname) + " " + u.release + " " + u.machine;
  m.cores = std::thread::hardware_concurrency();
  std::istringstream mem(firstLineOf("/proc/meminfo", "MemTotal:"));
  double kb = 0;
  mem >> kb;
  m.memoryGiB = kb / (1024.0 * 1024.0);
  return m;
}

std::string utcNow() {
  std::time_t t = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return buf;
}

// |a - b| scaled so that white is a difference of twice the reference's mean.
Image differenceImage(const Image& a, const Image& ref) {
  double mean = 0;
  for (float v : ref.data()) mean += v;
  mean = std::max(1e-6, mean / double(std::max<size_t>(1, ref.data().size())));
  Image d(ref.width(), ref.height(), ref.channels());
  for (size_t k = 0; k < d.data().size(); ++k) d.data()[k] = float(std::abs(double(a.data()[k]) - ref.data()[k]) / (2 * mean));
  return d;
}

Image textureImage(const ParameterSlot& s, const std::vector<float>& theta, float scale = 1.f, const std::vector<float>* minus = nullptr) {
  Image im(s.width, s.height, 3);
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x)
      for (int c = 0; c < 3; ++c) {
        size_t k = s.offset + size_t((y * s.width + x) * s.channels + std::min(c, s.channels - 1));
        float v = theta[k] - (minus ? (*minus)[k] : 0.f);
        im.at(x, y, c) = std::abs(v) * scale;
      }
  return im;
}

double slotRmse(const ParameterSlot& s, const std::vector<float>& a, const std::vector<float>& b) {
  double sum = 0;
  for (uint32_t k = 0; k < s.size; ++k) sum += double(a[s.offset + k] - b[s.offset + k]) * (a[s.offset + k] - b[s.offset + k]);
  return std::sqrt(sum / std::max<uint32_t>(1, s.size));
}

std::string shortName(const std::string& slot) {  // materials/mirror/roughness -> mirror/roughness
  size_t p = slot.find('/');
  return p == std::string::npos ? slot : slot.substr(p + 1);
}

std::string scalarValues(const ParameterSlot& s, const std::vector<float>& theta) {
  std::string o;
  for (uint32_t k = 0; k < s.size; ++k) o += (k ? " " : "") + fmt(double(theta[s.offset + k]));
  return o;
}

Json scalarValuesJson(const ParameterSlot& s, const std::vector<float>& theta) {
  Json o = Json::array();
  for (uint32_t k = 0; k < s.size; ++k) o.push_back(double(theta[s.offset + k]));
  return o;
}

struct MethodResult {
  std::string name;
  EvalMethod method;
  EqualTimeRun run;
  std::vector<Image> renders;
};

struct SceneResult {
  std::string scene;
  double seconds = 0;
  size_t parameters = 0;
  double initialParamError = 0, initialImageError = 0;
  std::vector<MethodResult> methods;
  Json truthScalars = Json::object();  // slot: values
  std::vector<Json> methodScalars;
  std::string setting;  // the job's settings that shape the figures (loss, learning-rate schedule, scene notes)
};

// What a reader needs next to a scene's figures: the job's loss and learning-rate schedule as
// implemented, and the scene choices that shape the comparison.
std::string sceneSetting(const std::string& scene, const Problem& p) {
  std::string s = "Loss " + std::string(lossName(p.gradient.loss)) + "; learning rates ";
  if (p.schedule.halfLifeSteps > 0)
    s += "decay as learning_rate * h / (h + t) at update t, h = " + fmt(p.schedule.halfLifeSteps) + " (half the rate after h steps)";
  else
    s += "constant";
  s += ".";
  if (scene == "oxalis")
    s += " The two spotlights are about 30x brighter than the fill light, so selection by power gives the fill 2 % of the "
         "light samples: the texels lit only by the fill light are where one light sample per pixel fails.";
  if (scene == "ajar")
    s += " The rate is kept constant on purpose: a decaying rate would mostly hide how far PT's gradients walk the texture "
         "away from the truth, the failure this scene is there to show.";
  return s;
}

double finalParamError(const MethodResult& m) { return m.run.history.back().parameterError; }
// RMS of the parameter error over the last quarter of the budget: a run that oscillates around
// the optimum (Adam on a noisy scalar) is judged by its noise level, not by where its last step
// happened to land.
double tailParamError(const MethodResult& m, double budget) { return tailParameterError(m.run.history, budget); }
double finalImageError(const MethodResult& m) { return m.run.history.back().imageError; }

// The grid: initial | truth | each method; rows: view-0 render, its difference from the truth,
// and per texture parameter the texture and its difference from the truth.
void drawSideBySide(const fs::path& dir, const SceneResult& r, Problem& p, ImageErrorMeter& meter) {
  fs::path tiles = dir / "images";
  fs::create_directories(tiles);
  std::vector<Image> initialRenders;
  meter.measure(p.initial, &initialRenders);
  const Image& truth = meter.reference().at(0);
  // One exposure for the whole row, from the truth's mean: dark scenes (ajar) stay readable.
  double mean = 0;
  for (float v : truth.data()) mean += v;
  mean /= double(std::max<size_t>(1, truth.data().size()));
  const float exposure = float(std::clamp(mean > 0 ? 0.18 / mean : 1.0, 1.0 / 16, 64.0));
  auto exposed = [&](Image im) {
    for (float& v : im.data()) v *= exposure;
    return im;
  };
  std::vector<std::string> columns = {"initial", "truth"};
  for (const auto& m : r.methods) columns.push_back(m.name);
  auto tile = [&](const std::string& name, const Image& im) {
    fs::path f = tiles / (name + ".png");
    writeImage(f, im);
    return f;
  };
  auto fileSafe = [](std::string s) {
    for (char& c : s)
      if (c == '/' || c == '+') c = '_';
    return s;
  };
  GridRow render{"render, view 0 (x" + fmt(double(exposure)) + ")", {}}, diff{"|render - truth|", {}};
  render.cells.push_back({tile("render_initial", exposed(initialRenders.at(0))), "image err " + fmt(r.initialImageError)});
  render.cells.push_back({tile("render_truth", exposed(truth)), "ground truth"});
  diff.cells.push_back({tile("diff_initial", differenceImage(initialRenders.at(0), truth)), "white = 2x mean"});
  diff.cells.push_back({{}, ""});
  for (const auto& m : r.methods) {
    render.cells.push_back({tile("render_" + fileSafe(m.name), exposed(m.renders.at(0))), "image err " + fmt(finalImageError(m))});
    diff.cells.push_back({tile("diff_" + fileSafe(m.name), differenceImage(m.renders.at(0), truth)), ""});
  }
  std::vector<GridRow> rows = {render, diff};
  for (const auto& s : p.params.slots()) {
    if (s.width <= 0) continue;
    std::string base = fileSafe(shortName(s.name));
    GridRow tex{shortName(s.name), {}}, texDiff{"|texture - truth| x4", {}};
    tex.cells.push_back({tile(base + "_initial", textureImage(s, p.initial)), "RMSE " + fmt(slotRmse(s, p.initial, p.truth))});
    tex.cells.push_back({tile(base + "_truth", textureImage(s, p.truth)), ""});
    texDiff.cells.push_back({tile(base + "_diff_initial", textureImage(s, p.initial, 4.f, &p.truth)), ""});
    texDiff.cells.push_back({{}, ""});
    for (const auto& m : r.methods) {
      tex.cells.push_back({tile(base + "_" + fileSafe(m.name), textureImage(s, m.run.theta)), "RMSE " + fmt(slotRmse(s, m.run.theta, p.truth))});
      texDiff.cells.push_back({tile(base + "_diff_" + fileSafe(m.name), textureImage(s, m.run.theta, 4.f, &p.truth)), ""});
    }
    rows.push_back(tex);
    rows.push_back(texDiff);
  }
  // Scalar parameters are shown as numbers under the renders.
  for (const auto& s : p.params.slots()) {
    if (s.width > 0) continue;
    std::string label = shortName(s.name) + " ";
    rows[0].cells[0].caption += "\n" + label + scalarValues(s, p.initial);
    rows[0].cells[1].caption += "\n" + label + scalarValues(s, p.truth);
    for (size_t i = 0; i < r.methods.size(); ++i) rows[0].cells[2 + i].caption += "\n" + label + scalarValues(s, r.methods[i].run.theta);
  }
  drawImageGrid(r.scene + ": equal time, " + fmt(r.seconds) + " s per method", columns, rows, dir / "side_by_side.png");
}

SceneResult runScene(const EvalScene& es, const Suite& suite, double budgetScale, const fs::path& out) {
  SceneResult r;
  r.scene = es.scene;
  r.seconds = es.seconds * budgetScale;
  auto job = zooJob(es.scene);
  job.mutable_optimization()->set_target_spp(suite.targetSpp);
  Problem p = buildProblem(job);
  r.parameters = p.params.size();
  r.setting = sceneSetting(es.scene, p);
  std::cerr << "[" << es.scene << "] rendering targets (" << suite.targetSpp << " spp, " << p.scene->cameras.size() << " views)...\n";
  std::vector<Image> targets = renderTargets(p);
  ImageErrorMeter meter(p, suite.imageErrorViews, suite.imageErrorSpp);
  fs::path dir = out / es.scene;
  fs::create_directories(dir);
  ConvergenceCsv csv(dir / "convergence.csv");
  try {
    csv.write();
  } catch (const InputError&) {
    throw InputError("--out: cannot write '" + (dir / "convergence.csv").string() + "'");
  }
  EqualTimeOptions budget;
  budget.seconds = r.seconds;
  budget.imageErrorCheckpoints = suite.checkpoints;
  for (const EvalMethod& m : es.methods) {
    GradientOptions o = p.gradient;
    o.method = m.light;
    o.pixels.sampler = m.pixels;
    MethodResult mr;
    mr.name = m.name();
    mr.method = m;
    mr.run = runEqualTime(p, targets, o, budget, &meter, [&](const EqualTimePoint& pt) { csv.add(convergenceRow(mr.name, pt)); });
    csv.write();
    meter.measure(mr.run.theta, &mr.renders);
    const EqualTimePoint& last = mr.run.history.back();
    std::cerr << "[" << es.scene << "] " << mr.name << ": " << last.step << " steps in " << fmt(last.seconds) << " s, parameter error "
              << fmt(mr.run.history.front().parameterError) << " -> " << fmt(last.parameterError) << ", image error "
              << fmt(mr.run.history.front().imageError) << " -> " << fmt(last.imageError)
              << (mr.run.failure.empty() ? "" : "; stopped: " + mr.run.failure) << "\n";
    r.methods.push_back(std::move(mr));
  }
  r.initialParamError = r.methods.front().run.history.front().parameterError;
  r.initialImageError = r.methods.front().run.history.front().imageError;
  std::string title = es.scene + " (" + fmt(r.seconds) + " s per method)";
  drawConvergenceChart({dir / "convergence.csv"}, dir / "convergence.png", "seconds", "param_error", title);
  drawConvergenceChart({dir / "convergence.csv"}, dir / "image_error.png", "seconds", "image_error", title);
  drawSideBySide(dir, r, p, meter);
  for (const auto& s : p.params.slots())
    if (s.width <= 0) r.truthScalars[s.name] = scalarValuesJson(s, p.truth);
  for (const auto& m : r.methods) {
    Json v = Json::object();
    for (const auto& s : p.params.slots())
      if (s.width <= 0) v[s.name] = scalarValuesJson(s, m.run.theta);
    r.methodScalars.push_back(std::move(v));
  }
  return r;
}

// The baseline a method is compared with: the scene's first method, and for a pixel sampler
// also the uniform sampler with the same light sampling.
const MethodResult* uniformPeer(const SceneResult& r, const MethodResult& m) {
  const PixelSampler* uniform = &pixelSampler("uniform");
  if (!m.method.pixels->miniBatch() || m.method.pixels == uniform) return nullptr;
  for (const auto& o : r.methods)
    if (o.method.light == m.method.light && o.method.pixels == uniform) return &o;
  return nullptr;
}

Json sceneJson(const SceneResult& r) {
  const MethodResult& base = r.methods.front();
  Json o = {{"budget_seconds_per_method", r.seconds}, {"setting", r.setting},
            {"parameters", r.parameters},
            {"baseline", base.name},
            {"initial_param_error", r.initialParamError},
            {"initial_image_error", r.initialImageError},
            {"csv", r.scene + "/convergence.csv"},
            {"chart", r.scene + "/convergence.png"},
            {"image_error_chart", r.scene + "/image_error.png"},
            {"side_by_side", r.scene + "/side_by_side.png"}};
  if (!r.truthScalars.empty()) o["truth"] = r.truthScalars;
  Json methods = Json::object();
  for (size_t i = 0; i < r.methods.size(); ++i) {
    const MethodResult& m = r.methods[i];
    const EqualTimePoint& last = m.run.history.back();
    Json j = {{"light_sampling", gradientMethodName(m.method.light)},
              {"pixel_sampling", m.method.pixels->name()},
              {"steps", last.step},
              {"seconds", last.seconds},
              {"param_error", last.parameterError},
              {"image_error", last.imageError},
              {"non_finite_samples", m.run.nonFiniteSamples},
              {"stage1_seconds", m.run.secondsStage1}};
    if (!m.run.failure.empty()) j["failure"] = m.run.failure;
    j["param_error_tail"] = tailParamError(m, r.seconds);
    j["param_error_ratio_vs_baseline"] = finalParamError(base) / finalParamError(m);
    j["param_error_tail_ratio_vs_baseline"] = tailParamError(base, r.seconds) / tailParamError(m, r.seconds);
    j["image_error_ratio_vs_baseline"] = finalImageError(base) / finalImageError(m);
    if (const MethodResult* u = uniformPeer(r, m))
      j["param_error_tail_ratio_vs_uniform"] = tailParamError(*u, r.seconds) / tailParamError(m, r.seconds);
    if (!r.methodScalars[i].empty()) j["values"] = r.methodScalars[i];
    methods[m.name] = std::move(j);
  }
  o["methods"] = std::move(methods);
  return o;
}

// summary.json's layout: the top level's figures on the first line; then each of its objects
// and arrays on a line of its own, or, when their members are objects or arrays themselves, one
// line per member.
std::string summaryText(const Json& summary) {
  auto isContainer = [](const Json& j) { return j.is_object() || j.is_array(); };
  std::string o = "{";
  bool first = true;
  for (const auto& [key, value] : summary.items()) {
    o += first ? "" : (isContainer(value) ? ",\n " : ", ");
    first = false;
    o += BenchReport::line(Json(key)) + ": ";
    bool nested = !value.empty() && std::all_of(value.begin(), value.end(), isContainer);
    if (!isContainer(value) || !nested) {
      o += BenchReport::line(value);
      continue;
    }
    bool object = value.is_object();
    o += object ? "{" : "[";
    bool firstMember = true;
    for (const auto& [k, v] : value.items()) {
      o += firstMember ? "\n  " : ",\n  ";
      firstMember = false;
      o += (object ? BenchReport::line(Json(k)) + ": " : "") + BenchReport::line(v);
    }
    o += object ? "}" : "]";
  }
  return o + "}\n";
}

std::string sceneMarkdown(const SceneResult& r) {
  const MethodResult& base = r.methods.front();
  std::ostringstream md;
  md << "### " << r.scene << "\n\n"
     << r.parameters << " parameter values; " << fmt(r.seconds) << " s per method; initial parameter error "
     << fmt(r.initialParamError) << ", image error " << fmt(r.initialImageError) << ". " << r.setting << "\n\n"
     << "| method | steps | parameter error (final) | parameter error (last 25 %) | image error | " << base.name
     << " / method (param, last 25 %) | " << base.name << " / method (image) |\n|---|---:|---:|---:|---:|---:|---:|\n";
  for (const auto& m : r.methods) {
    const EqualTimePoint& last = m.run.history.back();
    md << "| " << m.name << (m.run.failure.empty() ? "" : " (diverged)") << " | " << last.step << " | " << fmt(last.parameterError) << " | "
       << fmt(tailParamError(m, r.seconds)) << " | " << fmt(last.imageError) << " | "
       << fmt(tailParamError(base, r.seconds) / tailParamError(m, r.seconds)) << " | "
       << fmt(finalImageError(base) / finalImageError(m)) << " |\n";
  }
  md << "\n![" << r.scene << " convergence](" << r.scene << "/convergence.png) ![" << r.scene << " image error](" << r.scene
     << "/image_error.png)\n\n![" << r.scene << " side by side](" << r.scene << "/side_by_side.png)\n\n";
  return md.str();
}

struct EvalArgs {
  bool quick = false;
  std::string scale = "zoo";
  std::string out;
  std::vector<std::string> scenes;
  double budgetScale = 1;
  bool noTables = false;
};

void runEval(const EvalArgs& a) {
  if (!(a.budgetScale > 0)) throw InputError("--budget-scale: must be positive");
  const bool paper = a.scale == "paper";
  Suite suite = makeSuite(a.quick, paper);
  if (!a.scenes.empty()) {
    std::vector<EvalScene> picked;
    for (const auto& name : a.scenes) {
      bool found = false;
      for (const auto& s : suite.scenes)
        if (s.scene == name) picked.push_back(s), found = true;
      if (!found) {
        std::string known;
        for (const auto& s : suite.scenes) known += (known.empty() ? "" : ", ") + s.scene;
        throw InputError("--scenes: '" + name + "' is not in the " + (a.quick ? "quick " : "full ") + (paper ? "paper-scale " : "") + "suite (" + known + ")");
      }
    }
    suite.scenes = picked;
  }
  fs::path out(a.out);
  fs::create_directories(out);
  if (!fs::is_directory(out)) throw InputError("--out: '" + a.out + "' is not a folder");
  Stopwatch clock;
  double budget = 0;
  size_t runs = 0;
  for (const auto& s : suite.scenes) budget += s.seconds * a.budgetScale * double(s.methods.size()), runs += s.methods.size();
  std::cerr << "invr-lab eval (" << (a.quick ? "quick" : "full") << (paper ? ", paper scale" : "") << "): " << suite.scenes.size() << " scenes, " << runs
            << " equal-time runs, " << fmt(budget) << " s of optimisation budget"
            << (a.noTables ? "" : ", then the gradient-quality tables") << "\n";
  std::vector<SceneResult> results;
  for (const auto& s : suite.scenes) results.push_back(runScene(s, suite, a.budgetScale, out));
  std::vector<BenchReport> tables;
  if (!a.noTables) {
    std::cerr << "[tables] equal-time gradient error on " << suite.gradients.scene << "...\n";
    tables.push_back(benchGradients(suite.gradients));
    std::cerr << "[tables] ReSTIR overhead on " << suite.overhead.scene << "...\n";
    tables.push_back(benchOverhead(suite.overhead));
    for (double f : suite.pixelThetaFractions) {
      std::cerr << "[tables] pixel-sampler variance on " << suite.pixelVariance.scene << " (" << suite.pixelVariance.reps
                << " reps, theta fraction " << f << ")...\n";
      PixelBenchArgs pa = suite.pixelVariance;
      pa.thetaFraction = f;
      tables.push_back(benchPixelVariance(pa));
    }
    if (suite.varianceTables) {
      std::cerr << "[tables] variance-aware rendering on rings, spot and roulette...\n";
      for (BenchReport& r : benchVariance(suite.variance)) tables.push_back(std::move(r));
    }
  }
  double total = clock.seconds();
  Machine m = describeMachine();
  std::string date = utcNow();
  // summary.json
  std::ofstream js(out / "summary.json");
  if (!js) throw InputError("--out: cannot write '" + (out / "summary.json").string() + "'");
  Json summary = {{"mode", a.quick ? "quick" : "full"},
                  {"scale", a.scale},
                  {"date", date},
                  {"budget_scale", a.budgetScale},
                  {"total_seconds", total},
                  {"machine", {{"cpu", m.cpu}, {"cores", m.cores}, {"memory_gib", m.memoryGiB}, {"os", m.os}, {"kernel", m.kernel}}}};
  Json scenes = Json::object();
  for (const auto& r : results) scenes[r.scene] = sceneJson(r);
  summary["scenes"] = std::move(scenes);
  Json quality = Json::array();
  for (const auto& t : tables) quality.push_back(t.toJson());
  summary["gradient_quality"] = std::move(quality);
  js << summaryText(summary);
  js.close();
  // summary.md: the same, for people (README links the committed full run's).
  std::ofstream md(out / "summary.md");
  md << "# invr evaluation (" << (a.quick ? "quick" : "full") << (paper ? ", paper scale" : "") << ")\n\n"
     << "Generated by `invr-lab eval" << (a.quick ? " --quick" : "") << (paper ? " --scale paper" : "")
     << (a.budgetScale != 1 ? " --budget-scale " + fmt(a.budgetScale) : std::string()) << " --out DIR` on " << date << " in " << fmt(total) << " s.\n"
     << "Machine: " << m.cpu << ", " << m.cores << " cores, " << fmt(m.memoryGiB) << " GiB, " << m.os << " (" << m.kernel << ").\n\n"
     << "Every method gets the same wall-clock budget per scene (ReSTIR's burn-in included). Parameter error is the RMSE of "
        "the parameters against the truth, at the end and as the RMS over the last quarter of the budget (the fair figure "
        "for runs that oscillate around the optimum); image error is the per-pixel relative RMSE, sqrt(mean (I - I*)^2 / (I*^2 + 0.01)), "
        "of renders at the recovered parameters against renders of the truth with the same random numbers (" +
            std::to_string(suite.imageErrorSpp) + " spp, first " + std::to_string(suite.imageErrorViews) +
            " view(s)), measured with the clock stopped; its floor is the noise that common random numbers do not cancel. Ratios above 1 mean the "
        "method beats the scene's baseline (its first method). One run per method: on a shared 2-core machine, treat "
        "ratios within about 1.2 of each other as ties.\n\n## Equal-time reconstructions\n\n";
  for (const auto& r : results) md << sceneMarkdown(r);
  if (!tables.empty()) {
    md << "## Gradient quality at fixed parameters\n\n";
    for (const auto& t : tables) {
      md << "### " << t.title() << "\n\n| figure | value |\n|---|---|\n";
      for (const auto& [k, v] : t.rows()) md << "| " << k << " | " << v << " |\n";
      md << "\n";
    }
  }
  md.close();
  std::cout << "wrote " << fs::absolute(out).string() << "/summary.json and summary.md (" << fmt(total) << " s)\n";
}

}  // namespace

void addEvalCommand(CLI::App& app, int& exitCode) {
  auto a = std::make_shared<EvalArgs>();
  auto* c = app.add_subcommand("eval", "Speed-against-accuracy suite: equal-time reconstructions on zoo scenes, charts, side-by-side "
                                       "images, gradient-quality tables; writes DIR/summary.json");
  c->add_option("-o,--out", a->out, "output folder")->required();
  c->add_flag("--quick", a->quick, "the smoke-run suite (a few minutes on 2 cores)");
  c->add_option("--scale", a->scale,
                "zoo: the zoo's small problems (default); paper: oxalis-hd, kitty and gallery at the papers' scale (about an hour "
                "on 2 cores; not in CI)")
      ->check(CLI::IsMember({"zoo", "paper"}))
      ->capture_default_str();
  c->add_option("--scenes", a->scenes, "only these scenes of the suite")->delimiter(',');
  c->add_option("--budget-scale", a->budgetScale, "multiply every time budget (e.g. 0.5 on a fast machine)")->capture_default_str();
  c->add_flag("--no-tables", a->noTables, "skip the gradient-quality tables");
  c->callback([a, &exitCode] {
    runEval(*a);
    exitCode = 0;
  });
}

}  // namespace invr::cli
