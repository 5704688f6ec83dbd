// invr-lab bench step: one gradient step against the time bare Embree needs for the rays that step
// traced (the ray-tracing bound of issue 41). The step's rays are logged through every Embree query
// (core/geometry/ray_log.h), split by kind and BVH, and replayed in each of Embree's modes; the
// bound is the sum over kinds of the fastest mode. The step itself is timed without the log, on
// the same rays: the engine is deterministic, so a fresh engine run through the same warm-up steps
// traces them again.
#include <algorithm>
#include <map>
#include <memory>

#include "client/common/bench_report.h"
#include "client/lab/embree_replay.h"
#include "client/lab/lab_commands.h"
#include "client/lab/step_engine.h"
#include "core/error.h"
#include "core/job/problem.h"
#include "core/job/zoo_jobs.h"
#include "core/stopwatch.h"

namespace invr::cli {

namespace {

struct StepArgs {
  std::string scene = "oxalis";
  std::string method;  // empty: the job's
  int warmup = 4;      // gradient steps after the job's burn-in, before the measured one
  int repeats = 5;     // timed runs of the step and of each replay (fastest kept)
  int targetSpp = 64;
  bool replay = true;  // false: time the steps only (a workload for profilers)
  bool json = false;
};

struct StepRun {
  double seconds = 0;
  v1::GradientStats stats;
};

// A fresh engine through the job's evaluations before the measured one, then the measured step,
// timed. With `log`, only that step's rays are logged.
StepRun runStep(const Problem& p, const std::vector<Image>& targets, int warmup, std::unique_ptr<RayLog>* log) {
  StepEngine engine(p, targets);
  const uint64_t measured = measuredCounter(p, warmup);
  for (uint64_t k = 0; k < measured; ++k) engine.evaluate(k);
  if (log) {
    *log = std::make_unique<RayLog>();
    p.scene->observeRays(log->get());
  }
  Stopwatch clock;
  StepRun run;
  run.stats = engine.evaluate(measured);
  run.seconds = clock.seconds();
  if (log) p.scene->observeRays(nullptr);  // the BVHs stay retained for the replay; nothing else is logged
  return run;
}

// A profiler's workload (--no-replay): one engine through the same warm-up, then `count`
// consecutive gradient steps, each timed.
std::vector<StepRun> consecutiveSteps(const Problem& p, const std::vector<Image>& targets, int warmup, int count) {
  StepEngine engine(p, targets);
  const uint64_t first = measuredCounter(p, warmup);
  for (uint64_t k = 0; k < first; ++k) engine.evaluate(k);
  std::vector<StepRun> runs;
  for (int i = 0; i < count; ++i) {
    Stopwatch clock;
    StepRun run;
    run.stats = engine.evaluate(first + uint64_t(i));
    run.seconds = clock.seconds();
    runs.push_back(std::move(run));
  }
  return runs;
}

// The bound and the step against it; per kind: rays, bound seconds and the fastest mode (of the
// kind's largest group).
void reportBound(BenchReport& rep, double stepSeconds, const std::vector<LoggedRay>& rays, const std::vector<RayGroup>& groups,
                 const ReplayTimes& times, const v1::RayCounts& counted) {
  rep.number("ray_bound_seconds", times.boundSeconds(), "s (bare Embree, each kind in its fastest mode)");
  rep.number("ratio_step_over_ray_bound", stepSeconds / times.boundSeconds(), "(target <= 3)");
  rep.number("ray_single_seconds", times.modeSeconds(0), "s (bare Embree, single rays)");
  rep.number("ratio_step_over_single_rays", stepSeconds / times.modeSeconds(0));
  rep.number("rays", double(rays.size()), "(every Embree query of the step)");
  rep.number("rays_counted", double(counted.camera() + counted.bounce() + counted.shadow()), "(the step's own ray statistics)");
  std::map<std::string, std::pair<size_t, double>> perKind;
  std::map<std::string, std::pair<size_t, std::string>> modeOf;
  for (size_t g = 0; g < groups.size(); ++g) {
    auto& k = perKind[groups[g].kind];
    k.first += groups[g].rays.size();
    k.second += times.best[g][times.fastestMode(g)];
    auto& m = modeOf[groups[g].kind];
    if (groups[g].rays.size() > m.first) m = {groups[g].rays.size(), replayModes()[times.fastestMode(g)].name};
  }
  for (const char* kind : {"camera", "bounce", "shadow", "boundary"}) {
    auto it = perKind.find(kind);
    const size_t n = it == perKind.end() ? 0 : it->second.first;
    rep.number(std::string("rays_") + kind, double(n));
    if (n == 0) continue;
    rep.number(std::string("ray_bound_seconds_") + kind, it->second.second, "s");
    rep.text(std::string("embree_best_mode_") + kind, modeOf[kind].second);
  }
}

void runBenchStep(const StepArgs& a) {
  if (a.warmup < 0 || a.repeats <= 0 || a.targetSpp <= 0)
    throw InputError("bench step: --warmup must be >= 0, --repeats and --target-spp positive");
  v1::JobSpec job = zooJob(a.scene);
  job.mutable_optimization()->set_target_spp(a.targetSpp);
  if (!a.method.empty()) {  // through the job, so that its burn-in follows the method
    const GradientMethod m = gradientMethodFromName(a.method);
    job.mutable_optimization()->set_method(m == GradientMethod::Pt ? v1::METHOD_PT : m == GradientMethod::Ris ? v1::METHOD_RIS : v1::METHOD_RESTIR);
  }
  Problem p = buildProblem(job);
  const std::vector<Image> targets = renderTargets(p);
  p.params.write(p.initial, *p.scene);  // every step at the starting parameters

  std::unique_ptr<RayLog> log;
  const StepRun logged = a.replay ? runStep(p, targets, a.warmup, &log) : StepRun{};
  const std::vector<LoggedRay> rays = log ? log->take() : std::vector<LoggedRay>{};
  std::vector<Vec3> eyes;
  for (const Camera& c : p.scene->cameras) eyes.push_back(c.eye);
  const std::vector<RayGroup> groups = groupRays(rays, eyes);
  // The log (and the BVHs it retains) lives through the replays.
  ReplayTimes times;
  std::vector<StepRun> runs;
  if (a.replay) {
    for (int i = 0; i < a.repeats; ++i) {
      runs.push_back(runStep(p, targets, a.warmup, nullptr));
      replayOnce(groups, times);
    }
  } else {
    runs = consecutiveSteps(p, targets, a.warmup, a.repeats);
  }
  log.reset();
  const v1::RayCounts counted = runs[0].stats.rays();
  if (a.replay) {
    runs.push_back(logged);  // checked with the others, then left out of the timing
    for (const StepRun& r : runs)
      if (r.stats.rays().SerializeAsString() != counted.SerializeAsString() || r.stats.loss() != runs[0].stats.loss())
        throw std::runtime_error("bench step: the step traced other rays when run again (the engine must be deterministic)");
    runs.pop_back();
  }
  std::vector<double> seconds;
  for (const StepRun& r : runs) seconds.push_back(r.seconds);
  std::sort(seconds.begin(), seconds.end());
  const StepRun& fastest = *std::min_element(runs.begin(), runs.end(), [](const StepRun& x, const StepRun& y) { return x.seconds < y.seconds; });

  BenchReport rep("step");
  rep.text("scene", a.scene);
  rep.text("method", gradientMethodName(p.gradient.method));
  rep.number("views", double(evaluationAt(p, measuredCounter(p, a.warmup)).views.size()));
  rep.number("film_pixels", double(p.scene->width) * double(p.scene->height));
  rep.number("step_seconds", fastest.seconds, "s (fastest of --repeats)");
  rep.number("step_seconds_median", seconds[seconds.size() / 2], "s");
  const v1::GradientStats& st = fastest.stats;
  if (a.replay) reportBound(rep, fastest.seconds, rays, groups, times, st.rays());
  // The step by phase (the engine's own clocks, of the fastest run); "other" is the rest: loss,
  // gradient folding, setting up passes.
  const std::pair<const char*, double> phases[] = {{"reservoir", st.seconds_reservoir()}, {"stage1", st.seconds_stage1()},
                                                   {"primal", st.seconds_primal()},       {"derivative", st.seconds_derivative()},
                                                   {"boundary", st.seconds_boundary()},   {"variance", st.seconds_variance()}};
  double sum = 0;
  for (const auto& [name, s] : phases) {
    rep.number(std::string("phase_seconds_") + name, s, "s");
    sum += s;
  }
  rep.number("phase_seconds_other", std::max(0.0, fastest.seconds - sum), "s");
  // Shape jobs: what each boundary term drew from (edges summed over views) and counted, e.g. the
  // primary term's terminator_edges and hidden_edges_skipped (creases a closed mesh turns away
  // from the eye, left out before sampling).
  std::map<std::string, v1::BoundaryTermStats> terms(st.boundary().begin(), st.boundary().end());
  for (const auto& [name, term] : terms) {
    rep.number("boundary_" + name + "_candidate_edges", double(term.candidate_edges()));
    rep.number("boundary_" + name + "_samples", double(term.samples()));
    std::map<std::string, uint64_t> counters(term.counters().begin(), term.counters().end());
    for (const auto& [counter, value] : counters) rep.number("boundary_" + name + "_" + counter, double(value));
  }
  if (a.replay) rep.number("logged_step_seconds", logged.seconds, "s (with the ray log: not the figure above)");
  rep.print(a.json);
}

}  // namespace

void addBenchStepCommand(CLI::App& bench, int& exitCode) {
  auto args = std::make_shared<StepArgs>();
  auto* c = bench.add_subcommand("step", "One gradient step against bare Embree's time for the rays that step traced (the ray bound)");
  c->add_option("--scene", args->scene, "zoo scene (its job: parameters, views, spp)")->capture_default_str();
  c->add_option("--method", args->method, "pt, ris or restir (default: the job's)")->check(CLI::IsMember({"pt", "ris", "restir"}));
  c->add_option("--warmup", args->warmup, "full steps before the measured one")->capture_default_str();
  c->add_option("--repeats", args->repeats, "timed runs of the step and of each replay (fastest kept)")->capture_default_str();
  c->add_option("--target-spp", args->targetSpp, "spp of the targets rendered from the scene")->capture_default_str();
  c->add_flag("!--no-replay", args->replay,
              "no ray log or replays: one engine runs --repeats consecutive steps after the warm-up, each timed (a workload for profilers)");
  c->add_flag("--json", args->json, "print one JSON object");
  c->callback([args, &exitCode] {
    runBenchStep(*args);
    exitCode = 0;
  });
}

}  // namespace invr::cli
