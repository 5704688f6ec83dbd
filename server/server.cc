#include "server/server.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <spdlog/spdlog.h>

#include <fcntl.h>
#include <malloc.h>
#include <sys/file.h>
#include <unistd.h>

#include <atomic>
#include <thread>

#include "core/error.h"
#include "proto/wire/wire.h"
#include "server/admission.h"
#include "server/asset_store.h"
#include "server/auth.h"
#include "server/client_service.h"
#include "server/control_queue.h"
#include "server/dashboard.h"
#include "server/job_book.h"
#include "server/job_runner.h"
#include "server/job_store.h"
#include "server/metrics.h"
#include "server/scheduler.h"
#include "server/worker_service.h"

namespace invr::server {

namespace {
std::vector<NamedToken> clientTokensOf(const ServerOptions& o) {
  std::vector<NamedToken> all = o.clientTokens;
  if (!o.clientToken.empty()) all.push_back({"client", o.clientToken});
  return all;
}
}  // namespace

// The parts, each with one job (see their headers), wired together.
struct Server::Impl {
  ServerOptions opt;
  JobStore store;
  AssetStore assets;
  JobBook book;
  Scheduler scheduler;
  Admission admission;
  PreparedProblem prepared;
  Authenticator auth;
  std::atomic<bool> stopping{false};
  JobRunner runner;
  std::unique_ptr<ControlQueue> control;
  std::unique_ptr<ClientService> clientService;
  std::unique_ptr<WorkerService> workerService;
  std::unique_ptr<grpc::Server> grpcServer, healthServer;
  StepMetrics stepMetrics;
  std::unique_ptr<MetricsEndpoint> metrics;
  std::unique_ptr<Dashboard> dashboard;
  int healthPort = 0;
  std::vector<std::thread> runnerThreads;
  int storeLock = -1;  // flock on <store>/LOCK while this server runs

  explicit Impl(ServerOptions o)
      : opt(std::move(o)),
        store(opt.storeDir / "jobs"),
        assets(opt.storeDir / "assets"),
        book(store, opt.maxQueued),
        scheduler(SchedulerOptions{opt.leaseSeconds, opt.heartbeatTimeoutSeconds, opt.maxAttempts, opt.assignGraceSeconds}),
        admission(assets, opt.maxJobBytes, [this] { return scheduler.maxWorkerThreads(); }),
        auth(clientTokensOf(opt), opt.workerToken),
        runner(RunnerOptions{opt.finalSpp, opt.finalViews}, store, book, scheduler, admission, prepared, stopping) {}
  ~Impl() {
    if (storeLock >= 0) ::close(storeLock);
  }

