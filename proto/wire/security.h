// Transport security shared by client, worker and server: TLS credentials and bearer tokens.
//
// Clients and workers send `authorization: Bearer <token>` with every call; the server keeps one
// token for clients and a different one for workers. Tokens and keys are read from files (or an
// environment variable) so they never appear on a command line or in a process listing.
#pragma once

#include <grpcpp/grpcpp.h>

#include <filesystem>
#include <memory>
#include <string>

namespace invr::wire {

// A caller's side of a connection.
struct ClientSecurity {
  std::string caPem;          // non-empty: TLS, trusting this CA for the server's certificate
  std::string certPem;        // with keyPem: a client certificate (mutual TLS)
  std::string keyPem;
  std::string serverName;     // expected name in the server's certificate (default: the address's host)
  std::string token;          // bearer token sent with every call (empty: none)
  bool tls() const { return !caPem.empty(); }
};

// The contents of a PEM or token file; errors name `what` and the file. Tokens are trimmed of
// surrounding whitespace and must not be empty.
std::string readPemFile(const std::filesystem::path& path, const std::string& what);
std::string readTokenFile(const std::filesystem::path& path, const std::string& what);

// ClientSecurity from the command-line files; the token from `tokenFile`, else from the
// environment variable `tokenEnv` (when set and not empty).
ClientSecurity loadClientSecurity(const std::string& caFile, const std::string& certFile, const std::string& keyFile,
                                  const std::string& serverName, const std::string& tokenFile, const char* tokenEnv);

// Adds the bearer token (if any) to a call.
void addToken(grpc::ClientContext& ctx, const ClientSecurity& security);

// Equal strings, in time that depends only on their lengths' digests (tokens are compared
// through their SHA-256, so neither their content nor their length leaks).
bool constantTimeEquals(const std::string& a, const std::string& b);

// Whether a listen address binds only the loopback interface.
bool isLoopbackAddress(const std::string& address);

}  // namespace invr::wire
