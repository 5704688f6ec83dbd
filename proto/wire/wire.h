// What client, server and worker agree on about the wire.
#pragma once

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

#include "proto/wire/security.h"

namespace invr::wire {

// Tasks carry the parameter vector and results carry images; gRPC's 4 MiB default would cap a job
// at ~1M parameters, so the limit is raised on purpose on every channel and on the server.
// Files (assets, results) always travel in chunks of kChunkBytes.
inline constexpr int kMaxMessageBytes = 512 << 20;
inline constexpr size_t kChunkBytes = 1 << 20;

// A channel to `address`: plaintext, or TLS when `security` has a CA (then its client certificate,
// if any, for mutual TLS). The bearer token goes per call (addToken).
inline std::shared_ptr<grpc::Channel> channel(const std::string& address, const ClientSecurity& security = {}) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(kMaxMessageBytes);
  args.SetMaxSendMessageSize(kMaxMessageBytes);
  // Reconnect within a second of a server coming back: gRPC's default back-off grows to two
  // minutes, which is where a watcher's or worker's retry budget would otherwise go.
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 1000);
  // Despite its name, gRPC reads MIN_RECONNECT_BACKOFF as the time one connection attempt may take
  // (TCP, the TLS handshake, the server's first SETTINGS frame). It stays at gRPC's 20 s: at 100 ms
  // a TLS handshake with a loaded server timed out before the first call was sent.
  args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 20000);
  if (!security.tls()) return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
  grpc::SslCredentialsOptions ssl;
  ssl.pem_root_certs = security.caPem;
  ssl.pem_cert_chain = security.certPem;
  ssl.pem_private_key = security.keyPem;
  if (!security.serverName.empty()) args.SetSslTargetNameOverride(security.serverName);
  return grpc::CreateCustomChannel(address, grpc::SslCredentials(ssl), args);
}

}  // namespace invr::wire
