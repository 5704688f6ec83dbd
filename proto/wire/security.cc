#include "proto/wire/security.h"

#include <openssl/crypto.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "proto/wire/sha256.h"

namespace invr::wire {

namespace {

std::string readAll(const std::filesystem::path& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(what + " '" + path.string() + "': cannot read");
  std::ostringstream s;
  s << in.rdbuf();
  if (s.str().size() > (1u << 20)) throw std::runtime_error(what + " '" + path.string() + "': larger than 1 MiB");
  return s.str();
}

std::string trim(const std::string& s) {
  const char* ws = " \t\r\n";
  size_t a = s.find_first_not_of(ws);
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(ws) - a + 1);
}

}  // namespace

std::string readPemFile(const std::filesystem::path& path, const std::string& what) {
  std::string pem = readAll(path, what);
  if (pem.find("-----BEGIN ") == std::string::npos) throw std::runtime_error(what + " '" + path.string() + "': not a PEM file");
  return pem;
}

std::string readTokenFile(const std::filesystem::path& path, const std::string& what) {
  std::string t = trim(readAll(path, what));
  if (t.empty()) throw std::runtime_error(what + " '" + path.string() + "': empty");
  if (t.find_first_of("\r\n") != std::string::npos) throw std::runtime_error(what + " '" + path.string() + "': more than one line");
  return t;
}

ClientSecurity loadClientSecurity(const std::string& caFile, const std::string& certFile, const std::string& keyFile,
                                  const std::string& serverName, const std::string& tokenFile, const char* tokenEnv) {
  ClientSecurity s;
  if (!caFile.empty()) s.caPem = readPemFile(caFile, "--tls-ca");
  if (certFile.empty() != keyFile.empty()) throw std::runtime_error("--tls-cert and --tls-key go together (a client certificate and its key)");
  if (!certFile.empty()) {
    if (caFile.empty()) throw std::runtime_error("--tls-cert needs --tls-ca (the CA that signed the server's certificate)");
    s.certPem = readPemFile(certFile, "--tls-cert");
    s.keyPem = readPemFile(keyFile, "--tls-key");
  }
  s.serverName = serverName;
  if (!tokenFile.empty()) {
    s.token = readTokenFile(tokenFile, "--token-file");
  } else if (tokenEnv) {
    if (const char* env = std::getenv(tokenEnv)) s.token = trim(env);
  }
  return s;
}

void addToken(grpc::ClientContext& ctx, const ClientSecurity& security) {
  if (!security.token.empty()) ctx.AddMetadata("authorization", "Bearer " + security.token);
}

bool constantTimeEquals(const std::string& a, const std::string& b) {
  server::Sha256 ha, hb;
  ha.update(a.data(), a.size());
  hb.update(b.data(), b.size());
  const std::string da = ha.hex(), db = hb.hex();  // both 64 characters
  return CRYPTO_memcmp(da.data(), db.data(), da.size()) == 0;
}

bool isLoopbackAddress(const std::string& address) {
  for (const char* p : {"127.0.0.1:", "localhost:", "[::1]:"})
    if (address.rfind(p, 0) == 0) return true;
  return false;
}

}  // namespace invr::wire
