#include "server/job_runner.h"

#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/io/zero_copy_stream_impl_lite.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <iomanip>
#include <sstream>

#include "core/error.h"
#include "core/image/image.h"
#include "core/io/job_io.h"
#include "core/optim/optimization_loop.h"
#include "core/optim/results_io.h"
#include "core/optim/smoothed_loss.h"
#include "core/stopwatch.h"
#include "proto/wire/sha256.h"

namespace invr::server {

namespace v1 = invr::v1;

namespace {

// SHA-256 of the spec's deterministic serialization: how later tasks name the spec a worker holds.
std::string specHash(const v1::JobSpec& spec) {
  std::string bytes;
  {
    google::protobuf::io::StringOutputStream raw(&bytes);
    google::protobuf::io::CodedOutputStream coded(&raw);
    coded.SetSerializationDeterministic(true);
    spec.SerializeToCodedStream(&coded);
  }
  Sha256 h;
  h.update(bytes.data(), bytes.size());
  return h.hex();
}

// The spec is added per worker by the scheduler (once per connection).
v1::Task baseTask(const std::string& job, size_t shard, const std::vector<float>& theta) {
  v1::Task t;
  t.set_job_id(job);
  t.set_shard(uint32_t(shard));
  t.mutable_theta()->Assign(theta.begin(), theta.end());
  return t;
}

Image fromWire(const v1::FloatImage& fi, bool* ok) {
  Image im(fi.width(), fi.height(), fi.channels());
  *ok = size_t(fi.pixels_size()) == im.data().size();
  if (*ok) std::copy(fi.pixels().begin(), fi.pixels().end(), im.data().begin());
  return im;
}

// The snapshots a run wrote so far (they survive restarts), as result names.
// The files under the results' sub-folders: snapshots/ and truth/ (a synthetic job's truth).
std::vector<std::string> snapshotFiles(const std::filesystem::path& resultsDir) {
  std::vector<std::string> files;
  for (const char* sub : {"snapshots", "truth"}) {
    std::error_code ec;
    const auto root = resultsDir / sub;
    if (!std::filesystem::is_directory(root, ec)) continue;
    for (auto it = std::filesystem::recursive_directory_iterator(root, ec); !ec && it != std::filesystem::recursive_directory_iterator();
         it.increment(ec))
      if (it->is_regular_file(ec)) files.push_back(std::filesystem::relative(it->path(), resultsDir, ec).generic_string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace

struct JobRunner::Context {
  std::string id;
  v1::JobSpec spec;
  Problem p;
  std::vector<float> theta;
  v1::Checkpoint ck;
  bool haveCheckpoint = false;
  bool problemBuilt = false;
};

JobRunner::JobRunner(RunnerOptions options, JobStore& store, JobBook& book, Scheduler& scheduler, const Admission& admission,
                     PreparedProblem& prepared, const std::atomic<bool>& stopping)
    : opt_(options), store_(store), book_(book), scheduler_(scheduler), admission_(admission), prepared_(prepared), stopping_(stopping) {}

void JobRunner::run(const std::string& id) {
  Context c;
  c.id = id;
  c.spec = book_.spec(id);
  bool scheduled = false;
  try {
    if (auto validated = prepared_.take(id))
      c.p = std::move(*validated);  // built when it was submitted
    else
      c.p = admission_.build(c.spec);
    c.problemBuilt = true;
    ScheduledJob sj;
    sj.id = id;
    sj.spec = c.spec;
    sj.specHash = specHash(c.spec);
    sj.shape.parameters = c.p.params.size();
    sj.shape.width = c.p.scene->width;
    sj.shape.height = c.p.scene->height;
    sj.shards = c.p.shards.size();
    sj.priority = std::max<uint32_t>(1, c.spec.scheduling().priority());
    sj.maxWorkers = c.spec.scheduling().max_workers();
    sj.log = [this, id](const std::string& m) { book_.log(id, m); };
    sj.cancelled = [this, id] { return book_.cancelRequested(id); };
    scheduler_.addJob(std::move(sj));
    scheduled = true;
    runSteps(c);
    writeResults(c);
    scheduler_.removeJob(id);
    return;
  } catch (const JobCancelled&) {
    if (scheduled) scheduler_.removeJob(id);
    if (stopping_ && !book_.cancelRequested(id)) return;  // server shutting down: the job resumes on restart
    const std::vector<std::string> files = writeCheckpointResults(c);
    book_.end(id, v1::CANCELLED, "cancelled by request", &files);
    return;
  } catch (const JobFailed& f) {
    if (scheduled) scheduler_.removeJob(id);
    fail(c, f.reason);
  } catch (const InputError& e) {
    if (scheduled) scheduler_.removeJob(id);
    fail(c, e.what());
  } catch (const std::exception& e) {
    if (scheduled) scheduler_.removeJob(id);
    fail(c, std::string("internal error: ") + e.what());
  }
}

void JobRunner::runSteps(Context& c) {
  const std::string& id = c.id;
  Problem& p = c.p;
  const std::string method = gradientMethodName(p.gradient.method);
  auto saved = store_.loadCheckpoint(id);
  OptimizerState state;
  uint64_t counter = 0, step = 0;
  double secondsBefore = 0;
  if (saved) {
    c.ck = *saved;
    c.haveCheckpoint = true;
    c.theta.assign(c.ck.theta().begin(), c.ck.theta().end());
    state.m.assign(c.ck.adam_m().begin(), c.ck.adam_m().end());
    state.v.assign(c.ck.adam_v().begin(), c.ck.adam_v().end());
    state.step = c.ck.optimizer_step();
    counter = c.ck.counter();
    step = c.ck.step();
    secondsBefore = c.ck.seconds();
  } else {
    // Step 0 is a checkpoint too: a job that diverges on its first step still has one to keep.
    c.theta = p.initial;
    c.ck.set_step(0);
    c.ck.set_counter(0);
    c.ck.mutable_theta()->Assign(c.theta.begin(), c.theta.end());
    store_.saveCheckpoint(id, c.ck);
    c.haveCheckpoint = true;
  }
  if (c.theta.size() != p.params.size()) throw JobFailed{"checkpoint does not match the job's parameters"};
  book_.started(id, step, uint64_t(p.steps), method);
  if (p.groundTruthKnown() && !saved) {
    // A synthetic job's truth among its results (truth/parameters.json, textures as EXR): the
    // dashboard shows each texture beside it while the job runs.
    try {
      const auto dir = store_.resultsDir(id) / "truth";
      std::filesystem::create_directories(dir);
      std::vector<std::string> files;
      for (const auto& f : writeParameters(dir, p.params, p.truth, *p.scene)) files.push_back("truth/" + f);
      book_.addResults(id, files);
    } catch (const std::exception& e) {
      book_.log(id, std::string("cannot write the truth among the results: ") + e.what());
    }
  }
  {
    std::ostringstream msg;
    if (saved)
      msg << "resumed from checkpoint at step " << step << "/" << p.steps;
    else
      msg << "started: " << p.params.size() << " parameter values, " << p.steps << " steps, method " << method << ", "
          << p.scene->cameras.size() << " views in " << p.shards.size() << " shards";
    const uint32_t prio = std::max<uint32_t>(1, c.spec.scheduling().priority());
    if (prio != 1 || c.spec.scheduling().max_workers())
      msg << " (priority " << prio << (c.spec.scheduling().max_workers() ? ", at most " + std::to_string(c.spec.scheduling().max_workers()) + " workers" : "")
          << ")";
    book_.log(id, msg.str());
  }
  LoopState start;
  start.theta = c.theta;
  start.optimizer = state;
  start.counter = counter;
  start.step = step;
  OptimizationLoop loop(p, std::move(start), p.burnIn, p.steps);
  // The smoothed image loss goes on from the logged steps of an earlier run of this job.
  SmoothedLoss imageLoss;
  if (saved) {
    std::map<uint64_t, double> logged;
    for (const auto& e : store_.loadEvents(id))
      if (e.has_step() && e.step().step() <= step) logged[e.step().step()] = e.step().stats().primal_loss();
    for (const auto& [k, v] : logged) imageLoss.add(v);
  }
  const Stopwatch runClock;
  uint64_t stepsThisRun = 0;
  Stopwatch sinceFirstStep, sinceLastStep;
  // The shards go to workers; the loop sums their results in shard order, as in process.
  double wall = 0, slowest = 0;
  // A worker that builds a shard's session mid-job (a new assignment, an eviction, a restart)
  // refills its reservoirs with render-only steps first, but only when the shard has a past: one
  // whose views no earlier evaluation held starts empty, as it does in process. Which shards have
  // a past follows from the counters alone (the batches are a function of them), so a resumed job
  // finds it again.
  const uint32_t rebuildBurnIn = p.gradient.method == GradientMethod::Restir ? uint32_t(std::max(p.burnIn, 1)) : 0;
  std::vector<bool> shardSeen(p.shards.size(), false);
  uint64_t seenBefore = 0;  // evaluations [0, seenBefore) are counted in shardSeen
  auto markSeen = [&](const Evaluation& ev) {
    for (size_t s = 0; s < p.shards.size(); ++s)
      if (!shardSeen[s] && !shardRequest(p, ev, s).views.empty()) shardSeen[s] = true;
  };
  // The first evaluation a worker gets for a shard builds its session (the scene, the targets,
  // the reservoirs' burn-in): say so before the wait, and how long it took after, so no client
  // sits through it without a word.
  bool sessionsBuilt = false;
  auto evaluateOnWorkers = [&](const Evaluation& e, const std::vector<float>& at) {
    if (!sessionsBuilt) {
      std::ostringstream msg;
      msg << "preparing: the workers build each shard's session (" << p.shards.size() << " shards: the scene, ";
      if (p.givenTargets.empty())
        msg << "the targets rendered at " << p.targetSpp << " samples per pixel";
      else
        msg << "the uploaded targets";
      msg << (p.burnIn > 0 ? ", then " + std::to_string(p.burnIn) + " burn-in steps" : std::string()) << "); step 1 follows";
      book_.log(id, msg.str());
    }
    for (; seenBefore < e.counter; ++seenBefore) markSeen(evaluationAt(p, seenBefore));
    std::vector<std::optional<v1::Task>> tasks(p.shards.size());
    for (size_t s = 0; s < p.shards.size(); ++s) {
      GradientRequest r = shardRequest(p, e, s);
      if (r.views.empty()) continue;
      v1::Task t = baseTask(id, s, at);
      t.set_rebuild_burn_in(shardSeen[s] ? rebuildBurnIn : 0);
      t.set_kind(v1::Task::GRADIENT);
      t.mutable_views()->Assign(r.views.begin(), r.views.end());
      t.set_batch_views(uint32_t(r.batchViews));
      t.set_all_shard_views(r.allSessionViews);
      t.set_counter(e.counter);
      t.set_render_only(e.renderOnly);
      tasks[s] = std::move(t);
    }
    const Stopwatch stepClock;
    auto results = scheduler_.run(id, tasks);
    wall = stepClock.seconds();
    if (!sessionsBuilt) {
      sessionsBuilt = true;
      double session = 0;
      for (const auto& r : results)
        if (r) session = std::max(session, r->seconds_session());
      std::ostringstream msg;
      msg << "sessions ready: " << std::fixed << std::setprecision(1) << wall << " s (the slowest shard's scene and targets "
          << session << " s)";
      book_.log(id, msg.str());
    }
    slowest = 0;
    std::vector<std::optional<GradientResult>> out(results.size());
    for (size_t s = 0; s < results.size(); ++s) {
      const auto& r = results[s];
      if (!r) continue;
      GradientResult g;
      g.gradient.assign(r->gradient().begin(), r->gradient().end());
      g.stats = r->stats();
      const v1::GradientStats& st = r->stats();
      slowest = std::max(slowest, st.seconds_primal() + st.seconds_derivative() + st.seconds_reservoir() + r->seconds_session() +
                                      st.seconds_stage1() + st.seconds_variance() + st.seconds_boundary());
      out[s] = std::move(g);
    }
    return out;
  };
  while (!loop.done()) {
    const bool burnIn = loop.burningIn();
    std::optional<GradientResult> g;
    try {
      g = loop.next(evaluateOnWorkers);
    } catch (const InputError& err) {  // divergence: the loop kept the last good state
      throw JobFailed{std::string(err.what()) + "; the last good checkpoint (step " + std::to_string(loop.state().step) + ") is kept"};
    }
    if (burnIn) {
      const uint64_t k = loop.state().counter;
      const uint64_t every = std::max<uint64_t>(1, uint64_t(p.burnIn) / 10);  // at most about ten lines
      if (k == 1 || k % every == 0 || k == uint64_t(p.burnIn))
        book_.log(id, "burn-in " + std::to_string(k) + "/" + std::to_string(p.burnIn) + " (render-only steps that fill the reservoirs)");
      continue;
    }
    const Stopwatch updateClock;
    const LoopState& ls = loop.state();
    c.theta = ls.theta;
    ++stepsThisRun;
    // Rates from the steps after this run's first (which includes building sessions and targets).
    if (stepsThisRun == 1) sinceFirstStep.restart();
    double seconds = secondsBefore + runClock.seconds();
    c.ck.set_step(ls.step);
    c.ck.set_counter(ls.counter);
    c.ck.mutable_theta()->Assign(ls.theta.begin(), ls.theta.end());
    c.ck.mutable_adam_m()->Assign(ls.optimizer.m.begin(), ls.optimizer.m.end());
    c.ck.mutable_adam_v()->Assign(ls.optimizer.v.begin(), ls.optimizer.v.end());
    c.ck.set_optimizer_step(ls.optimizer.step);
    c.ck.set_seconds(seconds);
    store_.saveCheckpoint(id, c.ck);  // before the progress event: the log never runs ahead of it
    double perStep = stepsThisRun == 1 ? wall : sinceFirstStep.seconds() / double(stepsThisRun - 1);
    v1::StepProgress sp;
    *sp.mutable_stats() = g->stats;
    sp.set_step(ls.step);
    sp.set_steps(uint64_t(p.steps));
    sp.set_loss(g->stats.loss());
    sp.set_image_loss(imageLoss.add(g->stats.primal_loss()));
    for (const auto& [name, values] : smallParameterValues(p.params, ls.theta)) {
      v1::ParameterValue* pv = sp.add_parameters();
      pv->set_name(name);
      for (double v : values) pv->add_values(v);
    }
    sp.set_param_error(p.groundTruthKnown() ? parameterError(p, ls.theta) : -1.0);
    sp.set_shape_error(shapeError(p, ls.theta));
    sp.set_seconds(seconds);
    sp.set_steps_per_second(1.0 / perStep);
    sp.set_eta_seconds(perStep * double(uint64_t(p.steps) - ls.step));
    sp.set_transport_seconds(std::max(0.0, wall - slowest));
    sp.set_update_seconds(updateClock.seconds());
    book_.stepDone(id, sp, scheduler_.workerSeconds(id), scheduler_.workersOf(id));
    const int every = c.spec.optimization().snapshot_every();
    if (every > 0 && ls.step % uint64_t(every) == 0) writeSnapshot(c, ls.step);
    if (onStep) onStep(sinceLastStep.lap());
    spdlog::info("[{} step {}] loss {:.6g} param_error {:.4g} ({:.2f} steps/s)", id, ls.step, sp.loss(), sp.param_error(),
                 sp.steps_per_second());
  }
}

void JobRunner::copyLog(const std::string& id, std::vector<std::string>& files) {
  std::error_code ec;
  std::filesystem::copy_file(store_.jobDir(id) / "progress.jsonl", store_.resultsDir(id) / "progress.jsonl",
                             std::filesystem::copy_options::overwrite_existing, ec);
  if (!ec) files.push_back("progress.jsonl");
}

void JobRunner::fail(Context& c, const std::string& reason) {
  const std::vector<std::string> files = writeCheckpointResults(c);
  book_.end(c.id, v1::FAILED, reason, &files);
}

std::string JobRunner::writeJob(Context& c) {
  // The job beside its results: what `invr export` rebuilds the scene from.
  const auto path = store_.resultsDir(c.id) / "job.json";
  std::ofstream out(path);
  out << jobToJson(c.spec);
  if (!out.flush()) throw InputError("cannot write '" + path.string() + "'");
  return "job.json";
}

std::string JobRunner::writeConvergence(Context& c) {
  // The convergence CSV of the whole job, rebuilt from the log (it survives restarts).
  const Problem& p = c.p;
  ConvergenceCsv csv(store_.resultsDir(c.id) / "convergence.csv");
  std::map<uint64_t, v1::StepProgress> steps;
  for (const auto& e : store_.loadEvents(c.id))
    if (e.has_step()) steps[e.step().step()] = e.step();
  for (const auto& [k, sp] : steps) {
    ConvergenceRow row;
    row.method = gradientMethodName(p.gradient.method);
    row.step = sp.step();
    row.seconds = sp.seconds();
    row.loss = sp.loss();
    row.paramError = sp.param_error();
    if (!p.truthMeshes.empty()) row.shapeError = sp.shape_error();
    row.imageLoss = sp.image_loss();
    row.stats = sp.stats();
    csv.add(std::move(row));
  }
  csv.write();
  return "convergence.csv";
}

void JobRunner::writeSnapshot(Context& c, uint64_t step) {
  // Written under the results folder at once and listed among the results, so a running job's
  // snapshots can be fetched. A failure to write is logged; the run goes on.
  const Problem& p = c.p;
  const auto dir = store_.resultsDir(c.id) / "snapshots";
  const std::string stem = "step" + std::to_string(step);
  std::vector<std::string> files;
  try {
    std::filesystem::create_directories(dir / stem);
    for (const auto& f : writeParameters(dir / stem, p.params, c.theta, *p.scene)) files.push_back("snapshots/" + stem + "/" + f);
  } catch (const std::exception& e) {
    book_.log(c.id, "snapshot at step " + std::to_string(step) + ": cannot write its parameters: " + e.what());
  }
  std::vector<std::optional<v1::Task>> tasks(p.shards.size());
  for (size_t s = 0; s < p.shards.size(); ++s) {
    v1::Task t = baseTask(c.id, s, c.theta);
    t.set_kind(v1::Task::SNAPSHOT);
    t.set_final_spp(opt_.finalSpp);
    for (int v : p.shards[s])
      if (v < opt_.finalViews) {
        t.add_views(v);
        if (!std::filesystem::exists(dir / ("target_view" + std::to_string(v) + ".png"))) t.set_with_targets(true);
      }
    if (t.views_size() > 0) tasks[s] = std::move(t);
  }
  std::vector<std::optional<v1::TaskResult>> results;
  try {
    results = scheduler_.run(c.id, tasks);
  } catch (const JobFailed& f) {  // the renders failed (a worker's error, expired leases): the run goes on
    book_.log(c.id, "snapshot at step " + std::to_string(step) + ": no renders (" + f.reason + ")");
  }
  for (size_t s = 0; s < results.size(); ++s) {
    if (!results[s]) continue;
    // Renders, then (from a worker that holds the shard's session) the targets: each target is
    // written once, beside the snapshots, for the dashboard's side-by-side views.
    const int nv = tasks[s]->views_size();
    const bool withTargets = tasks[s]->with_targets() && results[s]->renders_size() == 2 * nv;
    for (int k = 0; k < results[s]->renders_size() && k < (withTargets ? 2 * nv : nv); ++k) {
      const std::string name = (k < nv ? stem + "_view" : std::string("target_view")) + std::to_string(tasks[s]->views(k % nv)) + ".png";
      if (k >= nv && std::filesystem::exists(dir / name)) continue;
      bool ok = false;
      Image im = fromWire(results[s]->renders(k), &ok);
      if (!ok) continue;
      try {
        writeImage(dir / name, im);
        files.push_back("snapshots/" + name);
        // The radiance too, for the dashboard's exposure control (an HDR scene's PNG is clipped).
        const std::string hdr = name.substr(0, name.size() - 4) + ".exr";
        writeImage(dir / hdr, im);
        files.push_back("snapshots/" + hdr);
      } catch (const std::exception& e) {
        book_.log(c.id, "snapshot at step " + std::to_string(step) + ": " + e.what());
      }
    }
  }
  book_.addResults(c.id, files);
  book_.log(c.id, "snapshot at step " + std::to_string(step) + ": " + std::to_string(files.size()) + " file(s) under snapshots/");
}

std::vector<std::string> JobRunner::writeCheckpointResults(Context& c) {
  // A job that stops early (failed, cancelled) keeps its last good parameters and its
  // convergence so far, next to the log.
  std::vector<std::string> files;
  if (c.problemBuilt && c.haveCheckpoint && c.p.params.size() == size_t(c.ck.theta_size())) {
    try {
      std::filesystem::create_directories(store_.resultsDir(c.id));
      files = writeParameters(store_.resultsDir(c.id), c.p.params, std::vector<float>(c.ck.theta().begin(), c.ck.theta().end()), *c.p.scene);
      files.push_back(writeJob(c));
      files.push_back(writeConvergence(c));
    } catch (const std::exception& e) {
      spdlog::warn("[{}] cannot write its checkpoint's results: {}", c.id, e.what());
    }
  }
  for (auto& f : snapshotFiles(store_.resultsDir(c.id))) files.push_back(std::move(f));
  copyLog(c.id, files);
  return files;
}

void JobRunner::writeResults(Context& c) {
  const std::string& id = c.id;
  Problem& p = c.p;
  auto dir = store_.resultsDir(id);
  std::filesystem::create_directories(dir);
  std::vector<std::string> files = writeParameters(dir, p.params, c.theta, *p.scene);
  files.push_back(writeJob(c));
  files.push_back(writeConvergence(c));
  // Charts are the client's: `invr fetch` and `invr run` draw convergence.png from this CSV.
  // Renders from the workers: where the run started (initial_view<k>), where it ended
  // (final_view<k>), and the targets beside them, for side-by-side comparison.
  book_.log(id, "rendering final images");
  auto renderAt = [&](const std::vector<float>& theta, bool initial) {
    std::vector<std::optional<v1::Task>> tasks(p.shards.size());
    for (size_t s = 0; s < p.shards.size(); ++s) {
      v1::Task t = baseTask(id, s, theta);
      t.set_kind(v1::Task::FINAL_RENDER);
      t.set_final_spp(opt_.finalSpp);
      for (int v : p.shards[s])
        if (v < opt_.finalViews) t.add_views(v);
      if (t.views_size() > 0) tasks[s] = std::move(t);
    }
    auto results = scheduler_.run(id, tasks);
    for (size_t s = 0; s < results.size(); ++s) {
      if (!results[s]) continue;
      const auto& r = *results[s];
      int nv = tasks[s]->views_size();
      // The initial render's task returns the targets too; they are written once, with the final renders.
      for (int k = 0; k < r.renders_size() && k < (initial ? nv : 2 * nv); ++k) {
        bool ok = false;
        Image im = fromWire(r.renders(k), &ok);
        if (!ok) continue;
        std::string stem = (k < nv ? (initial ? "initial_view" : "final_view") : "target_view") + std::to_string(tasks[s]->views(k % nv));
        for (const char* ext : {".png", ".exr"}) {
          writeImage(dir / (stem + ext), im);
          files.push_back(stem + ext);
        }
      }
      // Variance-aware jobs: the per-pixel variance of one sample, as the job now samples.
      for (int k = 0; k < r.variances_size() && k < nv && !initial; ++k) {
        bool ok = false;
        Image im = fromWire(r.variances(k), &ok);
        if (!ok) continue;
        std::string name = "variance_view" + std::to_string(tasks[s]->views(k)) + ".exr";
        writeImage(dir / name, im);
        files.push_back(name);
      }
    }
  };
  renderAt(p.initial, true);
  renderAt(c.theta, false);
  for (auto& f : writeSelectionResults(dir, p.params, *p.scene, c.theta)) files.push_back(f);
  for (auto& f : snapshotFiles(dir)) files.push_back(std::move(f));
  copyLog(id, files);
  book_.end(id, v1::SUCCEEDED, "", &files);
}

}  // namespace invr::server
