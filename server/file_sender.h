// Server streams of files in chunks: results to clients (FetchResult), assets to workers
// (FetchAsset), and the immediate failure of such a call.
#pragma once

#include <grpcpp/grpcpp.h>

#include <filesystem>
#include <fstream>
#include <type_traits>

#include "invr/v1/service.grpc.pb.h"
#include "proto/wire/wire.h"

namespace invr::server {

// Streams a file in chunks (results to clients, assets to workers), as AssetChunk messages or (for
// the client API's raw methods: raw_messages.h) as their serialised bytes.
template <class Out>
class FileSenderOf final : public grpc::ServerWriteReactor<Out> {
 public:
  explicit FileSenderOf(const std::filesystem::path& path) : in_(path, std::ios::binary) {
    if (!in_) {
      this->Finish(grpc::Status(grpc::StatusCode::NOT_FOUND, "cannot read '" + path.filename().string() + "'"));
      return;
    }
    next();
  }
  void OnWriteDone(bool ok) override {
    if (!ok) return this->Finish(grpc::Status::CANCELLED);
    next();
  }
  void OnDone() override { delete this; }

 private:
  void next() {
    std::string buf(wire::kChunkBytes, '\0');
    in_.read(buf.data(), std::streamsize(buf.size()));
    buf.resize(size_t(in_.gcount()));
    if (buf.empty() && sent_) return this->Finish(grpc::Status::OK);
    sent_ = true;  // an empty file still sends one (empty) chunk
    chunk_.set_data(std::move(buf));
    if constexpr (std::is_same_v<Out, invr::v1::AssetChunk>) {
      this->StartWrite(&chunk_);
    } else {
      bool own = false;
      (void)grpc::SerializationTraits<invr::v1::AssetChunk>::Serialize(chunk_, &bytes_, &own);
      this->StartWrite(&bytes_);
    }
  }
  std::ifstream in_;
  invr::v1::AssetChunk chunk_;
  grpc::ByteBuffer bytes_;
  bool sent_ = false;
};
using FileSender = FileSenderOf<invr::v1::AssetChunk>;

// A file stream that fails before its first chunk (unknown job, result or asset).
template <class Out>
class FailedFileSenderOf final : public grpc::ServerWriteReactor<Out> {
 public:
  explicit FailedFileSenderOf(grpc::Status status) { this->Finish(std::move(status)); }
  void OnDone() override { delete this; }
};
using FailedFileSender = FailedFileSenderOf<invr::v1::AssetChunk>;

}  // namespace invr::server
