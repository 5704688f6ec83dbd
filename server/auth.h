// Bearer-token checks of incoming calls: client tokens for the client API, a different one for
// the worker API, so a client's token cannot register a worker (nor a worker's submit jobs).
// Without a token for a role, that role's calls are not checked (loopback, or TLS client
// certificates alone). Health checks are never checked (orchestrators' probes carry no token).
// Client tokens have names (who submitted a job); the dashboard checks the same tokens.
#pragma once

#include <grpcpp/grpcpp.h>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace invr::server {

enum class CallerRole { Client, Worker };

struct NamedToken {
  std::string name, token;
};

// A client token file: one token per line, `NAME TOKEN` or the token alone (named "client");
// blank lines and lines starting with '#' are skipped. Names and tokens must be unique.
std::vector<NamedToken> readClientTokenFile(const std::filesystem::path& path);

class Authenticator {
 public:
  Authenticator(std::vector<NamedToken> clientTokens, std::string workerToken);
  // OK; UNAUTHENTICATED when the call has no bearer token or an unknown one; PERMISSION_DENIED
  // when it carries the other role's token. Refusals are logged with the peer and the method,
  // never with a token. `name`: the client token's name (empty when client tokens are off).
  grpc::Status check(const grpc::CallbackServerContext* ctx, CallerRole role, const char* method, std::string* name = nullptr) const;
  // The name of this client token; nullopt when it is not one (constant time per token).
  std::optional<std::string> clientTokenName(const std::string& token) const;
  bool enabled(CallerRole role) const { return role == CallerRole::Client ? !clients_.empty() : !worker_.empty(); }

 private:
  std::vector<NamedToken> clients_;
  std::string worker_;
};

}  // namespace invr::server
