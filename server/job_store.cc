#include "server/job_store.h"

#include <fcntl.h>
#include <google/protobuf/util/json_util.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "proto/wire/json_lines.h"

namespace invr::server {

namespace v1 = invr::v1;

void writeFileAtomically(const std::filesystem::path& path, const std::string& bytes) {
  std::filesystem::path tmp = path;
  tmp += ".tmp";
  int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd < 0) throw std::runtime_error("cannot write '" + tmp.string() + "'");
  size_t done = 0;
  while (done < bytes.size()) {
    ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n <= 0) {
      ::close(fd);
      throw std::runtime_error("write failed: '" + tmp.string() + "'");
    }
    done += size_t(n);
  }
  ::fsync(fd);
  ::close(fd);
  std::filesystem::rename(tmp, path);
}

JobStore::JobStore(std::filesystem::path dir) : dir_(std::move(dir)) {
  std::filesystem::create_directories(dir_);
  for (const auto& e : std::filesystem::directory_iterator(dir_)) {
    std::string n = e.path().filename().string();
    if (n.rfind("job-", 0) == 0) next_ = std::max<uint64_t>(next_, std::stoull(n.substr(4)) + 1);
  }
}

std::string JobStore::newJobId() {
  char buf[32];
  std::snprintf(buf, sizeof buf, "job-%06llu", static_cast<unsigned long long>(next_++));
  std::filesystem::create_directories(dir_ / buf / "results");
  return buf;
}

std::vector<v1::JobRecord> JobStore::loadAll() const {
  std::vector<v1::JobRecord> out;
  for (const auto& e : std::filesystem::directory_iterator(dir_)) {
    std::ifstream in(e.path() / "record.pb", std::ios::binary);
    v1::JobRecord r;
    if (in && r.ParseFromIstream(&in)) out.push_back(std::move(r));
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.job_id() < b.job_id(); });
  return out;
}

void JobStore::saveRecord(const v1::JobRecord& r) const { writeFileAtomically(jobDir(r.job_id()) / "record.pb", r.SerializeAsString()); }

void JobStore::saveCheckpoint(const std::string& job, const v1::Checkpoint& ck) const {
  writeFileAtomically(jobDir(job) / "checkpoint.pb", ck.SerializeAsString());
}

std::optional<v1::Checkpoint> JobStore::loadCheckpoint(const std::string& job) const {
  std::ifstream in(jobDir(job) / "checkpoint.pb", std::ios::binary);
  v1::Checkpoint ck;
  if (!in || !ck.ParseFromIstream(&in)) return std::nullopt;
  return ck;
}

void JobStore::appendEvent(const std::string& job, const v1::ProgressEvent& ev) const {
  // Numbers as JSON numbers and non-finite ones as null (what scripts reading the fetched log
  // expect); read back below, a null loss comes back as 0.
  const std::string line = wire::jsonLine(ev);
  std::ofstream out(jobDir(job) / "progress.jsonl", std::ios::app);
  out << line << "\n";
}

std::vector<v1::ProgressEvent> JobStore::loadEvents(const std::string& job) const {
  std::vector<v1::ProgressEvent> out;
  std::ifstream in(jobDir(job) / "progress.jsonl");
  std::string line;
  while (std::getline(in, line)) {
    v1::ProgressEvent ev;
    // A line cut short by a crash is dropped; everything before it is intact.
    if (google::protobuf::util::JsonStringToMessage(line, &ev).ok()) out.push_back(std::move(ev));
  }
  return out;
}

}  // namespace invr::server
