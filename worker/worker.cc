#include "worker/worker.h"

#include <spdlog/spdlog.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "core/job/problem.h"
#include "core/error.h"
#include "core/render/renderer.h"
#include "invr/v1/service.grpc.pb.h"
#include "proto/wire/sha256.h"
#include "proto/wire/wire.h"

namespace invr::worker {

namespace v1 = invr::v1;
using Clock = std::chrono::steady_clock;

namespace {

double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Resident memory of this process, from /proc.
double residentMb() {
  std::ifstream in("/proc/self/statm");
  double pages = 0, resident = 0;
  in >> pages >> resident;
  return resident * double(sysconf(_SC_PAGESIZE)) / 1048576.0;
}

// One shard of one job, alive across steps: this is what makes reservoirs persist.
struct Session {
  std::unique_ptr<Problem> problem;
  std::vector<Image> targets;  // the shard's views; others empty
  std::unique_ptr<GradientEngine> engine;
  EngineSession state;
  uint64_t lastUse = 0;
};

void toProto(const Image& im, v1::FloatImage* out) {
  out->set_width(im.width());
  out->set_height(im.height());
  out->set_channels(im.channels());
  out->mutable_pixels()->Assign(im.data().begin(), im.data().end());
}

class Worker {
 public:
  Worker(const WorkerOptions& o, const std::atomic<bool>& stop) : opt_(o), stop_(stop) {
    if (opt_.name.empty()) {
      char host[256] = {0};
      gethostname(host, sizeof host - 1);
      opt_.name = std::string(host) + ":" + std::to_string(getpid());
    }
    if (opt_.cacheDir.empty()) opt_.cacheDir = std::filesystem::temp_directory_path() / ("invr-worker-" + std::to_string(getpid()));
    std::filesystem::create_directories(opt_.cacheDir);
    memoryLimitMb_ = opt_.maxMemoryMb > 0 ? opt_.maxMemoryMb
                                          : 0.5 * double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGESIZE)) / 1048576.0;
  }

  int run() {
    double backoff = 0.1;
    while (!shouldStop()) {
      bool served = serveOnce();
      if (shouldStop()) break;
      if (!refusal_.ok()) {  // wrong credentials do not fix themselves: say so and stop
        spdlog::error("worker {}: the server refused this worker: {} ({}); check --token-file / $INVR_WORKER_TOKEN and the TLS options",
                      opt_.name, refusal_.error_message(), refusal_.error_code() == grpc::StatusCode::PERMISSION_DENIED ? "PERMISSION_DENIED" : "UNAUTHENTICATED");
        std::error_code ec;
        std::filesystem::remove_all(opt_.cacheDir, ec);
        return kExitRefused;
      }
      if (served) backoff = 0.1;
      // The server went away (or never answered): sessions may belong to a server that no longer
      // exists, so drop them; a reassigned shard is rebuilt with a burn-in.
      sessions_.clear();
      specs_.clear();
      specOfJob_.clear();
      std::this_thread::sleep_for(std::chrono::duration<double>(backoff));
      backoff = std::min(backoff * 2, 2.0);
    }
    std::error_code ec;
    std::filesystem::remove_all(opt_.cacheDir, ec);
    spdlog::info("worker {}: stopped", opt_.name);
    return 0;
  }

 private:
  void noteRefusal(const grpc::Status& st) {
    if (st.error_code() == grpc::StatusCode::UNAUTHENTICATED || st.error_code() == grpc::StatusCode::PERMISSION_DENIED) refusal_ = st;
  }
  grpc::Status refusal_ = grpc::Status::OK;

  bool shouldStop() const { return stop_.load() || (opt_.parentPid && getppid() != opt_.parentPid); }

