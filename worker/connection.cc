#include "worker/connection.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <thread>

#include "invr/v1/service.grpc.pb.h"
#include "core/stopwatch.h"
#include "proto/wire/wire.h"

namespace invr::worker {

namespace v1 = invr::v1;

void Connection::noteRefusal(const grpc::Status& st) {
  if (st.error_code() == grpc::StatusCode::UNAUTHENTICATED || st.error_code() == grpc::StatusCode::PERMISSION_DENIED) refusal_ = st;
}

bool Connection::serve(const Handlers& handlers) {
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
      if (shouldStop_()) {
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
        if (!cancel_ && Stopwatch(*stopSince).seconds() > opt_.drainSeconds) {
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
      if (!connected || shouldStop_()) break;
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
      handlers.release(m.release_job());
    } else if (m.has_task()) {
      std::optional<v1::WorkerMessage> out = handlers.task(m.task());
      busy = 0;
      if (out) write(*out);
    }
  }
  if (shouldStop_()) {
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

}  // namespace invr::worker
