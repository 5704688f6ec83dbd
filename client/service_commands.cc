// invr run / submit / watch / status / list / cancel / fetch / plan: the service from the CLI.
// `invr run` without --server starts an embedded server and local worker processes.
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <random>
#include <sstream>
#include <thread>

#include "proto/wire/cli_checks.h"
#include "proto/wire/json_lines.h"
#include "client/common/bench_report.h"
#include "client/commands.h"
#include "client/common/embedded.h"
#include "client/common/exit_codes.h"
#include "client/common/job_argument.h"
#include "client/common/progress.h"
#include "client/common/service_client.h"
#include "core/job/memory_model.h"
#include "core/job/plan.h"
#include "core/job/scene_description.h"
#include "core/job/problem.h"
#include "client/common/figures.h"
#include "core/restir/reservoir_store.h"
#include "server/server.h"
#include "proto/wire/sha256.h"

#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/io/zero_copy_stream_impl_lite.h>
#include <google/protobuf/util/json_util.h>

namespace invr::cli {

namespace v1 = invr::v1;

namespace {

// A job's results, and the chart of its convergence CSV drawn here (the server writes the CSV;
// charts are the client's). A machine without matplotlib still gets every file the server has.
int fetchResults(ServiceClient& c, const std::string& job, const std::filesystem::path& dir) {
  int n = c.fetchAll(job, dir);
  const std::filesystem::path csv = dir / "convergence.csv";
  if (!std::filesystem::exists(csv)) return n;
  // Chart the parameter error; -1 when the job has none (no ground truth, or a start mesh): then
  // the shape error if the job has one, else the smoothed image loss (else the loss).
  std::string y = "loss";
  {
    std::ifstream in(csv);
    std::string header, row;
    std::getline(in, header);
    if (std::getline(in, row)) {
      auto cells = [](const std::string& line) {
        std::vector<std::string> out;
        std::stringstream ss(line);
        for (std::string c; std::getline(ss, c, ',');) out.push_back(c);
        return out;
      };
      const auto names = cells(header), values = cells(row);
      auto value = [&](const std::string& name) -> std::string {
        for (size_t i = 0; i < names.size() && i < values.size(); ++i)
          if (names[i] == name) return values[i];
        return "";
      };
      const std::string pe = value("param_error"), se = value("shape_error"), il = value("image_loss");
      if (!pe.empty() && pe[0] != '-') y = "param_error";
      else if (!se.empty() && se[0] != '-') y = "shape_error";
      else if (!il.empty()) y = "image_loss";
    }
  }
  try {
    drawConvergenceChart({csv}, dir / "convergence.png", "seconds", y);
    ++n;
  } catch (const std::exception& e) {
    std::cerr << "invr: no convergence chart: " << e.what() << "\n";
  }
  return n;
}


// Ctrl-C: a waiting thread turns SIGINT into a flag (gRPC calls are cancelled from threads, never
// from a signal handler). Call it before any gRPC object exists, so every thread gRPC starts
// inherits the blocked mask.
std::atomic<bool>& interruptFlag() {
  static std::atomic<bool> flag{false};
  static std::once_flag once;
  std::call_once(once, [] {
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    pthread_sigmask(SIG_BLOCK, &set, nullptr);
    std::thread([set]() mutable {
      for (;;) {
        int sig = 0;
        sigwait(&set, &sig);
        if (flag) _exit(130);  // a second Ctrl-C: leave now
        flag = true;
      }
    }).detach();
  });
  return flag;
}

// How the CLI reaches a server: TLS and token options, shared by every command with --server
// (one command runs per process).
struct ConnectionArgs {
  std::string ca, cert, key, serverName, tokenFile;
};
ConnectionArgs& connectionArgs() {
  static ConnectionArgs a;
  return a;
}

void addConnectionArgs(CLI::App* cmd) {
  ConnectionArgs& a = connectionArgs();
  cmd->add_option("--tls-ca", a.ca, "CA certificate (PEM) that signed the server's: connect over TLS");
  cmd->add_option("--tls-cert", a.cert, "client certificate (PEM) for a server that requires one (mutual TLS)");
  cmd->add_option("--tls-key", a.key, "the client certificate's private key (PEM)");
  cmd->add_option("--tls-server-name", a.serverName, "name expected in the server's certificate (default: the host of --server)");
  cmd->add_option("--token-file", a.tokenFile, "file holding the server's client token (default: $INVR_TOKEN)");
}

std::string defaultServerAddress() {
  const char* env = std::getenv("INVR_SERVER");
  return env && *env ? std::string(env) : std::string("127.0.0.1:50051");
}

ServiceClient connect(const std::string& server) {
  const ConnectionArgs& a = connectionArgs();
  wire::ClientSecurity sec;
  try {
    sec = wire::loadClientSecurity(a.ca, a.cert, a.key, a.serverName, a.tokenFile, "INVR_TOKEN");
  } catch (const std::runtime_error& e) {
    throw InputError(e.what());
  }
  return ServiceClient(server, std::move(sec));
}

struct JobArgs {
  std::string job;
  int steps = 0;
  std::string method;
  int targetSpp = 0;
  int priority = 0, maxWorkers = -1;
  int snapshotEvery = 0;
  SceneArgs sceneArgs;
};

void addJobArgs(CLI::App* cmd, JobArgs& a) {
  cmd->add_option("job", a.job, "zoo scene name (its built-in job), job file (.json) or Mitsuba 3 scene (.xml, with --param)")->required();
  cmd->add_option("--steps", a.steps, "override the number of steps")->check(invr::wire::kPositive);
  cmd->add_option("--method", a.method, "override the gradient method")->check(CLI::IsMember({"pt", "ris", "restir"}));
  cmd->add_option("--target-spp", a.targetSpp, "override the samples per pixel of rendered targets")->check(invr::wire::kPositive);
  cmd->add_option("--snapshot-every", a.snapshotEvery,
                  "optimization.snapshot_every: every N steps, write renders of the first views and the parameters under the "
                  "results' snapshots/ folder (snapshots/step<k>_view<v>.png, snapshots/step<k>/parameters.json)")
      ->check(invr::wire::kPositive);
  cmd->add_option("--priority", a.priority,
                  "scheduling.priority: the job's weight in the share of worker time among jobs running at once (1..100; default 1)")
      ->check(CLI::Range(1, 100));
  cmd->add_option("--max-workers", a.maxWorkers, "scheduling.max_workers: at most this many workers hold the job's shards (0: no cap)")
      ->check(CLI::Range(0, 4096));
  addSceneArgs(cmd, a.sceneArgs, true);
}

// The job from its argument with overrides applied; baseDir for its relative asset paths. With
// `server`, the server resolves it (ResolveJob, as Python's client does) and the spec names every
// file by content; without, it is resolved here with the same code.
v1::JobSpec loadJob(const JobArgs& a, std::filesystem::path& baseDir, ServiceClient* server = nullptr) {
  AssetResolver assets;
  v1::JobSpec job = server ? server->resolve(a.job, a.sceneArgs.defines, a.sceneArgs.params, a.sceneArgs.sets, true)
                           : optimizationJobFromArgument(a.job, assets, a.sceneArgs);
  baseDir = assets.baseDir;
  if (a.steps > 0) job.mutable_optimization()->set_steps(a.steps);
  if (a.targetSpp > 0) job.mutable_optimization()->set_target_spp(a.targetSpp);
  if (a.snapshotEvery > 0) job.mutable_optimization()->set_snapshot_every(a.snapshotEvery);
  if (a.priority > 0) job.mutable_scheduling()->set_priority(uint32_t(a.priority));
  if (a.maxWorkers >= 0) job.mutable_scheduling()->set_max_workers(uint32_t(a.maxWorkers));
  if (a.method == "pt") job.mutable_optimization()->set_method(v1::METHOD_PT);
  if (a.method == "ris") job.mutable_optimization()->set_method(v1::METHOD_RIS);
  if (a.method == "restir") job.mutable_optimization()->set_method(v1::METHOD_RESTIR);
  if (job.name().empty()) job.set_name(std::filesystem::path(a.job).stem().string());
  return job;
}

std::string randomRequestId() {
  std::random_device rd;
  std::ostringstream s;
  s << std::hex << rd() << rd() << rd() << rd();
  return s.str();
}

// Prints events: a progress bar on a terminal, plain lines otherwise, JSON lines with --json.
class EventPrinter {
 public:
  explicit EventPrinter(bool json) : json_(json), tty_(isatty(fileno(stderr)) != 0), bar_("optimize") {}
  void operator()(const v1::ProgressEvent& e) {
    if (json_) {
      std::cout << eventJson(e) << std::endl;
      return;
    }
    if (e.has_step()) {
      const auto& s = e.step();
      char detail[160];
      std::snprintf(detail, sizeof detail, "step %llu/%llu  loss %.4g  image_loss %.4g%s  eta %.0f s", (unsigned long long)s.step(),
                    (unsigned long long)s.steps(), s.loss(), s.image_loss(),
                    s.param_error() >= 0 ? ("  param_error " + std::to_string(s.param_error()).substr(0, 8)).c_str() : "", s.eta_seconds());
      bar_.update(s.steps() ? double(s.step()) / double(s.steps()) : 0.0, detail);
      uint64_t every = std::max<uint64_t>(1, s.steps() / 20);
      if (!tty_ && (s.step() % every == 0 || s.step() == s.steps())) std::cout << describeEvent(e) << std::endl;
      lastStep_ = e.step();
      return;
    }
    if (tty_) std::cerr << "\r\033[K";
    std::cout << describeEvent(e) << std::endl;
  }
  void finish() {
    if (!json_) bar_.finish();
  }
  const v1::StepProgress& lastStep() const { return lastStep_; }

