#include "worker/sessions.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <fstream>


namespace invr::worker {

double residentMb() {
  std::ifstream in("/proc/self/statm");
  double pages = 0, resident = 0;
  in >> pages >> resident;
  return resident * double(sysconf(_SC_PAGESIZE)) / 1048576.0;
}

Session* SessionCache::find(const std::string& job, uint32_t shard) {
  auto it = sessions_.find({job, shard});
  if (it == sessions_.end()) return nullptr;
  it->second.lastUse = ++clock_;
  return &it->second;
}

Session& SessionCache::insert(const std::string& job, uint32_t shard, Session s) {
  while (!sessions_.empty() && (sessions_.size() >= maxSessions_ || residentMb() > memoryLimitMb_)) {
    auto lru = sessions_.begin();
    for (auto i = sessions_.begin(); i != sessions_.end(); ++i)
      if (i->second.lastUse < lru->second.lastUse) lru = i;
    spdlog::info("worker {}: evicting session {}/{} ({} sessions, {:.0f} MiB resident)", name_, lru->first.first, lru->first.second,
                 sessions_.size(), residentMb());
    sessions_.erase(lru);
  }
  s.lastUse = ++clock_;
  return sessions_[{job, shard}] = std::move(s);
}

void SessionCache::release(const std::string& job) {
  for (auto it = sessions_.begin(); it != sessions_.end();) it = it->first.first == job ? sessions_.erase(it) : std::next(it);
}

const invr::v1::JobSpec* SpecCache::specFor(const invr::v1::Task& t) {
  if (t.has_spec()) {
    specOfJob_[t.job_id()] = t.spec_sha256();
    return &(specs_[t.spec_sha256()] = t.spec());
  }
  auto it = specs_.find(t.spec_sha256());
  return it == specs_.end() ? nullptr : &it->second;
}

void SpecCache::release(const std::string& job) {
  auto h = specOfJob_.find(job);
  if (h == specOfJob_.end()) return;
  specs_.erase(h->second);
  specOfJob_.erase(h);
}

}  // namespace invr::worker
