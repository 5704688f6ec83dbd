#include "server/asset_store.h"

#include <atomic>
#include <cstdio>
#include <stdexcept>
#include <unistd.h>

namespace invr::server {

AssetStore::AssetStore(std::filesystem::path dir) : dir_(std::move(dir)) { std::filesystem::create_directories(dir_); }

bool AssetStore::validHash(const std::string& s) {
  if (s.size() != 64) return false;
  for (char c : s)
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  return true;
}

bool AssetStore::has(const std::string& sha256) const { return validHash(sha256) && std::filesystem::exists(path(sha256)); }

AssetStore::Upload::Upload(const AssetStore& store, uint64_t maxBytes) : store_(store), max_(maxBytes) {
  static std::atomic<uint64_t> counter{0};
  tmp_ = store.dir_ / (".upload-" + std::to_string(getpid()) + "-" + std::to_string(counter++));
  out_.open(tmp_, std::ios::binary);
  if (!out_) throw std::runtime_error("asset store: cannot write '" + tmp_.string() + "'");
}

AssetStore::Upload::~Upload() {
  if (!committed_) {
    out_.close();
    std::error_code ec;
    std::filesystem::remove(tmp_, ec);
  }
}

bool AssetStore::Upload::append(const std::string& bytes) {
  size_ += bytes.size();
  if (size_ > max_) return false;
  hash_.update(bytes.data(), bytes.size());
  out_.write(bytes.data(), std::streamsize(bytes.size()));
  return bool(out_);
}

std::string AssetStore::Upload::commit() {
  out_.close();
  if (!out_) throw std::runtime_error("asset store: write failed");
  std::string h = hash_.hex();
  std::filesystem::rename(tmp_, store_.path(h));  // atomic: a reader never sees half a file
  committed_ = true;
  return h;
}

}  // namespace invr::server