  // One connection. Returns true if it got as far as the server's welcome.
  bool serveOnce() {
    auto channel = wire::channel(opt_.server, opt_.security);
    auto stub = v1::WorkerService::NewStub(channel);
    grpc::ClientContext ctx;
    wire::addToken(ctx, opt_.security);
    auto stream = stub->Connect(&ctx);
    std::mutex wmu;
    auto write = [&](const v1::WorkerMessage& m) {
      std::lock_guard<std::mutex> lk(wmu);
      return stream->Write(m);
    };
    v1::WorkerMessage hello;
    hello.mutable_hello()->set_name(opt_.name);
    hello.mutable_hello()->set_capacity(uint32_t(opt_.threads > 0 ? opt_.threads : int(std::thread::hardware_concurrency())));
    if (!write(hello)) {
      noteRefusal(stream->Finish());
      return false;
    }
    std::mutex mu;
    std::condition_variable cv;
    std::deque<v1::ServerMessage> inbox;
    bool connected = true, welcomed = false;
    std::atomic<uint64_t> busy{0};
    std::string busyJob;
    std::thread reader([&] {
      v1::ServerMessage m;
      while (stream->Read(&m)) {
        std::lock_guard<std::mutex> lk(mu);
        if (m.has_welcome()) {
          welcomed = true;
          spdlog::info("worker {}: connected to {} as worker {}", opt_.name, opt_.server, m.welcome());
          continue;
        }
        // A job that ended (or was cancelled) stops its task in hand.
        if (m.has_release_job()) {
          if (busy.load() && busyJob == m.release_job()) cancel_ = true;
          // Tasks of the ended job still waiting here are dropped too.
          inbox.erase(std::remove_if(inbox.begin(), inbox.end(),
                                     [&](const v1::ServerMessage& q) { return q.has_task() && q.task().job_id() == m.release_job(); }),
                      inbox.end());
        }
        inbox.push_back(m);
        cv.notify_all();
      }
      std::lock_guard<std::mutex> lk(mu);
      connected = false;
      cv.notify_all();
    });
    std::thread heart([&] {
      std::unique_lock<std::mutex> lk(mu);
      std::optional<std::chrono::steady_clock::time_point> stopSince;
      while (connected) {
        cv.wait_for(lk, std::chrono::duration<double>(stopSince ? std::min(0.2, opt_.heartbeatSeconds) : opt_.heartbeatSeconds));
        if (!connected) break;
        if (shouldStop()) {
          // SIGTERM: tell the server at once (no new task comes), finish the task in hand if it
          // ends within the drain time, else hand it back (the server reassigns it).
          if (!stopSince) {
            stopSince = std::chrono::steady_clock::now();
            v1::WorkerMessage bye;
            bye.set_leaving(true);
            lk.unlock();
            write(bye);
            lk.lock();
            spdlog::info("worker {}: stopping; the task in hand has {:g} s to finish", opt_.name, opt_.drainSeconds);
          }
          if (!busy.load()) break;
          if (!cancel_ && std::chrono::duration<double>(std::chrono::steady_clock::now() - *stopSince).count() > opt_.drainSeconds) {
            spdlog::info("worker {}: handing task {} back to the server", opt_.name, busy.load());
            cancel_ = true;
          }
        }
        v1::WorkerMessage hb;
        hb.mutable_heartbeat()->set_busy_task(busy.load());
        lk.unlock();
        write(hb);
        lk.lock();
      }
    });
    for (;;) {
      v1::ServerMessage m;
      {
        std::unique_lock<std::mutex> lk(mu);
        cv.wait_for(lk, std::chrono::milliseconds(200), [&] { return !inbox.empty() || !connected; });
        if (!connected || shouldStop()) break;
        if (inbox.empty()) continue;
        m = std::move(inbox.front());
        inbox.pop_front();
        if (m.has_task()) {
          busy = m.task().task_id();
          busyJob = m.task().job_id();
          cancel_ = false;
        }
      }
      if (m.has_release_job()) {
        release(m.release_job());
      } else if (m.has_task()) {
        std::optional<v1::WorkerMessage> out = execute(m.task());
        busy = 0;
        if (out) write(*out);
      }
    }
    if (shouldStop()) {
      v1::WorkerMessage bye;
      bye.set_leaving(true);
      write(bye);
      std::lock_guard<std::mutex> lk(wmu);
      stream->WritesDone();
    }
    {
      // The server ended the stream (its status is then what Finish reports, e.g. a refusal), or
      // we are leaving: cancel to unblock the reader.
      std::lock_guard<std::mutex> lk(mu);
      if (connected) ctx.TryCancel();
      connected = false;
      cv.notify_all();
    }
    reader.join();
    heart.join();
    noteRefusal(stream->Finish());
    return welcomed;
  }

  void release(const std::string& job) {
    for (auto it = sessions_.begin(); it != sessions_.end();)
      it = it->first.first == job ? sessions_.erase(it) : std::next(it);
    auto h = specOfJob_.find(job);
    if (h != specOfJob_.end()) {
      specs_.erase(h->second);
      specOfJob_.erase(h);
    }
  }

