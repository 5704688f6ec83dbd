// invr-lab bench scale: how a gradient step's time and a worker's memory grow with film pixels,
// parameters, triangles and views (issue 42), for PT, RIS and ReSTIR. Every point is one job (a
// reduced oxalis-hd, with one size changed) run in a child process of its own, so that its peak
// resident memory is its own; each series gets its fitted growth exponent (the slope of log time
// or log memory against log size).
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include "client/common/process.h"
#include "client/common/bench_report.h"
#include "client/lab/lab_commands.h"
#include "client/lab/step_engine.h"
#include "core/error.h"
#include "core/job/problem.h"
#include "core/job/zoo_jobs.h"
#include "core/scene/zoo.h"
#include "core/stopwatch.h"

namespace invr::cli {

namespace {

namespace fs = std::filesystem;
using Json = BenchReport::Json;

// The base point: oxalis-hd (a plant's shadow on a textured painting, spot, spot and fill lights)
// at 128 x 128, a 64 x 64 texture, a plant of 12 leaves at 24 segments (13,500 triangles), one view.
constexpr int kBaseFilm = 128, kBaseTexture = 64, kBaseLeaves = 12, kBaseLeafSegments = 24;

struct Series {
  const char* name;
  const char* what;         // what the value sets
  std::vector<int> values;  // the points
  std::vector<int> quick;   // --quick's points
};

const std::vector<Series>& allSeries() {
  static const std::vector<Series> s = {
      {"pixels", "film width = height", {64, 128, 256, 512}, {32, 64}},
      {"parameters", "texture width = height (3 values a texel)", {32, 64, 128, 256, 512}, {16, 32}},
      // 12 leaves at 3, 24, 64 and 200 segments a leaflet: 900, 13,500, 95,000 and 943,000 triangles.
      {"triangles", "the plant's leaf_segments (12 leaves)", {3, 24, 64, 200}, {3, 12}},
      {"views", "views (all in every step)", {1, 2, 4, 8, 16}, {1, 2}},
  };
  return s;
}

const Series& seriesNamed(const std::string& name) {
  for (const Series& s : allSeries())
    if (name == s.name) return s;
  throw InputError("bench scale: unknown series '" + name + "' (pixels, parameters, triangles, views)");
}

v1::JobSpec scaleJob(const std::string& series, int value, const std::string& method) {
  v1::Scene s = zooScene("oxalis-hd");
  int film = kBaseFilm, texture = kBaseTexture, segments = kBaseLeafSegments, views = 1;
  if (series == "pixels") film = value;
  else if (series == "parameters") texture = value;
  else if (series == "triangles") segments = value;
  else if (series == "views") views = value;
  else seriesNamed(series);  // throws
  s.mutable_film()->set_width(film);
  s.mutable_film()->set_height(film);
  for (auto& m : *s.mutable_materials())
    if (m.name() == "painting") m.mutable_diffuse()->mutable_albedo()->mutable_procedural()->set_width(texture);
  for (auto& sh : *s.mutable_shapes())
    if (sh.has_plant()) {
      sh.mutable_plant()->set_leaves(kBaseLeaves);
      sh.mutable_plant()->set_leaf_segments(segments);
    }
  // More views: the first one's eye moved sideways and up a little each time, all on the painting.
  const v1::Camera first = s.views(0);
  for (int v = 1; v < views; ++v) {
    v1::Camera* c = s.add_views();
    *c = first;
    c->set_name("front_" + std::to_string(v));
    c->mutable_eye()->set_x(first.eye().x() + 0.04 * double(v % 4) - 0.06);
    c->mutable_eye()->set_y(first.eye().y() + 0.03 * double(v / 4));
  }
  v1::JobSpec job = zooJob("oxalis-hd");
  *job.mutable_scene() = s;
  auto* o = job.mutable_optimization();
  o->set_target_spp(4);  // the targets' content does not change the step's work
  o->set_views_per_step(0);
  const GradientMethod m = gradientMethodFromName(method);
  o->set_method(m == GradientMethod::Pt ? v1::METHOD_PT : m == GradientMethod::Ris ? v1::METHOD_RIS : v1::METHOD_RESTIR);
  return job;
}

// kB figures of /proc/self/status (VmRSS: now, VmHWM: the peak).
double statusBytes(const std::string& key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(key + ":", 0) == 0) return 1024.0 * std::stod(line.substr(key.size() + 1));
  return 0;
}

// The child: one point, printed as one JSON line.
void measurePoint(const std::string& series, int value, const std::string& method, int warmup, int repeats) {
  const double baseline = statusBytes("VmRSS");
  Problem p = buildProblem(scaleJob(series, value, method));
  const std::vector<Image> targets = renderTargets(p);
  p.params.write(p.initial, *p.scene);
  StepEngine engine(p, targets);
  const uint64_t first = measuredCounter(p, warmup);
  for (uint64_t k = 0; k < first; ++k) engine.evaluate(k);
  double fastest = 1e30;
  for (int i = 0; i < repeats; ++i) {
    Stopwatch clock;
    engine.evaluate(first + uint64_t(i));
    fastest = std::min(fastest, clock.seconds());
  }
  size_t triangles = 0;
  for (const TriangleMesh& m : p.scene->meshes) triangles += m.triangleCount();
  const size_t views = p.scene->cameras.size(), pixels = size_t(p.scene->width) * size_t(p.scene->height);
  const double sizeOf = series == "pixels" ? double(pixels) : series == "parameters" ? double(p.truth.size())
                        : series == "triangles"                 ? double(triangles)
                                                                : double(views);
  Json j = {{"x", sizeOf},
            {"pixels", pixels},
            {"parameters", p.truth.size()},
            {"triangles", triangles},
            {"views", views},
            {"step_seconds", fastest},
            {"peak_rss_bytes", statusBytes("VmHWM")},
            {"baseline_rss_bytes", baseline}};
  std::printf("%s\n", BenchReport::line(j).c_str());
}

// Least-squares slope of log y against log x.
double growthExponent(const std::vector<double>& x, const std::vector<double>& y) {
  double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    if (!(x[i] > 0 && y[i] > 0)) continue;
    const double lx = std::log(x[i]), ly = std::log(y[i]);
    n += 1;
    sx += lx;
    sy += ly;
    sxx += lx * lx;
    sxy += lx * ly;
  }
  const double d = n * sxx - sx * sx;
  return n >= 2 && d > 0 ? (n * sxy - sx * sy) / d : std::nan("");
}