  // Each runner thread runs one job at a time; together they run up to maxRunningJobs at once.
  void runnerLoop() {
    while (auto id = book.take()) {
      try {
        runner.run(*id);
      } catch (const std::exception& e) {  // only the store's disk can get here; the server stays up
        spdlog::error("[{}] {}", *id, e.what());
      }
    }
  }
};

Server::Server(ServerOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {}

Server::~Server() { shutdown(); }

namespace {

// TLS when a certificate is given; plaintext on loopback, or beyond it only when told so.
std::shared_ptr<grpc::ServerCredentials> credentials(const ServerOptions& o) {
  if (o.tlsCertPem.empty() != o.tlsKeyPem.empty()) throw InputError("--tls-cert and --tls-key go together (the server's certificate and its key)");
  if (!o.tlsClientCaPem.empty() && o.tlsCertPem.empty()) throw InputError("--tls-client-ca needs --tls-cert and --tls-key (mutual TLS is TLS)");
  for (const auto& c : clientTokensOf(o))
    if (!o.workerToken.empty() && c.token == o.workerToken)
      throw InputError("the client token '" + c.name + "' and the worker token are the same; a client could then connect workers");
  if (!o.tlsCertPem.empty()) {
    grpc::SslServerCredentialsOptions ssl(o.tlsClientCaPem.empty() ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                                                                  : GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
    ssl.pem_root_certs = o.tlsClientCaPem;
    ssl.pem_key_cert_pairs.push_back({o.tlsKeyPem, o.tlsCertPem});
    return grpc::SslServerCredentials(ssl);
  }
  if (!wire::isLoopbackAddress(o.address)) {
    if (!o.insecure)
      throw InputError("listening on " + o.address + " (not loopback) needs TLS (--tls-cert and --tls-key) or --insecure");
    spdlog::warn("listening on {} without TLS (--insecure): anyone on the network can read the traffic{}", o.address,
                 clientTokensOf(o).empty() || o.workerToken.empty() ? " and, without both tokens, use the service" : ", tokens included");
  }
  return grpc::InsecureServerCredentials();
}

}  // namespace

int Server::start() {
  Impl& s = *impl_;
  auto creds = credentials(s.opt);
  // Every step allocates and frees θ-sized buffers per shard (tasks, results, gradients). Keep
  // freed memory in the heap instead of returning it to the kernel and faulting it in again each
  // step (a tenth of the server's CPU at 64 workers); bounded by the trim threshold.
  mallopt(M_MMAP_THRESHOLD, 64 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
  // One server per store: a second one would split clients between two views of the same jobs.
  std::filesystem::create_directories(s.opt.storeDir);
  s.storeLock = ::open((s.opt.storeDir / "LOCK").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (s.storeLock < 0 || ::flock(s.storeLock, LOCK_EX | LOCK_NB) != 0)
    throw InputError("store '" + s.opt.storeDir.string() + "' is in use by another invr-server");
  s.book.load();
  s.control = std::make_unique<ControlQueue>();
  s.clientService =
      std::make_unique<ClientService>(s.book, s.admission, s.prepared, s.scheduler, s.assets, s.opt.maxAssetBytes, *s.control, s.auth);
  s.workerService = std::make_unique<WorkerService>(s.scheduler, s.assets, s.auth);
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder b;
  int port = 0;
  // Exclusive bind: without this gRPC sets SO_REUSEPORT, and a second server on the same port
  // would start and take half of the connections.
  b.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  b.AddListeningPort(s.opt.address, creds, &port);
  b.SetMaxReceiveMessageSize(wire::kMaxMessageBytes);
  b.SetMaxSendMessageSize(wire::kMaxMessageBytes);
  b.RegisterService(s.clientService.get());
  b.RegisterService(s.workerService.get());
  s.grpcServer = b.BuildAndStart();
  if (!s.grpcServer || port == 0)
    throw std::runtime_error("cannot listen on " + s.opt.address + " (address in use, perhaps by another invr-server, or not a local address)");
  if (!s.opt.healthAddress.empty()) {
    // Only the health service (every server has it): Kubernetes' gRPC probes speak plaintext.
    grpc::ServerBuilder hb;
    hb.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
    hb.AddListeningPort(s.opt.healthAddress, grpc::InsecureServerCredentials(), &s.healthPort);
    s.healthServer = hb.BuildAndStart();
    if (!s.healthServer || s.healthPort == 0) throw std::runtime_error("--health-address " + s.opt.healthAddress + ": cannot listen there");
  }
  if (!s.opt.metricsAddress.empty()) {
    s.runner.onStep = [&s](double seconds) { s.stepMetrics.stepDone(seconds); };
    s.metrics = std::make_unique<MetricsEndpoint>(s.opt.metricsAddress, [&s] {
      MetricsSnapshot m;
      auto n = s.book.countByState();
      m.queued = n[0], m.running = n[1], m.succeeded = n[2], m.failed = n[3], m.cancelled = n[4];
      auto c = s.scheduler.counts();
      m.workers = c.connected, m.busyWorkers = c.busy, m.workerThreads = c.threads;
      return s.stepMetrics.render(m);
    });
    spdlog::info("metrics on http://{}/metrics", s.opt.metricsAddress);
  }
  if (!s.opt.httpAddress.empty()) {
    s.dashboard = std::make_unique<Dashboard>(DashboardOptions{s.opt.httpAddress, s.opt.tlsCertPem, s.opt.tlsKeyPem, s.opt.insecure},
                                              s.book, s.scheduler, s.auth);
    spdlog::info("dashboard on {}", s.dashboard->url());
  }
  for (int i = 0; i < std::max(1, s.opt.maxRunningJobs); ++i) s.runnerThreads.emplace_back([&s] { s.runnerLoop(); });
  spdlog::info("invr-server listening on port {} ({}{}; store {}, up to {} jobs at once)", port, s.opt.tlsCertPem.empty() ? "plaintext" : "TLS",
               s.opt.tlsClientCaPem.empty() ? "" : " with client certificates",
               s.opt.storeDir.string(), s.opt.maxRunningJobs);
  if (s.auth.enabled(CallerRole::Client) || s.auth.enabled(CallerRole::Worker))
    spdlog::info("bearer tokens required: client API {}, worker API {}", s.auth.enabled(CallerRole::Client) ? "yes" : "no",
                 s.auth.enabled(CallerRole::Worker) ? "yes" : "no");
  return port;
}

void Server::shutdown() {
  if (!impl_ || !impl_->grpcServer) return;
  Impl& s = *impl_;
  if (s.stopping.exchange(true)) return;
  s.scheduler.stop();  // running jobs stop where they are (they resume on restart)
  s.book.stop();       // watchers end; runner threads take no new job
  for (auto& t : s.runnerThreads)
    if (t.joinable()) t.join();
  s.control->stop();
  s.metrics.reset();
  s.dashboard.reset();
  s.grpcServer->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
  if (s.healthServer) s.healthServer->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(1));
}

int Server::metricsPort() const { return impl_->metrics ? impl_->metrics->port() : 0; }
int Server::healthPort() const { return impl_->healthPort; }
std::string Server::dashboardUrl() const { return impl_->dashboard ? impl_->dashboard->url() : std::string(); }

void Server::wait() {
  if (impl_->grpcServer) impl_->grpcServer->Wait();
}

}  // namespace invr::server
