// Bearer-token checks of incoming calls: one token for the client API, a different one for the
// worker API, so a client's token cannot register a worker (nor a worker's submit jobs).
// Without a token for a role, that role's calls are not checked (loopback, or TLS client
// certificates alone). Health checks are never checked (orchestrators' probes carry no token).
#pragma once

#include <grpcpp/grpcpp.h>

#include <string>

namespace invr::server {

enum class CallerRole { Client, Worker };

class Authenticator {
 public:
  Authenticator(std::string clientToken, std::string workerToken);
  // OK; UNAUTHENTICATED when the call has no bearer token or an unknown one; PERMISSION_DENIED
  // when it carries the other role's token. Refusals are logged with the peer and the method,
  // never with a token.
  grpc::Status check(const grpc::CallbackServerContext* ctx, CallerRole role, const char* method) const;
  bool enabled(CallerRole role) const { return !(role == CallerRole::Client ? client_ : worker_).empty(); }

 private:
  std::string client_, worker_;
};

}  // namespace invr::server