 private:
  bool json_, tty_;
  ProgressBar bar_;
  v1::StepProgress lastStep_;
};

// Watches to the end; returns the exit code. Ctrl-C stops watching only.
int watchToEnd(ServiceClient& c, const std::string& id, uint64_t from, bool json, const std::string& resumeHint) {
  EventPrinter print(json);
  auto final = c.watch(id, from, [&](const v1::ProgressEvent& e) { print(e); }, interruptFlag());
  print.finish();
  if (!final) {
    std::cerr << "invr: stopped watching; " << resumeHint << "\n";
    return exit_code::kInterrupted;
  }
  if (final->state() != v1::SUCCEEDED)
    std::cerr << "invr: job " << id << " " << v1::JobState_Name(final->state()) << ": " << final->reason() << "\n";
  return exitCodeFor(final->state());
}

std::string where(const std::filesystem::path& dir) { return std::filesystem::absolute(dir).lexically_normal().string(); }

// ------------------------------------------------------------------------------- plan

// The threads each local worker of `invr run` gets on this machine (see runJob).
unsigned embeddedWorkerThreads(size_t shards, int workersAsked) {
  int cores = int(std::max(1u, std::thread::hardware_concurrency()));
  int workers = workersAsked > 0 ? workersAsked : std::max(2, cores);
  int busy = std::min<int>(workers, int(shards));
  return unsigned(std::max(1, cores / std::max(1, busy)));
}

// Without a server: the plan for `invr run`'s local workers on this machine. With one: the
// server's answer (the same validation as a submission, memory for its workers' threads).
void printPlan(v1::JobSpec job, const std::filesystem::path& baseDir, const std::string& server, bool json) {
  v1::JobPlan plan;
  if (!server.empty()) {
    ServiceClient c = connect(server);
    c.uploadAssets(job, baseDir);
    plan = c.plan(job);
  } else {
    AssetResolver assets;
    assets.baseDir = baseDir;
    Problem p = buildProblem(job, assets, SceneUse::Validate);
    plan = planJob(job, p, embeddedWorkerThreads(p.shards.size(), 0));
  }
  if (json)
    std::cout << wire::jsonLine(plan) << "\n";
  else
    std::cout << plan.text();
}

// ------------------------------------------------------------------------------- params

// A scene's optimisable names: asked of the server with --server, else built here.
void printParams(v1::JobSpec job, const std::filesystem::path& baseDir, const std::string& server, bool json) {
  v1::SceneDescription desc;
  if (!server.empty()) {
    ServiceClient c = connect(server);
    c.uploadAssets(job, baseDir);
    desc = c.describe(job);
  } else {
    AssetResolver assets;
    assets.baseDir = baseDir;
    std::unique_ptr<Scene> scene = buildJobScene(job, assets, SceneUse::Validate);
    desc = describeScene(*scene);
  }
  if (json) {
    std::cout << wire::jsonLine(desc) << "\n";
    return;
  }
  size_t width = 0;
  for (const auto& p : desc.parameters()) width = std::max(width, p.name().size());
  for (const auto& p : desc.parameters()) {
    std::ostringstream line;
    line << p.name() << std::string(width + 2 - p.name().size(), ' ') << p.kind() << ", " << p.size() << " value(s)";
    if (p.width() > 0) line << " (" << p.width() << "x" << p.height() << "x" << p.channels() << ")";
    line << ", bounds [" << p.lower() << ", " << p.upper() << "]"
         << ", learning rate " << p.learning_rate();
    if (p.aliases_size() > 0) {
      line << "; Mitsuba:";
      for (const auto& a : p.aliases()) line << " " << a;
    }
    std::cout << line.str() << "\n";
  }
}

// ------------------------------------------------------------------------------- embedded

struct RunArgs : JobArgs {
  std::string out = "out/run";
  std::string server;
  std::string store;
  int workers = 0;
  bool json = false;
  bool verbose = false;
  std::string httpAddress;
  int finalSpp = 64;
};

int runJob(const RunArgs& a) {
  interruptFlag();
  std::filesystem::path baseDir;
  std::filesystem::path out(a.out);
  if (!a.server.empty() && !a.httpAddress.empty())
    throw InputError("--http-address is the embedded server's dashboard; a running server has its own (invr-server --http-address)");
  if (!a.server.empty() && a.finalSpp != 64)
    throw InputError("--final-spp is the embedded server's; a running server has its own (invr-server --final-spp)");
  if (!a.server.empty()) {  // against a running server: resolve, submit, watch, fetch
    ServiceClient c = connect(a.server);
    v1::JobSpec job = loadJob(a, baseDir, &c);
    auto r = c.submit(job, randomRequestId());
    (a.json ? std::cerr : std::cout) << "submitted " << r.job_id() << " to " << a.server << "\n";
    int code = watchToEnd(c, r.job_id(), 0, a.json, "the job goes on: invr watch " + r.job_id() + " --server " + a.server);
    if (code == exit_code::kOk || code == exit_code::kJobFailed) {
      int n = fetchResults(c, r.job_id(), out);
      (a.json ? std::cerr : std::cout) << "wrote " << n << " file(s) to " << where(out) << "\n";
    }
    return code;
  }

  // Embedded: a server in this process and local worker processes.
  v1::JobSpec job = loadJob(a, baseDir);
  AssetResolver localAssets;
  localAssets.baseDir = baseDir;
  // Fail fast, with the file's own paths in errors; no BVH: this process never traces a ray.
  Problem probe = buildProblem(job, localAssets, SceneUse::Validate);
  int cores = int(std::max(1u, std::thread::hardware_concurrency()));
  int workers = a.workers > 0 ? a.workers : std::max(2, cores);
  int threads = int(embeddedWorkerThreads(probe.shards.size(), a.workers));
  bool tempStore = a.store.empty();
  std::filesystem::path store = tempStore ? std::filesystem::temp_directory_path() / ("invr-run-" + std::to_string(getpid())) : std::filesystem::path(a.store);
  std::filesystem::create_directories(store);
  struct RemoveStore {
    std::filesystem::path dir;
    ~RemoveStore() {
      std::error_code ec;
      if (!dir.empty()) std::filesystem::remove_all(dir, ec);
    }
  } removeStore{tempStore ? store : std::filesystem::path()};
  // Worker trouble reaches the user as progress events; the log is for --verbose.
  if (!a.verbose) spdlog::set_level(spdlog::level::err);
  EmbeddedService service(store, workers, threads, a.httpAddress, a.finalSpp);
  ServiceClient& c = service.client();
  c.uploadAssets(job, baseDir);
  // The request id is the job's content: with a kept --store, running the same job again
  // resumes it (or returns its results) instead of starting over.
  std::string bytes;
  google::protobuf::io::StringOutputStream sos(&bytes);
  {
    google::protobuf::io::CodedOutputStream cos(&sos);
    cos.SetSerializationDeterministic(true);
    job.SerializeToCodedStream(&cos);
  }
  server::Sha256 h;
  h.update(bytes.data(), bytes.size());
  auto r = c.submit(job, "run-" + h.hex());
  if (!a.json)
    std::cout << "invr run: " << job.name() << " as " << r.job_id() << (r.existing() ? " (resumed)" : "") << " on an embedded server with "
              << workers << " local worker(s) x " << threads << " thread(s)\n";
  if (!a.json && !service.dashboardUrl().empty()) std::cout << "invr run: dashboard at " << service.dashboardUrl() << "\n";
  int code = watchToEnd(c, r.job_id(), 0, a.json,
                        tempStore ? "the embedded server stops with this command (use --store DIR to keep and resume jobs)"
                                  : "the job resumes when you run the same command again");
  if (code == exit_code::kOk || code == exit_code::kJobFailed) {
    int n = fetchResults(c, r.job_id(), out);
    v1::JobStatus st = c.get(r.job_id());
    if (!a.json) {
      if (st.state() == v1::SUCCEEDED) {
        std::cout << "done: " << st.step() << " steps in " << st.seconds() << " s, loss " << st.loss();
        if (st.param_error() >= 0) std::cout << ", parameter error " << parameterError(probe, probe.initial) << " -> " << st.param_error();
        std::cout << "\n";
      }
      std::cout << "wrote " << n << " file(s) to " << where(out) << " (parameters.json, job.json, convergence.csv and .png, initial/final/target renders, progress.jsonl"
                << (std::filesystem::exists(std::filesystem::path(out) / "snapshots") ? ", snapshots/" : "") << ")\n";
    }
  }
  service.stop();
  return code;
}

}  // namespace

void addServiceCommands(CLI::App& app, int& exitCode) {
  auto run = std::make_shared<RunArgs>();
  auto* r = app.add_subcommand("run", "Run an optimisation job: on an embedded server with local workers, or on --server");
  addJobArgs(r, *run);
  r->add_option("-o,--out", run->out, "folder for the results")->capture_default_str();
  r->add_option("--server", run->server, "host:port of a running invr-server (default: embedded)");
  addConnectionArgs(r);
  r->add_option("--workers", run->workers, "local worker processes (embedded; default one per core, at least 2)")->check(invr::wire::kPositive);
  r->add_option("--store", run->store, "keep the embedded server's job store here (an interrupted run resumes)");
  r->add_flag("--json", run->json, "one JSON object per progress event on stdout");
  r->add_flag("-v,--verbose", run->verbose, "the embedded server's log on stderr");
  r->add_option("--http-address", run->httpAddress,
                "embedded: the server's dashboard at http://HOST:PORT/ while the job runs (a port alone: 127.0.0.1; docs/dashboard.md)");
  r->add_option("--final-spp", run->finalSpp, "embedded: samples per pixel of the final (and initial) renders written with the results")
      ->check(invr::wire::kPositive)
      ->capture_default_str();
  r->callback([run, &exitCode] { exitCode = runJob(*run); });

  auto serverOpt = [](CLI::App* cmd, std::string& s) {
    cmd->add_option("--server", s, "host:port of the invr-server (default: $INVR_SERVER, else 127.0.0.1:50051)")
        ->default_str(defaultServerAddress());
    s = defaultServerAddress();
    addConnectionArgs(cmd);
  };

  auto sub = std::make_shared<RunArgs>();
  auto requestId = std::make_shared<std::string>();
  auto* s = app.add_subcommand("submit", "Submit a job to a server; prints its id");
  addJobArgs(s, *sub);
  serverOpt(s, sub->server);
  s->add_option("--request-id", *requestId, "makes a retried submission idempotent (default: random)");
  s->callback([sub, requestId, &exitCode] {
    std::filesystem::path baseDir;
    ServiceClient c = connect(sub->server);
    v1::JobSpec job = loadJob(*sub, baseDir, &c);
    auto resp = c.submit(job, requestId->empty() ? randomRequestId() : *requestId);
    std::cout << resp.job_id() << "\n";
    exitCode = exit_code::kOk;
  });

  struct IdArgs {
    std::string id, server, out = "out/fetch";
    uint64_t from = 0;
    bool json = false;
    double reconnect = 60;
  };
  auto w = std::make_shared<IdArgs>();
  auto* wc = app.add_subcommand("watch", "Stream a job's progress until it ends (Ctrl-C stops watching, not the job)");
  wc->add_option("job_id", w->id)->required();
  serverOpt(wc, w->server);
  wc->add_option("--from", w->from, "resume from this event sequence number");
  wc->add_flag("--json", w->json, "one JSON object per event");
  wc->add_option("--reconnect-timeout", w->reconnect, "seconds to wait for the server to come back if the stream breaks (a restart)")
      ->capture_default_str()
      ->check(invr::wire::kNonNegative);
  wc->callback([w, &exitCode] {
    interruptFlag();
    ServiceClient c = connect(w->server);
    c.setReconnectSeconds(w->reconnect);
    exitCode = watchToEnd(c, w->id, w->from, w->json, "the job goes on: invr watch " + w->id + " --server " + w->server);
  });

  auto st = std::make_shared<IdArgs>();
  auto* sc = app.add_subcommand("status", "A job's state (exit code 0 running/succeeded, 4 failed, 6 cancelled)");
  sc->add_option("job_id", st->id)->required();
  serverOpt(sc, st->server);
  sc->add_flag("--json", st->json, "as JSON");
  sc->callback([st, &exitCode] {
    ServiceClient c = connect(st->server);
    v1::JobStatus s = c.get(st->id);
    if (st->json) {
      std::cout << wire::jsonLine(s) << "\n";
    } else {
      std::cout << s.job_id() << "  " << v1::JobState_Name(s.state()) << "  step " << s.step() << "/" << s.steps() << "  loss " << s.loss();
      if (s.param_error() >= 0) std::cout << "  param_error " << s.param_error();
      std::cout << "  " << s.seconds() << " s";
      std::cout << "  priority " << s.priority() << "  worker time " << s.worker_seconds() << " s";
      if (s.state() == v1::RUNNING) std::cout << " on " << s.workers() << " worker(s)";
      if (!s.submitted_by().empty()) std::cout << "  submitted by " << s.submitted_by();
      if (!s.reason().empty()) std::cout << "\n  reason: " << s.reason();
      std::cout << "\n";
    }
    exitCode = (s.state() == v1::FAILED || s.state() == v1::CANCELLED) ? exitCodeFor(s.state()) : exit_code::kOk;
  });

  auto ls = std::make_shared<IdArgs>();
  auto* lc = app.add_subcommand("list", "List the server's jobs");
  serverOpt(lc, ls->server);
  lc->add_flag("--json", ls->json, "the ListJobsResponse as one JSON object ({\"jobs\": [...]}, numbers as numbers)");
  lc->callback([ls, &exitCode] {
    ServiceClient c = connect(ls->server);
    const v1::ListJobsResponse all = c.list();
    exitCode = exit_code::kOk;
    if (ls->json) {
      std::cout << wire::jsonLine(all) << "\n";
      return;
    }
    for (const auto& j : all.jobs())
      std::cout << j.job_id() << "  " << v1::JobState_Name(j.state()) << "  " << j.name() << "  step " << j.step() << "/" << j.steps()
                << "  priority " << j.priority() << (j.submitted_by().empty() ? "" : "  by " + j.submitted_by()) << "\n";
    exitCode = exit_code::kOk;
  });

  auto cn = std::make_shared<IdArgs>();
  auto* cc = app.add_subcommand("cancel", "Cancel a job (idempotent)");
  cc->add_option("job_id", cn->id)->required();
  serverOpt(cc, cn->server);
  cc->callback([cn, &exitCode] {
    ServiceClient c = connect(cn->server);
    v1::JobStatus s = c.cancel(cn->id);
    std::cout << s.job_id() << "  " << v1::JobState_Name(s.state()) << (s.state() == v1::RUNNING ? " (stopping)" : "") << "\n";
    exitCode = exit_code::kOk;
  });

  auto fe = std::make_shared<IdArgs>();
  auto* fc = app.add_subcommand("fetch", "Download a job's results (parameters, renders, convergence CSV, progress log)");
  fc->add_option("job_id", fe->id)->required();
  serverOpt(fc, fe->server);
  fc->add_option("-o,--out", fe->out, "folder")->capture_default_str();
  fc->callback([fe, &exitCode] {
    ServiceClient c = connect(fe->server);
    int n = fetchResults(c, fe->id, fe->out);
    std::cout << "wrote " << n << " file(s) to " << where(fe->out) << "\n";
    exitCode = exit_code::kOk;
  });

  auto wk = std::make_shared<IdArgs>();
  auto* wkc = app.add_subcommand("workers", "List the workers connected to a server");
  serverOpt(wkc, wk->server);
  wkc->add_flag("--json", wk->json, "the ListWorkersResponse as one JSON object ({\"workers\": [...]})");
  wkc->callback([wk, &exitCode] {
    ServiceClient c = connect(wk->server);
    const v1::ListWorkersResponse all = c.workers();
    exitCode = exit_code::kOk;
    if (wk->json) {
      std::cout << wire::jsonLine(all) << "\n";
      return;
    }
    for (const auto& w : all.workers())
      std::cout << w.name() << "  " << w.capacity() << " thread(s)  " << w.shards() << " shard(s) of " << w.jobs() << " job(s)"
                << (w.busy() ? "  busy" : "  idle") << (w.leaving() ? "  leaving" : "") << "\n";
    exitCode = exit_code::kOk;
  });

  struct ChartArgs {
    std::vector<std::string> inputs;
    std::string out = "chart.png", x = "seconds", y = "param_error", title, server;
  };
  auto ch = std::make_shared<ChartArgs>();
  auto* chc = app.add_subcommand("chart", "Chart convergence CSVs, job output folders or jobs on a server (log-scale error against time or steps)");
  chc->add_option("runs", ch->inputs, "convergence.csv files, folders holding one (from run, fetch, optimize, eval), or job ids on --server")
      ->required();
  chc->add_option("-o,--out", ch->out, "chart file (.png or .svg)")->capture_default_str();
  chc->add_option("--x", ch->x, "x axis")->check(CLI::IsMember({"seconds", "step", "steps"}))->capture_default_str();
  chc->add_option("--y", ch->y,
                  "y axis (image_error: CSVs from invr-lab eval and bench reconstruct; image_loss: the smoothed one-render loss of run, "
                  "fetch and optimize)")
      ->check(CLI::IsMember({"param_error", "loss", "image_error", "shape_error", "image_loss"}))
      ->capture_default_str();
  chc->add_option("--title", ch->title, "chart title");
  serverOpt(chc, ch->server);
  chc->callback([ch, &exitCode] {
    std::vector<std::filesystem::path> csvs;
    std::filesystem::path fetched;  // jobs' CSVs, downloaded into a folder per job id
    for (const auto& in : ch->inputs) {
      std::filesystem::path p(in);
      if (!std::filesystem::exists(p) && in.rfind("job-", 0) == 0 && in.find('/') == std::string::npos) {
        if (fetched.empty()) fetched = std::filesystem::temp_directory_path() / ("invr-chart-" + std::to_string(getpid()));
        connect(ch->server).fetchOne(in, "convergence.csv", fetched / in);
        csvs.push_back(fetched / in / "convergence.csv");
        continue;
      }
      if (std::filesystem::is_directory(p)) p /= "convergence.csv";
      if (!std::filesystem::exists(p)) throw InputError("'" + p.string() + "': not found (a CSV, a folder holding convergence.csv, or a job id)");
      csvs.push_back(p);
    }
    std::string x = ch->x == "steps" ? "step" : ch->x;
    try {
      drawConvergenceChart(csvs, ch->out, x, ch->y, ch->title);
    } catch (...) {
      if (!fetched.empty()) std::filesystem::remove_all(fetched);
      throw;
    }
    if (!fetched.empty()) std::filesystem::remove_all(fetched);
    std::cout << "wrote " << where(ch->out) << "\n";
    exitCode = exit_code::kOk;
  });

  struct ParamsArgs {
    std::string scene, server;
    SceneArgs sceneArgs;
    bool json = false;
  };
  auto pa = std::make_shared<ParamsArgs>();
  auto* pac = app.add_subcommand("params", "List the names a job may optimise in a scene (sizes, bounds, learning rates, Mitsuba names)");
  pac->add_option("scene", pa->scene, "zoo scene name, job file (.json), Mitsuba 3 scene (.xml) or - (job JSON on standard input)")->required();
  addSceneArgs(pac, pa->sceneArgs, false);
  pac->add_option("--server", pa->server, "ask this server (DescribeScene) instead of building the scene here");
  addConnectionArgs(pac);
  pac->add_flag("--json", pa->json, "the SceneDescription (service.proto) as one JSON object: {\"parameters\": [...]}");
  pac->callback([pa, &exitCode] {
    AssetResolver assets;
    v1::JobSpec job;
    if (!pa->server.empty()) {  // resolved by the server, which then describes it
      ServiceClient c = connect(pa->server);
      job = c.resolve(pa->scene, pa->sceneArgs.defines, {}, pa->sceneArgs.sets, false);
    } else {
      job = jobFromArgument(pa->scene, assets, pa->sceneArgs);
    }
    printParams(job, assets.baseDir, pa->server, pa->json);
    exitCode = exit_code::kOk;
  });

  struct PlanArgs : JobArgs {
    std::string server;
    bool json = false;
  };
  auto pl = std::make_shared<PlanArgs>();
  auto* pc = app.add_subcommand("plan", "Print what a job will compute (estimators, parameters, memory) without running it");
  addJobArgs(pc, *pl);
  pc->add_option("--server", pl->server,
                 "ask this server (validated as a submission would be; memory for its workers' threads); without it, the plan for "
                 "`invr run`'s local workers on this machine");
  addConnectionArgs(pc);
  pc->add_flag("--json", pl->json, "the JobPlan (service.proto) as one JSON object");
  pc->callback([pl, &exitCode] {
    std::filesystem::path baseDir;
    v1::JobSpec job;
    if (!pl->server.empty()) {
      ServiceClient c = connect(pl->server);
      job = loadJob(*pl, baseDir, &c);
    } else {
      job = loadJob(*pl, baseDir);
    }
    printPlan(job, baseDir, pl->server, pl->json);
    exitCode = exit_code::kOk;
  });
}

}  // namespace invr::cli
