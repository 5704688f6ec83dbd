#include "worker/asset_cache.h"

#include <fstream>

#include "core/error.h"
#include "invr/v1/service.grpc.pb.h"
#include "proto/wire/sha256.h"
#include "proto/wire/wire.h"

namespace invr::worker {

namespace v1 = invr::v1;

AssetResolver AssetCache::resolver() {
  AssetResolver r;
  r.byHash = [this](const std::string& h) { return fetch(h); };
  return r;
}

std::filesystem::path AssetCache::fetch(const std::string& hash) {
  std::filesystem::path path = dir_ / hash;
  if (std::filesystem::exists(path)) return path;
  auto stub = v1::WorkerService::NewStub(wire::channel(server_, security_));
  grpc::ClientContext ctx;
  wire::addToken(ctx, security_);
  v1::FetchAssetRequest req;
  req.set_sha256(hash);
  auto reader = stub->FetchAsset(&ctx, req);
  std::filesystem::path tmp = path;
  tmp += ".part";
  server::Sha256 sha;
  {
    std::ofstream out(tmp, std::ios::binary);
    v1::AssetChunk c;
    while (reader->Read(&c)) {
      sha.update(c.data().data(), c.data().size());
      out.write(c.data().data(), std::streamsize(c.data().size()));
    }
  }
  grpc::Status st = reader->Finish();
  if (!st.ok()) throw InputError("asset " + hash + ": " + st.error_message());
  if (sha.hex() != hash) throw std::runtime_error("asset " + hash + ": content does not match its hash");
  std::filesystem::rename(tmp, path);
  return path;
}

}  // namespace invr::worker