// Memory has a fixed part (the scene's other shapes, thread arenas) that hides growth in a log-log
// slope at small sizes: fit y = a + b x^k instead (k on a grid of 0.01 in [0.05, 2.5]; for each k
// a and b by unconstrained least squares, the k whose a or b comes out negative skipped) and return
// the k of the smallest error; NaN (null in JSON) for fewer than three points or no admissible k.
double offsetGrowthExponent(const std::vector<double>& x, const std::vector<double>& y) {
  if (x.size() < 3) return std::nan("");  // three unknowns: any k fits two points
  double bestK = std::nan(""), bestErr = 1e300;
  const double scale = *std::max_element(x.begin(), x.end());
  for (int step = 5; step <= 250; ++step) {
    const double k = 0.01 * double(step);
    double n = 0, su = 0, sy = 0, suu = 0, suy = 0;
    for (size_t i = 0; i < x.size(); ++i) {
      const double u = std::pow(x[i] / scale, k);
      n += 1, su += u, sy += y[i], suu += u * u, suy += u * y[i];
    }
    const double d = n * suu - su * su;
    if (!(d > 0)) continue;
    const double b = (n * suy - su * sy) / d, a = (sy - b * su) / n;
    if (b < 0 || a < 0) continue;
    double err = 0;
    for (size_t i = 0; i < x.size(); ++i) err += std::pow(y[i] - a - b * std::pow(x[i] / scale, k), 2);
    if (err < bestErr) bestErr = err, bestK = k;
  }
  return bestK;
}

struct ScaleArgs {
  std::vector<std::string> series = {"pixels", "parameters", "triangles", "views"};
  std::vector<std::string> methods = {"pt", "ris", "restir"};
  int warmup = 1, repeats = 3;
  bool quick = false, json = false;
  std::string point;  // a child: "SERIES=VALUE"
  std::string method = "restir";
};

Json runChild(const ScaleArgs& a, const std::string& series, int value, const std::string& method) {
  std::string name = (fs::temp_directory_path() / "invr_bench_scale_XXXXXX").string();
  const int fd = ::mkstemp(name.data());
  if (fd < 0) throw std::runtime_error("bench scale: cannot create a temporary file in " + fs::temp_directory_path().string());
  ::close(fd);
  const fs::path out = name;
  const pid_t pid = spawnProcess({fs::read_symlink("/proc/self/exe").string(), "bench", "scale", "--point", series + "=" + std::to_string(value),
                                  "--method", method, "--warmup", std::to_string(a.warmup), "--repeats", std::to_string(a.repeats)},
                                 out, out);
  const int code = waitProcess(pid);
  std::ifstream in(out);
  std::stringstream text;
  text << in.rdbuf();
  fs::remove(out);
  if (code != 0) throw std::runtime_error("bench scale: the point " + series + "=" + std::to_string(value) + " (" + method + ") failed: " + text.str());
  std::string last, line;
  while (std::getline(text, line))
    if (!line.empty() && line[0] == '{') last = line;
  const Json point = Json::parse(last, nullptr, false);
  if (point.is_discarded() || !point.contains("step_seconds"))
    throw std::runtime_error("bench scale: the point " + series + "=" + std::to_string(value) + " (" + method + ") printed no figures: " + text.str());
  return point;
}