  // The task's job spec: sent whole with a job's first task on this connection, by hash after.
  // Null when the worker does not hold it (the server then sends it again).
  const v1::JobSpec* specFor(const v1::Task& t) {
    if (t.has_spec()) {
      specOfJob_[t.job_id()] = t.spec_sha256();
      return &(specs_[t.spec_sha256()] = t.spec());
    }
    auto it = specs_.find(t.spec_sha256());
    return it == specs_.end() ? nullptr : &it->second;
  }

  AssetResolver resolver() {
    AssetResolver r;
    r.byHash = [this](const std::string& h) { return fetchAsset(h); };
    return r;
  }

  std::filesystem::path fetchAsset(const std::string& hash) {
    std::filesystem::path path = opt_.cacheDir / hash;
    if (std::filesystem::exists(path)) return path;
    auto stub = v1::WorkerService::NewStub(wire::channel(opt_.server, opt_.security));
    grpc::ClientContext ctx;
    wire::addToken(ctx, opt_.security);
    v1::FetchAssetRequest req;
    req.set_sha256(hash);
    auto reader = stub->FetchAsset(&ctx, req);
    std::filesystem::path tmp = path;
    tmp += ".part";
    server::Sha256 sha;
    {
      std::ofstream out(tmp, std::ios::binary);
      v1::AssetChunk c;
      while (reader->Read(&c)) {
        sha.update(c.data().data(), c.data().size());
        out.write(c.data().data(), std::streamsize(c.data().size()));
      }
    }
    grpc::Status st = reader->Finish();
    if (!st.ok()) throw InputError("asset " + hash + ": " + st.error_message());
    if (sha.hex() != hash) throw std::runtime_error("asset " + hash + ": content does not match its hash");
    std::filesystem::rename(tmp, path);
    return path;
  }

  Session& session(const v1::Task& t, const v1::JobSpec& spec, v1::TaskResult& res) {
    auto key = std::make_pair(t.job_id(), t.shard());
    auto it = sessions_.find(key);
    if (it != sessions_.end()) {
      it->second.lastUse = ++useClock_;
      return it->second;
    }
    auto t0 = Clock::now();
    Session s;
    s.problem = std::make_unique<Problem>(buildProblem(spec, resolver()));
    Problem& p = *s.problem;
    if (t.shard() >= p.shards.size()) throw InputError("task: shard " + std::to_string(t.shard()) + " out of range");
    s.targets.resize(p.scene->cameras.size());
    for (int v : p.shards[t.shard()]) {
      if (cancel_) throw EvaluationCancelled{};
      s.targets[size_t(v)] = renderTarget(p, v, &cancel_);
    }
    s.engine = std::make_unique<GradientEngine>(*p.scene, p.params, s.targets, p.gradient);
    // Taking over a shard mid-job: rebuild the reservoirs with render-only steps at the current
    // parameters, on random streams of their own (top bit set) so no step's stream is reused.
    if (t.counter() > 0 && t.rebuild_burn_in() > 0) {
      std::vector<float> theta(t.theta().begin(), t.theta().end());
      if (theta.size() != p.params.size()) throw InputError("task: theta has " + std::to_string(theta.size()) + " values, the job " + std::to_string(p.params.size()));
      p.params.write(theta, *p.scene);  // the session's one writer, between passes
      for (uint32_t k = 0; k < t.rebuild_burn_in(); ++k) {
        GradientRequest r;
        r.views = p.shards[t.shard()];
        r.step = (uint64_t(1) << 63) | (t.counter() << 16) | k;
        r.seed = p.seed;
        r.renderOnly = true;
        r.allSessionViews = true;
        r.cancel = &cancel_;
        s.engine->evaluate(r, s.state);
      }
    }
    res.set_rebuilt(true);
    res.set_seconds_session(since(t0));
    // Least recently used sessions go while there are too many or memory is short (an evicted
    // shard is rebuilt, with a burn-in, when its next task comes).
    while (!sessions_.empty() && (sessions_.size() >= opt_.maxSessions || residentMb() > memoryLimitMb_)) {
      auto lru = sessions_.begin();
      for (auto i = sessions_.begin(); i != sessions_.end(); ++i)
        if (i->second.lastUse < lru->second.lastUse) lru = i;
      spdlog::info("worker {}: evicting session {}/{} ({} sessions, {:.0f} MiB resident)", opt_.name, lru->first.first,
                   lru->first.second, sessions_.size(), residentMb());
      sessions_.erase(lru);
    }
    s.lastUse = ++useClock_;
    return sessions_[key] = std::move(s);
  }

