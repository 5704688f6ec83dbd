// References that several tests of one binary compare against (a finite difference, a converged
// render's statistics), computed once per build of the binary instead of once per test.
//
// ctest runs every TEST in a process of its own, so a static fixture would be recomputed in each.
// Under ctest, INVR_TEST_REFERENCES names a folder that is emptied whenever the binary is relinked
// (invr_gtest() in tests/CMakeLists.txt). The first process that needs a key computes it while it
// holds an exclusive lock on <hash>.lock and writes <hash> (the values as hexadecimal floats, so a
// reader gets them to the bit); processes that need it meanwhile wait for the lock, then read. The
// key is stored beside the values and checked on reading. Without the variable (a binary run by
// hand), each process computes its own, memoised within the process. Either way a reference is a
// deterministic function of its key, so which process computes it never changes a verdict.
#pragma once

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "test_util.h"

namespace invr::test {

namespace detail {

inline uint64_t fnv1a(const std::string& s) {
  uint64_t h = 1469598103934665603ull;
  for (unsigned char c : s) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

inline bool readReference(const std::filesystem::path& path, const std::string& key, std::vector<double>& out) {
  std::ifstream in(path);
  if (!in) return false;
  std::string storedKey;
  std::getline(in, storedKey);
  if (storedKey != key) throw std::runtime_error("shared reference " + path.string() + " holds '" + storedKey + "', not '" + key + "'");
  std::string word;
  out.clear();
  while (in >> word) out.push_back(std::strtod(word.c_str(), nullptr));
  return true;
}

inline void writeReference(const std::filesystem::path& path, const std::string& key, const std::vector<double>& values) {
  const std::filesystem::path tmp = path.string() + ".tmp" + std::to_string(::getpid());
  {
    std::ofstream out(tmp);
    out << key << '\n';
    char buf[64];
    for (double v : values) {
      std::snprintf(buf, sizeof buf, "%a\n", v);
      out << buf;
    }
    if (!out) throw std::runtime_error("cannot write shared reference " + tmp.string());
  }
  std::filesystem::rename(tmp, path);  // readers never see half a file
}

}  // namespace detail

// The values of `key`, from the binary's reference folder or computed by `compute`. The key must
// name everything the values depend on (scene, parameter, component, step, seeds, sample counts).
inline std::vector<double> sharedReference(const std::string& givenKey, const std::function<std::vector<double>()>& compute) {
  static std::mutex mutex;
  static std::map<std::string, std::vector<double>> memo;
  std::lock_guard<std::mutex> guard(mutex);
  // Embree's kernels (INVR_EMBREE_CONFIG, docs/testing.md) change hits in the last bits: a
  // reference is kept per kernel choice.
  const char* embree = std::getenv("INVR_EMBREE_CONFIG");
  const std::string key = givenKey + (embree && *embree ? std::string(" embree ") + embree : std::string());
  if (auto it = memo.find(key); it != memo.end()) return it->second;
  const char* dir = std::getenv("INVR_TEST_REFERENCES");
  std::vector<double> values;
  if (!dir || !*dir) {
    values = compute();
  } else {
    std::filesystem::create_directories(dir);
    char name[32];
    std::snprintf(name, sizeof name, "%016" PRIx64, detail::fnv1a(key));
    const std::filesystem::path path = std::filesystem::path(dir) / name;
    const std::string lockPath = path.string() + ".lock";
    const int fd = ::open(lockPath.c_str(), O_CREAT | O_RDWR | O_CLOEXEC, 0644);
    if (fd < 0 || ::flock(fd, LOCK_EX) != 0) throw std::runtime_error("cannot lock " + lockPath);
    try {
      if (!detail::readReference(path, key, values)) {
        values = compute();
        detail::writeReference(path, key, values);
      }
    } catch (...) {
      ::close(fd);  // closing releases the lock
      throw;
    }
    ::close(fd);
  }
  memo[key] = values;
  return values;
}

// A MeanSE reference (its count, mean and sum of squared deviations, to the bit).
inline MeanSE sharedMeanSE(const std::string& key, const std::function<MeanSE()>& compute) {
  const std::vector<double> v = sharedReference(key, [&] {
    const MeanSE m = compute();
    return std::vector<double>{m.n, m.mean, m.m2};
  });
  if (v.size() != 3) throw std::runtime_error("shared reference '" + key + "': not a MeanSE");
  MeanSE m;
  m.n = v[0];
  m.mean = v[1];
  m.m2 = v[2];
  return m;
}

}  // namespace invr::test
