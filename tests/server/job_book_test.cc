// The job book over a real store in a temporary folder: request ids, the bounded queue, events
// and watchers, cancellation, and what a restarted server finds.
#include "server/job_book.h"

#include <gtest/gtest.h>
#include <unistd.h>

namespace invr::server {
namespace {

namespace v1 = invr::v1;

struct TempDir {
  std::filesystem::path path;
  TempDir() {
    path = std::filesystem::temp_directory_path() / ("invr-book-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    std::filesystem::remove_all(path);
  }
  ~TempDir() { std::filesystem::remove_all(path); }
  static inline int counter = 0;
};

struct Sink final : EventSink {
  std::vector<v1::ProgressEvent> events;
  bool closed = false;
  void push(const v1::ProgressEvent& e) override { events.push_back(e); }
  void close(grpc::Status) override { closed = true; }
};

v1::JobSpec spec(const std::string& name) {
  v1::JobSpec s;
  s.set_name(name);
  s.set_zoo("cornell");
  return s;
}

TEST(JobBook, RequestIdsAreIdempotentAndTheQueueIsBounded) {
  TempDir dir;
  JobStore store(dir.path);
  JobBook book(store, 2);
  std::string a, b, again;
  bool existing = true;
  ASSERT_TRUE(book.add(spec("a"), "req-1", &a, &existing).ok());
  EXPECT_FALSE(existing);
  ASSERT_TRUE(book.add(spec("a"), "req-1", &again, &existing).ok());
  EXPECT_TRUE(existing);
  EXPECT_EQ(again, a);
  EXPECT_EQ(book.jobOfRequest("req-1").value_or(""), a);
  ASSERT_TRUE(book.add(spec("b"), "", &b, &existing).ok());
  EXPECT_EQ(book.queued(), 2u);
  EXPECT_EQ(book.roomInQueue().error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  std::string c;
  EXPECT_EQ(book.add(spec("c"), "", &c, &existing).error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  // Taking one makes room; it is RUNNING.
  EXPECT_EQ(book.take().value_or(""), a);
  v1::JobStatus st;
  ASSERT_TRUE(book.status(a, &st).ok());
  EXPECT_EQ(st.state(), v1::RUNNING);
  EXPECT_EQ(book.running(), 1u);
  EXPECT_TRUE(book.roomInQueue().ok());
}

TEST(JobBook, WatchersGetTheLogFromTheirSequenceThenLiveEventsAndTheFinalOne) {
  TempDir dir;
  JobStore store(dir.path);
  JobBook book(store, 4);
  std::string id;
  bool existing = false;
  ASSERT_TRUE(book.add(spec("a"), "", &id, &existing).ok());  // event 1: queued
  ASSERT_TRUE(book.take());
  book.log(id, "started");  // 2
  Sink late;
  ASSERT_TRUE(book.watch(id, 2, &late).ok());
  ASSERT_EQ(late.events.size(), 1u);
  EXPECT_EQ(late.events[0].message(), "started");
  v1::StepProgress sp;
  sp.set_step(1);
  sp.set_loss(0.5);
  book.stepDone(id, sp, 1.25, 2);  // 3
  book.end(id, v1::SUCCEEDED, "", nullptr);  // 4: final
  ASSERT_EQ(late.events.size(), 3u);
  EXPECT_TRUE(late.events[1].has_step());
  ASSERT_TRUE(late.events[2].has_final());
  EXPECT_EQ(late.events[2].final().state(), v1::SUCCEEDED);
  EXPECT_EQ(late.events[2].final().worker_seconds(), 1.25);
  EXPECT_EQ(late.events[2].sequence(), 4u);
  book.unwatch(id, &late);
  // Past the end: nothing to send, the stream closes.
  Sink after;
  ASSERT_TRUE(book.watch(id, 5, &after).ok());
  EXPECT_TRUE(after.events.empty());
  EXPECT_TRUE(after.closed);
  EXPECT_EQ(book.watch("job-999999", 1, &after).error_code(), grpc::StatusCode::NOT_FOUND);
}

TEST(JobBook, EventsArePagedFromASequenceAndTheStatusCarriesRateAndSubmitter) {
  TempDir dir;
  JobStore store(dir.path);
  JobBook book(store, 4);
  std::string id;
  bool existing = false;
  ASSERT_TRUE(book.add(spec("a"), "", &id, &existing, "alice").ok());  // event 1: queued
  ASSERT_TRUE(book.take());
  for (int k = 1; k <= 5; ++k) {  // events 2..6
    v1::StepProgress sp;
    sp.set_step(uint64_t(k));
    sp.set_steps_per_second(2.0 * k);
    sp.set_eta_seconds(10.0 - k);
    book.stepDone(id, sp, 0, 1);
  }
  std::vector<v1::ProgressEvent> ev;
  ASSERT_TRUE(book.events(id, 3, 2, &ev).ok());
  ASSERT_EQ(ev.size(), 2u);
  EXPECT_EQ(ev[0].sequence(), 3u);
  EXPECT_EQ(ev[1].step().step(), 3u);
  ASSERT_TRUE(book.events(id, 6, 100, &ev).ok());
  ASSERT_EQ(ev.size(), 1u);
  ASSERT_TRUE(book.events(id, 7, 100, &ev).ok());
  EXPECT_TRUE(ev.empty());
  EXPECT_EQ(book.events("job-999999", 1, 1, &ev).error_code(), grpc::StatusCode::NOT_FOUND);
  v1::JobStatus st;
  ASSERT_TRUE(book.status(id, &st).ok());
  EXPECT_EQ(st.submitted_by(), "alice");
  EXPECT_EQ(st.steps_per_second(), 10.0);
  EXPECT_EQ(st.eta_seconds(), 5.0);
  book.end(id, v1::SUCCEEDED, "", nullptr);
  ASSERT_TRUE(book.status(id, &st).ok());
  EXPECT_EQ(st.steps_per_second(), 0.0);  // a rate for running jobs only
  EXPECT_EQ(st.submitted_by(), "alice");
}

TEST(JobBook, CancellingAQueuedJobEndsItARunningOneIsFlagged) {
  TempDir dir;
  JobStore store(dir.path);
  JobBook book(store, 4);
  std::string a, b;
  bool existing = false, wasQueued = false;
  ASSERT_TRUE(book.add(spec("a"), "", &a, &existing).ok());
  ASSERT_TRUE(book.add(spec("b"), "", &b, &existing).ok());
  ASSERT_EQ(book.take().value_or(""), a);
  v1::JobStatus st;
  ASSERT_TRUE(book.cancel(b, &st, &wasQueued).ok());
  EXPECT_TRUE(wasQueued);
  EXPECT_EQ(st.state(), v1::CANCELLED);
  EXPECT_EQ(book.queued(), 0u);
  ASSERT_TRUE(book.cancel(a, &st, &wasQueued).ok());
  EXPECT_FALSE(wasQueued);
  EXPECT_EQ(st.state(), v1::RUNNING);
  EXPECT_TRUE(book.cancelRequested(a));
  EXPECT_EQ(book.cancel("nope", &st, &wasQueued).error_code(), grpc::StatusCode::NOT_FOUND);
}

TEST(JobBook, ARestartedServerQueuesUnfinishedJobsAgainAndKeepsFinishedOnes) {
  TempDir dir;
  std::string a, b;
  {
    JobStore store(dir.path);
    JobBook book(store, 4);
    bool existing = false;
    v1::JobSpec pt = spec("a");
    pt.mutable_optimization()->set_method(v1::METHOD_PT);
    ASSERT_TRUE(book.add(pt, "req-a", &a, &existing).ok());
    ASSERT_TRUE(book.add(spec("b"), "", &b, &existing).ok());
    ASSERT_TRUE(book.take());  // a runs...
    book.started(a, 0, 10, "pt");
    book.end(a, v1::FAILED, "diverged", nullptr);
    ASSERT_TRUE(book.take());  // ... b runs when the server stops
  }
  JobStore store(dir.path);
  JobBook book(store, 4);
  book.load();
  v1::JobStatus st;
  ASSERT_TRUE(book.status(a, &st).ok());
  EXPECT_EQ(st.state(), v1::FAILED);
  EXPECT_EQ(st.reason(), "diverged");
  EXPECT_EQ(st.method(), "pt");  // a finished job never starts again: its method comes from its spec
  ASSERT_TRUE(book.status(b, &st).ok());
  EXPECT_EQ(st.method(), "restir");  // the default method
  ASSERT_TRUE(book.status(b, &st).ok());
  EXPECT_EQ(st.state(), v1::QUEUED);
  EXPECT_EQ(book.queued(), 1u);
  EXPECT_EQ(book.jobOfRequest("req-a").value_or(""), a);
}

}  // namespace
}  // namespace invr::server
