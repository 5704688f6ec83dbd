// The worker's copies of a job's assets (meshes, textures, targets), fetched from the server by
// SHA-256 into a folder of its own and checked against their hash.
#pragma once

#include <filesystem>
#include <string>

#include "core/scene/scene_builder.h"
#include "proto/wire/security.h"

namespace invr::worker {

class AssetCache {
 public:
  AssetCache(std::filesystem::path dir, std::string server, invr::wire::ClientSecurity security)
      : dir_(std::move(dir)), server_(std::move(server)), security_(std::move(security)) {}
  // The local path of the asset with this hash, fetched first if missing. Throws InputError when
  // the server does not have it, std::runtime_error when the bytes do not match the hash.
  std::filesystem::path fetch(const std::string& hash);
  // A resolver that fetches what a job names by hash.
  AssetResolver resolver();

 private:
  std::filesystem::path dir_;
  std::string server_;
  invr::wire::ClientSecurity security_;
};

}  // namespace invr::worker
