// SHA-256 content hashes (OpenSSL) for the asset store, lowercase hex.
#pragma once

#include <openssl/evp.h>

#include <filesystem>
#include <string>

namespace invr::server {

// Incremental SHA-256 (OpenSSL), lowercase hex.
class Sha256 {
 public:
  Sha256();
  ~Sha256();
  void update(const void* data, size_t n);
  std::string hex();
 private:
  EVP_MD_CTX* ctx_;
};

std::string sha256File(const std::filesystem::path& path);

}  // namespace invr::server
