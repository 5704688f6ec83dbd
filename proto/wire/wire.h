// What client, server and worker agree on about the wire.
#pragma once

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

namespace invr::wire {

// Tasks carry the parameter vector and results carry images; gRPC's 4 MiB default would cap a job
// at ~1M parameters, so the limit is raised on purpose on every channel and on the server.
// Files (assets, results) always travel in chunks of kChunkBytes.
inline constexpr int kMaxMessageBytes = 512 << 20;
inline constexpr size_t kChunkBytes = 1 << 20;

inline std::shared_ptr<grpc::Channel> channel(const std::string& address) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(kMaxMessageBytes);
  args.SetMaxSendMessageSize(kMaxMessageBytes);
  // Reconnect within a second of a server coming back: gRPC's default back-off grows to two
  // minutes, which is where a watcher's or worker's retry budget would otherwise go.
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
  args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 100);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 1000);
  return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
}

}  // namespace invr::wire
