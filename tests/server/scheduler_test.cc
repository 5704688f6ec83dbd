// The scheduler with in-process fake workers: fair share by priority, sticky shards spread over
// the workers of every running job, the worker cap, lost workers and cancellation.
#include "server/scheduler.h"

#include <gtest/gtest.h>

#include <atomic>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <thread>

namespace invr::server {
namespace {

namespace v1 = invr::v1;

constexpr size_t kParams = 3;

// A worker that answers each task after `taskSeconds` (or never, when silent).
class FakeWorker final : public WorkerLink {
 public:
  FakeWorker(Scheduler& s, std::string name, double taskSeconds, bool silent = false)
      : s_(s), taskSeconds_(taskSeconds), silent_(silent), thread_([this] { loop(); }) {
    v1::WorkerMessage hello;
    hello.mutable_hello()->set_name(std::move(name));
    hello.mutable_hello()->set_capacity(1);
    s_.onMessage(this, hello);
  }
  ~FakeWorker() override {
    disconnect();
    thread_.join();
  }
  void send(v1::ServerMessage m) override {
    std::lock_guard<std::mutex> lk(mu_);
    if (m.has_task()) inbox_.push_back(m.task());
    cv_.notify_all();
  }
  void close() override {}
  void disconnect() {
    {
      std::lock_guard<std::mutex> lk(mu_);
      if (gone_) return;
      gone_ = true;
      cv_.notify_all();
    }
    s_.onGone(this);
  }
  int tasks() const { return done_; }

