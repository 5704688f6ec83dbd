// invr optimize: run an inverse problem in this process (no server) and write its results.
// invr example: print a zoo scene's built-in job as JSON, for a user to edit.
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <memory>

#include "proto/wire/cli_checks.h"
#include "client/common/bench_report.h"
#include "client/commands.h"
#include "client/common/job_argument.h"
#include "client/common/progress.h"
#include "core/job/zoo_jobs.h"
#include "core/error.h"
#include "core/io/job_io.h"
#include "client/common/figures.h"
#include "core/optim/local_run.h"
#include "core/optim/results_io.h"
#include "core/render/renderer.h"

namespace invr::cli {

namespace {

struct OptimizeArgs {
  std::string job;
  std::string out = "out/optimize";
  int steps = 0;
  int snapshotEvery = 0;
  int finalSpp = 64;
  std::string method;
  SceneArgs sceneArgs;
};

// The service's snapshots (job_runner.cc), in process: renders of the first four views at the
// final renders' spp, and the parameters. The scene is written with the theta the next step
// writes anyway, so the run's numbers do not change.
void writeLocalSnapshot(Problem& problem, const std::vector<float>& theta, uint64_t step, const std::filesystem::path& dir, int spp) {
  const std::string stem = "step" + std::to_string(step);
  std::filesystem::create_directories(dir / "snapshots" / stem);
  writeParameters(dir / "snapshots" / stem, problem.params, theta, *problem.scene);
  problem.params.write(theta, *problem.scene);
  const RenderOptions ro = transportRenderOptions(problem, spp, kFinalRenderStream);
  for (size_t v = 0; v < problem.scene->cameras.size() && v < 4; ++v)
    writeImage(dir / "snapshots" / (stem + "_view" + std::to_string(v) + ".png"), renderView(*problem.scene, int(v), ro).image);
}

void runOptimize(const OptimizeArgs& a) {
  AssetResolver assets;
  auto job = optimizationJobFromArgument(a.job, assets, a.sceneArgs);
  if (a.steps < 0) throw InputError("--steps: must be positive (got " + std::to_string(a.steps) + ")");
  if (a.steps > 0) job.mutable_optimization()->set_steps(a.steps);
  if (a.method == "pt") job.mutable_optimization()->set_method(invr::v1::METHOD_PT);
  else if (a.method == "ris") job.mutable_optimization()->set_method(invr::v1::METHOD_RIS);
  else if (a.method == "restir") job.mutable_optimization()->set_method(invr::v1::METHOD_RESTIR);
  if (a.snapshotEvery > 0) job.mutable_optimization()->set_snapshot_every(a.snapshotEvery);
  const int snapshotEvery = job.optimization().snapshot_every();
  Problem problem = buildProblem(job, assets);
  std::filesystem::path dir(a.out);
  std::filesystem::create_directories(dir);
  ConvergenceCsv csv(dir / "convergence.csv");
  try {
    csv.write();  // the header: fails now, not after the run, when the folder is not writable
  } catch (const InputError&) {
    throw InputError("-o: cannot write to '" + a.out + "'");
  }
  const char* method = gradientMethodName(problem.gradient.method);
  std::cout << "optimizing " << (job.name().empty() ? a.job : job.name()) << ": " << problem.params.size() << " parameter values, "
            << problem.steps << " steps, method " << method << ", " << problem.scene->cameras.size() << " views\n"
            << "rendering targets (" << problem.targetSpp << " spp, " << problem.scene->cameras.size() << " view(s))...\n" << std::flush;
  ProgressBar targetBar("targets");
  ProgressBar bar("optimize");
  bool tty = isatty(fileno(stdout)) != 0;
  LocalRunResult result;
  try {
    bool targetsDone = false;
    result = runLocally(problem, [&](const StepReport& r) {
      if (!targetsDone) {
        targetsDone = true;
        targetBar.finish();
      }
      ConvergenceRow row{method, r.step, r.seconds, r.loss, r.parameterError, std::numeric_limits<double>::quiet_NaN(), r.stats, r.shapeError};
      row.imageLoss = r.imageLoss;
      csv.add(std::move(row));
      if (csv.rows() % 100 == 0) csv.write();  // a long run's CSV stays current
      if (snapshotEvery > 0 && r.theta && r.step % uint64_t(snapshotEvery) == 0) writeLocalSnapshot(problem, *r.theta, r.step, dir, a.finalSpp);
      char detail[160];
      std::snprintf(detail, sizeof detail, "step %llu/%d  loss %.4g  image_loss %.4g%s", (unsigned long long)r.step, problem.steps, r.loss,
                    r.imageLoss, r.parameterError >= 0 ? ("  param_error " + BenchReport::fmt(r.parameterError)).c_str() : "");
      bar.update(double(r.step) / problem.steps, detail);
      if (!tty && (r.step % 10 == 0 || int(r.step) == problem.steps))
        std::cout << "step " << r.step << "/" << problem.steps << "  loss " << r.loss << "  image_loss " << r.imageLoss
                  << "  param_error " << r.parameterError
                  << (r.shapeError >= 0 ? "  shape_error " + std::to_string(r.shapeError) : std::string()) << "  " << r.seconds << " s\n"
                  << std::flush;
    }, [&](int done, int views) {
      targetBar.update(double(done) / views, std::to_string(done) + "/" + std::to_string(views) + " view(s)");
      if (!tty && done == views) std::cout << "targets rendered\n" << std::flush;
    });
  } catch (const std::exception&) {
    csv.write();  // the steps that were done (a diverging run's among them)
    throw;
  }
  csv.write();
  bar.finish();
  writeParameters(dir, problem.params, result.theta, *problem.scene);
  {
    // The job beside its results (invr export rebuilds the scene from it), asset paths absolute.
    invr::v1::JobSpec resolved = job;
    forEachAssetRef(resolved, [&](invr::v1::AssetRef& ref, const std::string&) {
      if (ref.has_path() && std::filesystem::path(ref.path()).is_relative()) ref.set_path(std::filesystem::absolute(assets.baseDir / ref.path()).string());
    });
    std::ofstream out(dir / "job.json");
    out << jobToJson(resolved);
    if (!out.flush()) throw InputError("-o: cannot write '" + (dir / "job.json").string() + "'");
  }
  try {  // the chart is a convenience: a machine without matplotlib still gets the CSV
    // Sampling parameters and photographs have no ground truth: chart the smoothed image loss.
    const bool truth = parameterError(problem, problem.initial) >= 0;
    drawConvergenceChart({dir / "convergence.csv"}, dir / "convergence.png", "seconds",
                         truth ? "param_error" : !problem.truthMeshes.empty() ? "shape_error" : "image_loss");
  } catch (const std::exception& e) {
    std::cerr << "invr: no convergence chart: " << e.what() << "\n";
  }
  RenderOptions ro = transportRenderOptions(problem, a.finalSpp, kFinalRenderStream);  // the targets' transport
  for (size_t v = 0; v < problem.scene->cameras.size() && v < 4; ++v) {
    writeImage(dir / ("final_view" + std::to_string(v) + ".png"), renderView(*problem.scene, int(v), ro).image);
    writeImage(dir / ("target_view" + std::to_string(v) + ".png"), result.targets[v]);
    writeImage(dir / ("target_view" + std::to_string(v) + ".exr"), result.targets[v]);  // exact (invr export takes them)
  }
  // Where the run started, for side-by-side comparison (the scene goes back to the result after).
  problem.params.write(problem.initial, *problem.scene);
  for (size_t v = 0; v < problem.scene->cameras.size() && v < 4; ++v)
    writeImage(dir / ("initial_view" + std::to_string(v) + ".png"), renderView(*problem.scene, int(v), ro).image);
  problem.params.write(result.theta, *problem.scene);
  // Variance-aware jobs and sampling parameters: what the optimised sampling does (docs/variance.md).
  for (const std::string& f : writeSelectionResults(dir, problem.params, *problem.scene, result.theta)) std::cout << "wrote " << f << "\n";
  if (problem.gradient.variance.enabled) {
    GradientEngine engine(*problem.scene, problem.params, result.targets, problem.gradient);
    for (size_t v = 0; v < problem.scene->cameras.size() && v < 4; ++v)
      writeImage(dir / ("variance_view" + std::to_string(v) + ".exr"), engine.sampleVarianceMap(int(v), std::max(2, a.finalSpp), problem.seed));
  }
  const StepReport& last = result.history.back();
  std::cout << "done: "
            << (last.parameterError >= 0 ? "parameter error " + BenchReport::fmt(parameterError(problem, problem.initial)) + " -> " +
                                               BenchReport::fmt(last.parameterError)
                : last.shapeError >= 0   ? std::string("no parameter error (started from another mesh)")
                                         : std::string("no parameter error (sampling parameters have no ground truth)"))
            << (last.shapeError >= 0 ? ", shape error " + BenchReport::fmt(shapeError(problem, problem.initial)) + " -> " + BenchReport::fmt(last.shapeError)
                                     : std::string())
            << ", loss "
            << result.history.front().loss << " -> " << last.loss << ", image loss " << result.history.front().imageLoss << " -> "
            << last.imageLoss << " in " << last.seconds << " s (targets " << BenchReport::fmt(result.targetSeconds) << " s)\n"
            << "wrote " << std::filesystem::absolute(dir).string() << " (convergence.csv and .png, parameters.json, job.json, initial/target/final renders" << (snapshotEvery > 0 ? ", snapshots/" : "") << ")\n";
}

}  // namespace

void addOptimizeCommands(CLI::App& app, int& exitCode) {
  auto args = std::make_shared<OptimizeArgs>();
  auto* cmd = app.add_subcommand("optimize", "Run an inverse problem in this process (a zoo scene's built-in job, a job file or a Mitsuba 3 scene with --param)");
  cmd->add_option("job", args->job, "zoo scene name, job file (.json with an 'optimization') or Mitsuba 3 scene (.xml, with --param)")->required();
  cmd->add_option("-o,--out", args->out, "output folder")->capture_default_str();
  cmd->add_option("--steps", args->steps, "override the number of steps")->check(invr::wire::kPositive);
  cmd->add_option("--snapshot-every", args->snapshotEvery,
                  "every N steps, write renders of the first views and the parameters under OUT/snapshots/ (step<k>_view<v>.png, step<k>/parameters.json)")
      ->check(invr::wire::kPositive);
  cmd->add_option("--method", args->method, "override the method")->check(CLI::IsMember({"pt", "ris", "restir"}));
  cmd->add_option("--final-spp", args->finalSpp, "samples per pixel of the initial, final and snapshot renders (and the variance maps)")
      ->check(invr::wire::kPositive)
      ->capture_default_str();
  addSceneArgs(cmd, args->sceneArgs, true);
  cmd->callback([args, &exitCode] { runOptimize(*args); exitCode = 0; });

  auto name = std::make_shared<std::string>();
  auto* ex = app.add_subcommand("example", "Print a zoo scene's built-in job as JSON (edit it, then `invr optimize FILE.json`)");
  ex->add_option("scene", *name, "zoo scene name")->required();
  ex->callback([name, &exitCode] {
    std::cout << jobToJson(zooJob(*name)) << "\n";
    exitCode = 0;
  });
}

}  // namespace invr::cli