  std::optional<v1::WorkerMessage> execute(const v1::Task& t) {
    v1::WorkerMessage out;
    v1::TaskResult& res = *out.mutable_result();
    res.set_task_id(t.task_id());
    res.set_job_id(t.job_id());
    res.set_shard(t.shard());
    try {
      const v1::JobSpec* spec = specFor(t);
      if (!spec) {
        res.set_spec_unknown(true);
        return out;
      }
      Session& s = session(t, *spec, res);
      Problem& p = *s.problem;
      std::vector<float> theta(t.theta().begin(), t.theta().end());
      if (theta.size() != p.params.size()) throw InputError("task: theta has " + std::to_string(theta.size()) + " values, the job " + std::to_string(p.params.size()));
      if (t.kind() == v1::Task::FINAL_RENDER) {
        p.params.write(theta, *p.scene);
        RenderOptions ro = transportRenderOptions(p, std::max(1, t.final_spp()), kFinalRenderStream);
        ro.cancel = &cancel_;
        for (int v : t.views()) toProto(renderView(*p.scene, v, ro).image, res.add_renders());
        for (int v : t.views()) toProto(s.targets.at(size_t(v)), res.add_renders());
        if (p.gradient.variance.enabled)
          for (int v : t.views()) toProto(s.engine->sampleVarianceMap(v, std::max(2, t.final_spp()), p.seed, &cancel_), res.add_variances());
        return out;
      }
      GradientRequest r;
      r.views.assign(t.views().begin(), t.views().end());
      r.step = t.counter();
      r.seed = p.seed;
      r.renderOnly = t.render_only();
      r.batchViews = int(t.batch_views());
      r.allSessionViews = t.all_shard_views();
      r.cancel = &cancel_;
      p.params.write(theta, *p.scene);  // between tasks: nothing renders now
      GradientResult g = s.engine->evaluate(r, s.state);
      res.mutable_gradient()->Assign(g.gradient.begin(), g.gradient.end());
      res.set_loss(g.stats.loss);
      res.set_seconds_primal(g.stats.secondsPrimal);
      res.set_seconds_derivative(g.stats.secondsDerivative);
      res.set_seconds_reservoir(g.stats.secondsReservoirUpdate);
      res.set_seconds_stage1(g.stats.secondsStage1);
      res.set_bias_term(g.stats.biasTerm);
      res.set_variance_term(g.stats.varianceTerm);
      res.set_cost(g.stats.cost);
      res.set_seconds_variance(g.stats.secondsVariance);
      res.set_seconds_boundary(g.stats.secondsBoundary);
      res.set_boundary_edges(g.stats.boundaryEdges);
      res.set_edge_reservoirs(g.stats.edgeReservoirs);
      res.set_edge_reservoirs_preserved(g.stats.edgeReservoirsPreserved);
      res.set_non_finite(g.stats.nonFiniteSamples);
      res.set_reservoirs(g.stats.reservoirs);
      res.set_mean_m(g.stats.meanM);
      res.set_mean_neighbours(g.stats.meanNeighbours);
    } catch (const EvaluationCancelled&) {
      sessions_.erase(std::make_pair(t.job_id(), t.shard()));
      spdlog::info("worker {}: task {} of {} cancelled", opt_.name, t.task_id(), t.job_id());
      return std::nullopt;
    } catch (const InputError& e) {
      res.set_error(e.what());
      res.set_input_error(true);
    } catch (const std::exception& e) {
      res.set_error(e.what());
      sessions_.erase(std::make_pair(t.job_id(), t.shard()));
    }
    return out;
  }

  WorkerOptions opt_;
  const std::atomic<bool>& stop_;
  std::map<std::pair<std::string, uint32_t>, Session> sessions_;
  std::map<std::string, v1::JobSpec> specs_;        // by spec hash
  std::map<std::string, std::string> specOfJob_;    // job id -> spec hash
  uint64_t useClock_ = 0;
  std::atomic<bool> cancel_{false};
  double memoryLimitMb_ = 0;
};

}  // namespace

int runWorker(const WorkerOptions& options, const std::atomic<bool>& stop) {
  std::unique_ptr<tbb::global_control> threads;
  if (options.threads > 0)
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(options.threads));
  Worker w(options, stop);
  return w.run();
}

}  // namespace invr::worker
