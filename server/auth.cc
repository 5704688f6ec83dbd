#include "server/auth.h"

#include <spdlog/spdlog.h>

#include <fstream>
#include <set>
#include <sstream>

#include "core/error.h"
#include "proto/wire/security.h"

namespace invr::server {

std::vector<NamedToken> readClientTokenFile(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw InputError("--client-token-file '" + path.string() + "': cannot read it");
  std::vector<NamedToken> out;
  std::set<std::string> names, tokens;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    std::istringstream fields(line);
    std::string a, b, extra;
    fields >> a >> b >> extra;
    if (a.empty() || a[0] == '#') continue;
    const std::string where = "--client-token-file '" + path.string() + "' line " + std::to_string(n);
    if (!extra.empty()) throw InputError(where + ": more than two fields (expected 'NAME TOKEN' or 'TOKEN')");
    NamedToken t = b.empty() ? NamedToken{"client", a} : NamedToken{a, b};
    if (!names.insert(t.name).second) throw InputError(where + ": the name '" + t.name + "' is used twice");
    if (!tokens.insert(t.token).second) throw InputError(where + ": this token is used twice");
    out.push_back(std::move(t));
  }
  if (out.empty()) throw InputError("--client-token-file '" + path.string() + "': no token in it");
  return out;
}

Authenticator::Authenticator(std::vector<NamedToken> clientTokens, std::string workerToken)
    : clients_(std::move(clientTokens)), worker_(std::move(workerToken)) {}

std::optional<std::string> Authenticator::clientTokenName(const std::string& token) const {
  std::optional<std::string> found;
  for (const auto& c : clients_)  // every token compared, so the time does not tell which matched
    if (wire::constantTimeEquals(token, c.token) && !found) found = c.name;
  return found;
}

grpc::Status Authenticator::check(const grpc::CallbackServerContext* ctx, CallerRole role, const char* method, std::string* name) const {
  if (!enabled(role)) return grpc::Status::OK;
  const char* api = role == CallerRole::Client ? "client" : "worker";
  auto refuse = [&](grpc::StatusCode code, const std::string& why) {
    spdlog::warn("{} call {} from {} refused: {}", api, method, ctx->peer(), why);
    return grpc::Status(code, why);
  };
  const auto& md = ctx->client_metadata();
  auto it = md.find("authorization");
  if (it == md.end()) return refuse(grpc::StatusCode::UNAUTHENTICATED, std::string("no bearer token (the ") + api + " API needs one)");
  const std::string value(it->second.data(), it->second.size());
  const std::string prefix = "Bearer ";
  if (value.compare(0, prefix.size(), prefix) != 0)
    return refuse(grpc::StatusCode::UNAUTHENTICATED, "the authorization header is not 'Bearer <token>'");
  const std::string token = value.substr(prefix.size());
  const bool isWorker = !worker_.empty() && wire::constantTimeEquals(token, worker_);
  const std::optional<std::string> client = clientTokenName(token);
  if (role == CallerRole::Worker ? isWorker : client.has_value()) {
    if (name && client) *name = *client;
    return grpc::Status::OK;
  }
  if (role == CallerRole::Worker ? client.has_value() : isWorker)
    return refuse(grpc::StatusCode::PERMISSION_DENIED, role == CallerRole::Worker ? "a client token cannot connect a worker"
                                                                                   : "a worker token cannot use the client API");
  return refuse(grpc::StatusCode::UNAUTHENTICATED, "invalid bearer token");
}

}  // namespace invr::server
