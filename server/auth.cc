#include "server/auth.h"

#include <spdlog/spdlog.h>

#include "proto/wire/security.h"

namespace invr::server {

Authenticator::Authenticator(std::string clientToken, std::string workerToken)
    : client_(std::move(clientToken)), worker_(std::move(workerToken)) {}

grpc::Status Authenticator::check(const grpc::CallbackServerContext* ctx, CallerRole role, const char* method) const {
  const std::string& expected = role == CallerRole::Client ? client_ : worker_;
  if (expected.empty()) return grpc::Status::OK;
  const std::string& other = role == CallerRole::Client ? worker_ : client_;
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
  if (wire::constantTimeEquals(token, expected)) return grpc::Status::OK;
  if (!other.empty() && wire::constantTimeEquals(token, other))
    return refuse(grpc::StatusCode::PERMISSION_DENIED, role == CallerRole::Worker ? "a client token cannot connect a worker"
                                                                                   : "a worker token cannot use the client API");
  return refuse(grpc::StatusCode::UNAUTHENTICATED, "invalid bearer token");
}

}  // namespace invr::server