 private:
  void loop() {
    for (;;) {
      v1::Task t;
      {
        std::unique_lock<std::mutex> lk(mu_);
        cv_.wait(lk, [&] { return gone_ || (!inbox_.empty() && !silent_); });
        if (gone_) return;
        t = inbox_.front();
        inbox_.pop_front();
      }
      std::this_thread::sleep_for(std::chrono::duration<double>(taskSeconds_));
      v1::WorkerMessage m;
      v1::TaskResult* r = m.mutable_result();
      r->set_task_id(t.task_id());
      r->set_job_id(t.job_id());
      r->set_shard(t.shard());
      for (size_t k = 0; k < kParams; ++k) r->add_gradient(float(t.shard() + 1));
      ++done_;
      // Not under mu_: the scheduler answers with the next task through send(). A result after
      // disconnect() is from a link the scheduler no longer knows, and is ignored.
      if (!gone_) s_.onMessage(this, m);
    }
  }
  Scheduler& s_;
  double taskSeconds_;
  bool silent_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<v1::Task> inbox_;
  std::atomic<bool> gone_{false};
  std::atomic<int> done_{0};
  std::thread thread_;
};

struct Log {
  std::mutex mu;
  std::vector<std::string> lines;
  bool has(const std::string& s) {
    std::lock_guard<std::mutex> lk(mu);
    for (auto& l : lines)
      if (l.find(s) != std::string::npos) return true;
    return false;
  }
};

ScheduledJob job(const std::string& id, size_t shards, double priority, Log& log, std::atomic<bool>* cancel = nullptr) {
  ScheduledJob j;
  j.id = id;
  j.specHash = "hash-" + id;
  j.shape.parameters = kParams;
  j.shards = shards;
  j.priority = priority;
  j.log = [&log](const std::string& m) {
    std::lock_guard<std::mutex> lk(log.mu);
    log.lines.push_back(m);
  };
  j.cancelled = [cancel] { return cancel && cancel->load(); };
  return j;
}

std::vector<std::optional<v1::Task>> tasksFor(const std::string& id, size_t shards) {
  std::vector<std::optional<v1::Task>> ts(shards);
  for (size_t s = 0; s < shards; ++s) {
    v1::Task t;
    t.set_job_id(id);
    t.set_shard(uint32_t(s));
    t.set_kind(v1::Task::GRADIENT);
    ts[s] = t;
  }
  return ts;
}

SchedulerOptions fast() {
  SchedulerOptions o;
  o.assignGraceSeconds = 0;
  return o;
}

// Two jobs whose runners evaluate back to back on one worker for `seconds`: each job's share of
// the worker time. The runner's own step between evaluations is simulated by a short pause.
std::pair<double, double> share(double priorityA, double priorityB, double seconds) {
  Scheduler s(fast());
  FakeWorker w(s, "w", 0.01);
  Log log;
  s.addJob(job("a", 1, priorityA, log));
  s.addJob(job("b", 1, priorityB, log));
  std::atomic<bool> stop{false};
  auto runner = [&](const std::string& id) {
    while (!stop) {
      s.run(id, tasksFor(id, 1));
      std::this_thread::sleep_for(std::chrono::milliseconds(2));  // the optimiser step
    }
  };
  std::thread a(runner, "a"), b(runner, "b");
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  stop = true;
  a.join();
  b.join();
  double ta = s.workerSeconds("a"), tb = s.workerSeconds("b");
  return {ta / (ta + tb), ta + tb};
}

TEST(Scheduler, EqualPrioritiesShareAWorkerEvenly) {
  auto [shareA, total] = share(1, 1, 1.5);
  EXPECT_GT(total, 1.0);  // the worker was kept busy
  EXPECT_NEAR(shareA, 0.5, 0.06);
}

TEST(Scheduler, PriorityTwoGetsTwiceTheWorkerTimeOfPriorityOne) {
  // Without the brief wait for the job that is behind, the two would alternate (0.5).
  auto [shareA, total] = share(2, 1, 1.5);
  EXPECT_GT(total, 1.0);
  EXPECT_NEAR(shareA, 2.0 / 3.0, 0.06);
}

TEST(Scheduler, ShardsOfTwoJobsSpreadOverTheWorkersAndResultsComeInShardOrder) {
  Scheduler s(fast());
  FakeWorker w1(s, "w1", 0.001), w2(s, "w2", 0.001);
  Log log;
  s.addJob(job("a", 1, 1, log));
  s.addJob(job("b", 1, 1, log));
  auto ra = s.run("a", tasksFor("a", 1));
  auto rb = s.run("b", tasksFor("b", 1));
  ASSERT_TRUE(ra[0] && rb[0]);
  EXPECT_EQ(s.workersOf("a"), 1u);
  EXPECT_EQ(s.workersOf("b"), 1u);
  // One shard each: on different workers, since the load of every running job counts.
  auto ws = s.workers();
  ASSERT_EQ(ws.size(), 2u);
  EXPECT_EQ(ws[0].shards(), 1u);
  EXPECT_EQ(ws[1].shards(), 1u);
  s.addJob(job("c", 4, 1, log));
  auto rc = s.run("c", tasksFor("c", 4));
  for (size_t k = 0; k < 4; ++k) {
    ASSERT_TRUE(rc[k]);
    EXPECT_EQ(rc[k]->shard(), k);
    EXPECT_EQ(rc[k]->gradient(0), float(k + 1));
  }
}

TEST(Scheduler, MaxWorkersCapsTheDistinctWorkersOfAJob) {
  Scheduler s(fast());
  FakeWorker w1(s, "w1", 0.001), w2(s, "w2", 0.001), w3(s, "w3", 0.001);
  Log log;
  ScheduledJob j = job("a", 4, 1, log);
  j.maxWorkers = 2;
  s.addJob(j);
  auto r = s.run("a", tasksFor("a", 4));
  for (auto& x : r) EXPECT_TRUE(x);
  EXPECT_EQ(s.workersOf("a"), 2u);
  s.addJob(job("b", 4, 1, log));  // no cap: every worker
  s.run("b", tasksFor("b", 4));
  EXPECT_EQ(s.workersOf("b"), 3u);
}

TEST(Scheduler, ALostWorkersShardMovesAndTheEvaluationCompletes) {
  Scheduler s(fast());
  FakeWorker good(s, "good", 0.001);
  auto silent = std::make_unique<FakeWorker>(s, "silent", 0.001, /*silent=*/true);
  Log log;
  s.addJob(job("a", 2, 1, log));
  std::thread killer([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    silent->disconnect();
  });
  auto r = s.run("a", tasksFor("a", 2));
  killer.join();
  EXPECT_TRUE(r[0] && r[1]);
  EXPECT_TRUE(log.has("worker silent lost; reassigning"));
}

TEST(Scheduler, ShardsFailingOnEveryAttemptFailTheJob) {
  SchedulerOptions o = fast();
  o.leaseSeconds = 0.05;
  o.maxAttempts = 2;
  Scheduler s(o);
  FakeWorker w1(s, "w1", 0.001, true), w2(s, "w2", 0.001, true);
  Log log;
  s.addJob(job("a", 1, 1, log));
  EXPECT_THROW(s.run("a", tasksFor("a", 1)), JobFailed);
  EXPECT_TRUE(log.has("expired"));
}

TEST(Scheduler, CancellationEndsAWaitingEvaluation) {
  Scheduler s(fast());  // no worker at all: the evaluation waits
  Log log;
  std::atomic<bool> cancel{false};
  s.addJob(job("a", 1, 1, log, &cancel));
  std::thread t([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    cancel = true;
    s.wake();
  });
  EXPECT_THROW(s.run("a", tasksFor("a", 1)), JobCancelled);
  t.join();
  EXPECT_TRUE(log.has("waiting for a worker to connect"));
}

}  // namespace
}  // namespace invr::server
