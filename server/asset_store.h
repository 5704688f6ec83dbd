// Content-addressed asset store: files named by the SHA-256 of their bytes.
#pragma once

#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include "proto/wire/sha256.h"

namespace invr::server {

class AssetStore {
 public:
  explicit AssetStore(std::filesystem::path dir);
  bool has(const std::string& sha256) const;
  std::filesystem::path path(const std::string& sha256) const { return dir_ / sha256; }
  static bool validHash(const std::string& s);

  // One upload in progress: bytes go to a temporary file while they are hashed.
  class Upload {
   public:
    Upload(const AssetStore& store, uint64_t maxBytes);
    ~Upload();
    bool append(const std::string& bytes);  // false: over the size limit
    std::string commit();                   // renames into the store; returns the hash
    uint64_t size() const { return size_; }
   private:
    const AssetStore& store_;
    std::filesystem::path tmp_;
    std::ofstream out_;
    Sha256 hash_;
    uint64_t size_ = 0, max_;
    bool committed_ = false;
  };

 private:
  std::filesystem::path dir_;
};

}  // namespace invr::server
