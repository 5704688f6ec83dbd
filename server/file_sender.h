// Server streams of files in chunks: results to clients (FetchResult), assets to workers
// (FetchAsset), and the immediate failure of such a call.
#pragma once

#include <grpcpp/grpcpp.h>

#include <filesystem>
#include <fstream>

#include "invr/v1/service.grpc.pb.h"
#include "proto/wire/wire.h"

namespace invr::server {

// Streams a file in chunks (results to clients, assets to workers).
class FileSender final : public grpc::ServerWriteReactor<invr::v1::AssetChunk> {
 public:
  explicit FileSender(const std::filesystem::path& path) : in_(path, std::ios::binary) {
    if (!in_) {
      Finish(grpc::Status(grpc::StatusCode::NOT_FOUND, "cannot read '" + path.filename().string() + "'"));
      return;
    }
    next();
  }
  void OnWriteDone(bool ok) override {
    if (!ok) return Finish(grpc::Status::CANCELLED);
    next();
  }
  void OnDone() override { delete this; }

 private:
  void next() {
    std::string buf(wire::kChunkBytes, '\0');
    in_.read(buf.data(), std::streamsize(buf.size()));
    buf.resize(size_t(in_.gcount()));
    if (buf.empty() && sent_) return Finish(grpc::Status::OK);
    sent_ = true;  // an empty file still sends one (empty) chunk
    chunk_.set_data(std::move(buf));
    StartWrite(&chunk_);
  }
  std::ifstream in_;
  invr::v1::AssetChunk chunk_;
  bool sent_ = false;
};

// A file stream that fails before its first chunk (unknown job, result or asset).
class FailedFileSender final : public grpc::ServerWriteReactor<invr::v1::AssetChunk> {
 public:
  explicit FailedFileSender(grpc::Status status) { Finish(std::move(status)); }
  void OnDone() override { delete this; }
};

}  // namespace invr::server
