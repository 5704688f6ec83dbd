// A queue of messages written one at a time on a gRPC server stream (worker streams, progress
// watchers): the callback API allows one write in flight per stream.
#pragma once

#include <grpcpp/grpcpp.h>

#include <deque>
#include <mutex>

namespace invr::server {

// A queue of messages written one at a time on a server stream. Decisions are made under the
// stream's own mutex and Start*/Finish are called after releasing it, so a reaction that runs
// inline cannot deadlock.
template <class Reactor, class Msg>
class WriteQueue {
 public:
  explicit WriteQueue(Reactor* r) : r_(r) {}
  void push(Msg m, bool last = false) {
    const Msg* start = nullptr;
    {
      std::lock_guard<std::mutex> lk(mu_);
      if (closing_) return;
      q_.push_back(std::move(m));
      if (last) closing_ = true, lastQueued_ = true;
      if (writing_) return;
      writing_ = true;
      start = &q_.front();
    }
    r_->StartWrite(start);
  }
  // After a write completes: the next message, or Finish once closing and drained.
  void done(bool ok) {
    const Msg* next = nullptr;
    bool fin = false;
    {
      std::lock_guard<std::mutex> lk(mu_);
      q_.pop_front();
      if (!ok) closing_ = true, q_.clear();
      if (!q_.empty()) {
        next = &q_.front();
      } else {
        writing_ = false;
        if (closing_ && !finished_) finished_ = fin = true;
      }
    }
    if (next) r_->StartWrite(next);
    if (fin) r_->Finish(status_);
  }
  // Stop writing; Finish now if nothing is in flight, else when it completes.
  void close(grpc::Status status = grpc::Status::OK) {
    bool fin = false;
    {
      std::lock_guard<std::mutex> lk(mu_);
      if (!closing_) status_ = status;
      closing_ = true;
      if (!writing_ && !finished_) finished_ = fin = true;
    }
    if (fin) r_->Finish(status_);
  }

 private:
  Reactor* r_;
  std::mutex mu_;
  std::deque<Msg> q_;
  bool writing_ = false, closing_ = false, finished_ = false, lastQueued_ = false;
  grpc::Status status_ = grpc::Status::OK;
};


}  // namespace invr::server