void runBenchScale(const ScaleArgs& a) {
  if (a.warmup < 0 || a.repeats <= 0) throw InputError("bench scale: --warmup must be >= 0 and --repeats positive");
  for (const std::string& m : a.methods) gradientMethodFromName(m);  // throws for unknown names
  if (!a.point.empty()) {
    const size_t eq = a.point.find('=');
    if (eq == std::string::npos) throw InputError("bench scale: --point must be SERIES=VALUE");
    int value = 0;
    try {
      value = std::stoi(a.point.substr(eq + 1));
    } catch (const std::exception&) {
    }
    if (value <= 0) throw InputError("bench scale: --point's value must be positive");
    measurePoint(a.point.substr(0, eq), value, a.method, a.warmup, a.repeats);
    return;
  }
  BenchReport rep("scale");
  rep.text("base", "oxalis-hd at 128x128, 64x64 texture, plant of 12 leaves at 24 segments, one view; one series changes one of them");
  for (const std::string& name : a.series) {
    const Series& s = seriesNamed(name);
    for (const std::string& method : a.methods) {
      std::vector<double> x, t, mem;
      Json points = Json::array();
      for (int v : a.quick ? s.quick : s.values) {
        if (!a.json) std::fprintf(stderr, "bench scale: %s=%d (%s)\n", s.name, v, method.c_str());
        Json pt = runChild(a, s.name, v, method);
        x.push_back(pt["x"].get<double>());
        t.push_back(pt["step_seconds"].get<double>());
        mem.push_back(pt["peak_rss_bytes"].get<double>() - pt["baseline_rss_bytes"].get<double>());
        points.push_back(Json{{"x", x.back()}, {"step_seconds", t.back()}, {"memory_bytes", mem.back()}});
      }
      const std::string key = std::string(s.name) + "_" + method;
      std::string display;
      for (const auto& p : points)
        display += (display.empty() ? "" : "; ") + BenchReport::fmt(p["x"].get<double>()) + ": " + BenchReport::fmt(p["step_seconds"].get<double>()) +
                   " s, " + BenchReport::fmt(p["memory_bytes"].get<double>() / 1048576.0) + " MiB";
      rep.value("points_" + key, points, display);
      rep.number("time_exponent_" + key, growthExponent(x, t), "(log-log slope of step seconds)");
      rep.number("memory_exponent_" + key, offsetGrowthExponent(x, mem), "(k of the best fit a + b x^k to peak memory above the process's start)");
      // The top of the range, where fixed costs weigh least: the slope between the last two points.
      const size_t n = x.size();
      rep.number("time_exponent_top_" + key, growthExponent({x[n - 2], x[n - 1]}, {t[n - 2], t[n - 1]}), "(the last two points)");
      rep.number("memory_per_unit_top_" + key, (mem[n - 1] - mem[n - 2]) / (x[n - 1] - x[n - 2]), "bytes per unit (the last two points)");
    }
  }
  rep.print(a.json);
}

std::vector<std::string> splitList(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  std::string item;
  while (std::getline(in, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

}  // namespace

void addBenchScaleCommand(CLI::App& bench, int& exitCode) {
  auto args = std::make_shared<ScaleArgs>();
  auto series = std::make_shared<std::string>("pixels,parameters,triangles,views");
  auto methods = std::make_shared<std::string>("pt,ris,restir");
  auto* c = bench.add_subcommand("scale", "Step time and worker memory against film pixels, parameters, triangles and views, with fitted growth exponents");
  c->add_option("--series", *series, "comma-separated: pixels, parameters, triangles, views")->capture_default_str();
  c->add_option("--methods", *methods, "comma-separated: pt, ris, restir")->capture_default_str();
  c->add_option("--warmup", args->warmup, "gradient steps after the job's burn-in, before the timed ones")->capture_default_str();
  c->add_option("--repeats", args->repeats, "timed steps per point (fastest kept)")->capture_default_str();
  c->add_flag("--quick", args->quick, "two small points per series (a check that it runs, not figures)");
  c->add_flag("--json", args->json, "print one JSON object");
  // A child's point; not for users.
  c->add_option("--point", args->point, "SERIES=VALUE: measure one point in this process (used by the bench itself)")->group("");
  c->add_option("--method", args->method, "the method of --point")->group("");
  c->callback([args, series, methods, &exitCode] {
    args->series = splitList(*series);
    args->methods = splitList(*methods);
    for (const std::string& s : args->series) seriesNamed(s);
    runBenchScale(*args);
    exitCode = 0;
  });
}

}  // namespace invr::cli
