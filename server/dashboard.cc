#include "server/dashboard.h"

#include <httplib.h>
#include <openssl/pem.h>
#include <openssl/rand.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <chrono>
#include <fstream>
#include <functional>
#include <list>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>
#include <thread>

#include "core/error.h"
#include "core/image/image.h"
#include "proto/wire/json_lines.h"
#include "proto/wire/wire.h"
#include "server/auth.h"
#include "server/dashboard_assets.h"
#include "server/job_book.h"
#include "server/scheduler.h"

namespace invr::server {

namespace v1 = invr::v1;
using nlohmann::json;

namespace {


// Signed-in browsers: random session ids (what the cookie holds, never the token), bounded in
// number and lifetime so that an open page or many sign-ins cannot grow the server.
class SessionTable {
 public:
  SessionTable(size_t capacity, double hours) : capacity_(capacity), lifetime_(std::chrono::seconds(int64_t(hours * 3600))) {}

  std::string create(const std::string& name) {
    unsigned char raw[32];
    if (RAND_bytes(raw, sizeof raw) != 1) throw std::runtime_error("no randomness for a session id");
    static const char* hex = "0123456789abcdef";
    std::string id;
    for (unsigned char c : raw) id += {hex[c >> 4], hex[c & 15]};
    std::lock_guard<std::mutex> lk(mu_);
    order_.push_back(id);
    byId_[id] = {name, Clock::now() + lifetime_, std::prev(order_.end())};
    while (byId_.size() > capacity_) drop(order_.front());
    return id;
  }
  std::optional<std::string> find(const std::string& id) {
    std::lock_guard<std::mutex> lk(mu_);
    auto it = byId_.find(id);
    if (it == byId_.end()) return std::nullopt;
    if (Clock::now() > it->second.expires) {
      drop(id);
      return std::nullopt;
    }
    return it->second.name;
  }
  void remove(const std::string& id) {
    std::lock_guard<std::mutex> lk(mu_);
    if (byId_.count(id)) drop(id);
  }
  int maxAgeSeconds() const { return int(std::chrono::duration_cast<std::chrono::seconds>(lifetime_).count()); }

 private:
  using Clock = std::chrono::steady_clock;
  struct Entry {
    std::string name;
    Clock::time_point expires;
    std::list<std::string>::iterator pos;
  };
  void drop(const std::string& id) {
    auto it = byId_.find(id);
    order_.erase(it->second.pos);
    byId_.erase(it);
  }
  const size_t capacity_;
  const Clock::duration lifetime_;
  std::mutex mu_;
  std::list<std::string> order_;  // oldest first
  std::map<std::string, Entry> byId_;
};

// Content types spelled so that cpp-httplib does not compress the answer: it compresses exactly
// "application/json", "application/javascript" and text/*, and with brotli at its slowest
// quality (0.6 s for Chart.js, 0.2 s for a list of 100 jobs, measured); the page is served to
// one user, mostly over loopback, where bytes are cheap and that time is not.
constexpr const char* kJson = "application/json; charset=utf-8";
constexpr size_t kMaxBody = 64 * 1024;
constexpr const char* kJavaScript = "application/javascript; charset=utf-8";

std::string dump(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

// Messages as every JSON of invr has them (wire::jsonLine: `--json`, progress.jsonl, Python):
// field names as in the .proto files, enums by name, numbers as numbers, non-finite as null.
json messageJson(const google::protobuf::Message& m) { return json::parse(wire::jsonLine(m)); }

// What a job's page shows from its results: the latest snapshot per view beside the target (and
// the final render once there is one), and the texture parameters as images.
// A count from a result name's digits; nullopt when it does not fit (names come from the disk).
std::optional<uint64_t> number(const std::ssub_match& m) {
  uint64_t v = 0;
  auto [end, ec] = std::from_chars(&*m.first, &*m.first + m.length(), v);
  if (ec != std::errc() || end != &*m.first + m.length() || v > uint64_t(1) << 40) return std::nullopt;
  return v;
}

// The texture parameters of a parameters.json (name -> its file, relative to the results), or
// nothing when it cannot be read.
std::map<std::string, std::string> textureFiles(const std::function<std::optional<std::filesystem::path>(const std::string&)>& path,
                                                const std::string& prefix) {
  std::map<std::string, std::string> out;
  auto p = path(prefix + "parameters.json");
  if (!p) return out;
  try {
    std::ifstream in(*p);
    const json j = json::parse(in);
    for (const auto& [name, v] : j.items())
      if (v.is_object() && v.contains("texture") && v["texture"].is_string()) out[name] = prefix + v["texture"].get<std::string>();
  } catch (const std::exception&) {
  }
  return out;
}

json imagesJson(const v1::JobStatus& s, const std::function<std::optional<std::filesystem::path>(const std::string&)>& path) {
  static const std::regex snapshot(R"(snapshots/step(\d+)_view(\d+)\.png)");
  static const std::regex stepParameters(R"(snapshots/step(\d+)/parameters\.json)");
  std::set<std::string> have(s.results().begin(), s.results().end());
  static const std::regex target(R"((?:snapshots/)?target_view(\d+)\.png)");
  static const std::regex final(R"(final_view(\d+)\.png)");
  uint64_t latest = 0;
  std::smatch m;
  uint64_t latestParameters = 0;  // a snapshot's parameters are written even when its renders fail
  for (const auto& r : have) {
    if (std::regex_match(r, m, snapshot))
      if (auto k = number(m[1])) latest = std::max(latest, *k);
    if (std::regex_match(r, m, stepParameters))
      if (auto k = number(m[1])) latestParameters = std::max(latestParameters, *k);
  }
  // A PNG's radiance twin, when the results hold it: what the exposure control scales.
  auto hdr = [&](const std::string& png) -> json {
    const std::string exr = png.substr(0, png.size() - 4) + ".exr";
    return have.count(exr) ? json(exr) : json(nullptr);
  };
  std::map<uint64_t, json> views;
  auto view = [&](uint64_t v) -> json& {
    auto& j = views[v];
    if (j.is_null())
      j = json{{"view", v},          {"snapshot", nullptr},     {"target", nullptr},    {"final", nullptr},
               {"snapshot_hdr", nullptr}, {"target_hdr", nullptr}, {"final_hdr", nullptr}};
    return j;
  };
  for (const auto& r : have) {
    if (std::regex_match(r, m, snapshot) && number(m[1]) == latest)
      if (auto v = number(m[2])) view(*v)["snapshot"] = r, view(*v)["snapshot_hdr"] = hdr(r);
    if (std::regex_match(r, m, target))
      if (auto v = number(m[1])) view(*v)["target"] = r, view(*v)["target_hdr"] = hdr(r);
    if (std::regex_match(r, m, final))
      if (auto v = number(m[1])) view(*v)["final"] = r, view(*v)["final_hdr"] = hdr(r);
  }
  // Textures by parameter name: the latest snapshot's (the results' once the job has ended),
  // beside the truth when the job knows it (truth/, written when a synthetic job starts).
  const bool finished = finishedState(s.state()) && have.count("parameters.json");
  const std::string prefix = finished ? "" : "snapshots/step" + std::to_string(latestParameters) + "/";
  const auto truth = textureFiles(path, "truth/");
  json textures = json::array();
  if (finished || latestParameters > 0)
    for (const auto& [name, file] : textureFiles(path, prefix)) {
      auto t = truth.find(name);
      textures.push_back(json{{"parameter", name}, {"file", file}, {"truth", t == truth.end() ? json(nullptr) : json(t->second)}});
    }
  json v = json::array();
  for (auto& [k, j] : views) v.push_back(std::move(j));
  return json{{"snapshot_step", latest}, {"views", std::move(v)}, {"textures", std::move(textures)}};
}

std::string readFile(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream o;
  o << in.rdbuf();
  return o.str();
}

std::string contentType(const std::string& name) {
  auto ends = [&](const char* e) { return name.size() >= strlen(e) && name.compare(name.size() - strlen(e), strlen(e), e) == 0; };
  if (ends(".png")) return "image/png";
  if (ends(".json") || ends(".jsonl")) return kJson;
  if (ends(".csv")) return "text/csv; charset=utf-8";
  return "application/octet-stream";
}

// HOST:PORT, or a port alone (loopback).
std::pair<std::string, int> splitAddress(const std::string& address) {
  std::string a = address.find(':') == std::string::npos ? "127.0.0.1:" + address : address;
  auto colon = a.rfind(':');
  std::string host = a.substr(0, colon);
  if (host.size() > 1 && host.front() == '[') host = host.substr(1, host.size() - 2);
  try {
    size_t used = 0;
    int port = std::stoi(a.substr(colon + 1), &used);
    if (used != a.size() - colon - 1 || port < 0 || port > 65535) throw std::invalid_argument("port");
    return {host, port};
  } catch (const std::exception&) {
    throw InputError("--http-address '" + address + "': expected HOST:PORT or PORT");
  }
}

std::unique_ptr<httplib::Server> makeServer(const DashboardOptions& o) {
  if (o.tlsCertPem.empty()) return std::make_unique<httplib::Server>();
  auto pem = [](const std::string& text) { return BIO_new_mem_buf(text.data(), int(text.size())); };
  BIO* cb = pem(o.tlsCertPem);
  BIO* kb = pem(o.tlsKeyPem);
  X509* cert = PEM_read_bio_X509(cb, nullptr, nullptr, nullptr);
  EVP_PKEY* key = PEM_read_bio_PrivateKey(kb, nullptr, nullptr, nullptr);
  BIO_free(cb);
  BIO_free(kb);
  if (!cert || !key) {
    X509_free(cert);
    EVP_PKEY_free(key);
    throw InputError("--http-address: cannot read the TLS certificate or key (PEM)");
  }
  auto s = std::make_unique<httplib::SSLServer>(cert, key);  // the context keeps its own references
  X509_free(cert);
  EVP_PKEY_free(key);
  if (!s->is_valid()) throw InputError("--http-address: the TLS certificate and key do not make a valid HTTPS server");
  return s;
}

}  // namespace

struct Dashboard::Impl {
  DashboardOptions opt;
  const JobBook& book;
  const Scheduler& scheduler;
  const Authenticator& auth;
  SessionTable sessions;
  std::unique_ptr<httplib::Server> http;
  std::thread thread;
  std::string host;
  int port = 0;
  bool loopbackOnly = true;

  Impl(DashboardOptions o, const JobBook& b, const Scheduler& s, const Authenticator& a)
      : opt(std::move(o)), book(b), scheduler(s), auth(a), sessions(opt.maxSessions, opt.sessionHours) {}

  static void error(httplib::Response& res, int status, const std::string& message) {
    res.status = status;
    res.set_content(dump(json{{"error", message}}), kJson);
  }

  // The session cookie, named by port: cookies are not told apart by port, and two servers on
  // one host must not sign each other's browsers out.
  std::string cookieName() const { return "invr_session_" + std::to_string(port); }

  std::string cookieValue(const httplib::Request& req) const {
    const std::string all = req.get_header_value("Cookie");
    std::istringstream in(all);
    std::string part;
    while (std::getline(in, part, ';')) {
      size_t b = part.find_first_not_of(' ');
      if (b == std::string::npos) continue;
      part = part.substr(b);
      const std::string prefix = cookieName() + "=";
      if (part.compare(0, prefix.size(), prefix) == 0) return part.substr(prefix.size());
    }
    return "";
  }

  // Who is asking: the token's (or session's) name, "" when client tokens are off; nullopt
  // (and a 401 answer) when it cannot be told.
  std::optional<std::string> caller(const httplib::Request& req, httplib::Response& res) {
    if (!auth.enabled(CallerRole::Client)) return std::string();
    const std::string authz = req.get_header_value("Authorization");
    if (!authz.empty()) {
      const std::string prefix = "Bearer ";
      if (authz.compare(0, prefix.size(), prefix) == 0)
        if (auto name = auth.clientTokenName(authz.substr(prefix.size()))) return name;
      spdlog::warn("dashboard: a call from {} refused: invalid bearer token", req.remote_addr);
      error(res, 401, "invalid bearer token");
      return std::nullopt;
    }
    if (const std::string sid = cookieValue(req); !sid.empty())
      if (auto name = sessions.find(sid)) return name;
    error(res, 401, "sign in with a client token (the page's form, or the header 'Authorization: Bearer TOKEN')");
    return std::nullopt;
  }

  // A state-changing call (sign-in, sign-out) must come from this origin: JSON only (a form on
  // another site cannot send it without a CORS preflight, which is never granted) and, when the
  // browser says where it comes from, this host.
  static bool sameOrigin(const httplib::Request& req, httplib::Response& res) {
    const std::string type = req.get_header_value("Content-Type");
    if (type.compare(0, 16, "application/json") != 0) {
      error(res, 415, "send JSON (Content-Type: application/json)");
      return false;
    }
    const std::string origin = req.get_header_value("Origin");
    const std::string host = req.get_header_value("Host");
    if (!origin.empty() && origin != "http://" + host && origin != "https://" + host) {
      error(res, 403, "cross-origin request refused");
      return false;
    }
    return true;
  }

  void routes() {
    httplib::Server& s = *http;
    auto asset = [&s](const char* path, const EmbeddedFile& f, const char* type) {
      s.Get(path, [f, type](const httplib::Request&, httplib::Response& res) {
        res.set_content(f.data, f.size, type);
        res.set_header("Cache-Control", "no-cache");
      });
    };
    asset("/", dashboardFile("index.html"), "text/html; charset=utf-8");
    asset("/app.js", dashboardFile("app.js"), kJavaScript);
    asset("/style.css", dashboardFile("style.css"), "text/css; charset=utf-8");
    asset("/chart.min.js", dashboardFile("chart.min.js"), kJavaScript);

    s.Get("/api/session", [this](const httplib::Request& req, httplib::Response& res) {
      json j{{"auth_required", auth.enabled(CallerRole::Client)}, {"signed_in", false}, {"name", ""}};
      if (!auth.enabled(CallerRole::Client)) {
        j["signed_in"] = true;
      } else if (const std::string sid = cookieValue(req); !sid.empty()) {
        if (auto name = sessions.find(sid)) j["signed_in"] = true, j["name"] = *name;
      }
      res.set_content(dump(j), kJson);
    });
    s.Post("/api/login", [this](const httplib::Request& req, httplib::Response& res) {
      if (!sameOrigin(req, res)) return;
      std::string token;
      try {
        token = json::parse(req.body).at("token").get<std::string>();
      } catch (const std::exception&) {
        return error(res, 400, "expected {\"token\": \"...\"}");
      }
      if (!auth.enabled(CallerRole::Client)) return error(res, 400, "this server checks no client tokens: nothing to sign in to");
      auto name = auth.clientTokenName(token);
      if (!name) {
        spdlog::warn("dashboard: sign-in from {} refused: not a client token", req.remote_addr);
        return error(res, 401, "not a client token of this server");
      }
      const std::string sid = sessions.create(*name);
      res.set_header("Set-Cookie", cookieName() + "=" + sid + "; Path=/; HttpOnly; SameSite=Strict; Max-Age=" +
                                       std::to_string(sessions.maxAgeSeconds()) + (opt.tlsCertPem.empty() ? "" : "; Secure"));
      spdlog::info("dashboard: {} signed in from {}", *name, req.remote_addr);
      res.set_content(dump(json{{"name", *name}}), kJson);
    });
    s.Post("/api/logout", [this](const httplib::Request& req, httplib::Response& res) {
      if (!sameOrigin(req, res)) return;
      if (const std::string sid = cookieValue(req); !sid.empty()) sessions.remove(sid);
      res.set_header("Set-Cookie", cookieName() + "=; Path=/; HttpOnly; SameSite=Strict; Max-Age=0");
      res.set_content("{}", kJson);
    });

    s.Get("/api/jobs", [this](const httplib::Request& req, httplib::Response& res) {
      if (!caller(req, res)) return;
      json jobs = json::array();
      for (const auto& st : book.list()) jobs.push_back(messageJson(st));
      res.set_content(dump(json{{"jobs", std::move(jobs)}}), kJson);
    });
    s.Get(R"(/api/jobs/([A-Za-z0-9._-]+))", [this](const httplib::Request& req, httplib::Response& res) {
      if (!caller(req, res)) return;
      v1::JobStatus st;
      if (grpc::Status g = book.status(req.matches[1], &st); !g.ok()) return error(res, 404, g.error_message());
      json j = messageJson(st);
      const std::string id = req.matches[1];
      j["images"] = imagesJson(st, [&](const std::string& name) -> std::optional<std::filesystem::path> {
        std::filesystem::path p;
        if (!book.resultPath(id, name, &p).ok()) return std::nullopt;
        return p;
      });
      res.set_content(dump(j), kJson);
    });
    s.Get(R"(/api/jobs/([A-Za-z0-9._-]+)/events)", [this](const httplib::Request& req, httplib::Response& res) {
      if (!caller(req, res)) return;
      uint64_t from = 1;
      size_t max = 1000;
      try {
        if (req.has_param("from")) from = std::stoull(req.get_param_value("from"));
        if (req.has_param("max")) max = std::clamp<size_t>(std::stoull(req.get_param_value("max")), 1, 5000);
      } catch (const std::exception&) {
        return error(res, 400, "from and max are counts");
      }
      std::vector<v1::ProgressEvent> events;
      if (grpc::Status g = book.events(req.matches[1], from, max, &events); !g.ok()) return error(res, 404, g.error_message());
      json out = json::array();
      uint64_t next = from;
      for (const auto& e : events) {
        out.push_back(messageJson(e));
        next = e.sequence() + 1;
      }
      res.set_content(dump(json{{"events", std::move(out)}, {"next", next}}), kJson);
    });
    // An exposure that shows an HDR image: the one that maps the 99th percentile of its luminance
    // to white (an oxalis target: spot pools at 147 over a median of 0.008).
    s.Get(R"(/api/jobs/([A-Za-z0-9._-]+)/exposure)", [this](const httplib::Request& req, httplib::Response& res) {
      if (!caller(req, res)) return;
      const std::string name = req.get_param_value("name");
      std::filesystem::path path;
      if (grpc::Status g = book.resultPath(req.matches[1], name, &path); !g.ok()) return error(res, 404, g.error_message());
      if (!(name.size() > 4 && name.compare(name.size() - 4, 4, ".exr") == 0)) return error(res, 415, "an exposure is computed from an EXR");
      try {
        const Image im = readImage(path, false);
        std::vector<float> lum;
        lum.reserve(size_t(im.width()) * size_t(im.height()));
        const int c = im.channels();
        for (size_t i = 0; i + size_t(c) <= im.data().size(); i += size_t(c)) {
          const float* px = &im.data()[i];
          const float y = c >= 3 ? 0.2126f * px[0] + 0.7152f * px[1] + 0.0722f * px[2] : px[0];
          if (std::isfinite(y)) lum.push_back(y);
        }
        double p99 = 0;
        if (!lum.empty()) {
          auto at = lum.begin() + std::ptrdiff_t(double(lum.size() - 1) * 0.99);
          std::nth_element(lum.begin(), at, lum.end());
          p99 = *at;
        }
        const double ev = p99 > 0 ? std::clamp(-std::log2(p99), -16.0, 16.0) : 0.0;
        res.set_content(dump(json{{"ev", ev}, {"percentile", 99}, {"luminance", p99}}), kJson);
      } catch (const std::exception& e) {
        return error(res, 500, std::string("cannot read '") + name.substr(0, 256) + "': " + e.what());
      }
    });
    // A result file as it is (`file`), or as a PNG the browser can show (`image`: PNGs as they
    // are, EXR textures and renders converted at `exposure` stops (default 0), clamped and
    // sRGB-encoded).
    auto file = [this](bool asImage) {
      return [this, asImage](const httplib::Request& req, httplib::Response& res) {
        if (!caller(req, res)) return;
        const std::string name = req.get_param_value("name");
        double ev = 0;
        if (req.has_param("exposure")) {
          const std::string text = req.get_param_value("exposure");
          char* end = nullptr;
          ev = std::strtod(text.c_str(), &end);
          if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(ev) || std::abs(ev) > 32)
            return error(res, 400, "exposure: a number of stops in [-32, 32]");
        }
        std::filesystem::path path;
        if (grpc::Status g = book.resultPath(req.matches[1], name, &path); !g.ok()) return error(res, 404, g.error_message());
        const bool png = contentType(name) == "image/png";
        const bool exr = name.size() > 4 && name.compare(name.size() - 4, 4, ".exr") == 0;
        if (asImage && !png && !exr) return error(res, 415, "'" + name.substr(0, 256) + "' is not an image");
        try {
          if (asImage && exr) {
            // Through a file of our own (O_EXCL, private), removed whatever happens.
            std::string tmp = (std::filesystem::temp_directory_path() / "invr-dashboard-XXXXXX.png").string();
            const int fd = ::mkstemps(tmp.data(), 4);
            if (fd < 0) throw std::runtime_error("no temporary file for the conversion");
            ::close(fd);
            struct Remove {
              std::string path;
              ~Remove() { std::filesystem::remove(path); }
            } remove{tmp};
            Image im = readImage(path, false);
            if (ev != 0) {
              const float scale = float(std::exp2(ev));
              for (float& v : im.data()) v *= scale;
            }
            writeImage(tmp, im);
            res.set_content(readFile(tmp), "image/png");
          } else {
            res.set_content(readFile(path), contentType(name));
            if (!asImage) res.set_header("Content-Disposition", "attachment");
          }
        } catch (const std::exception& e) {
          return error(res, 500, std::string("cannot read '") + name.substr(0, 256) + "': " + e.what());
        }
      };
    };
    s.Get(R"(/api/jobs/([A-Za-z0-9._-]+)/file)", file(false));
    s.Get(R"(/api/jobs/([A-Za-z0-9._-]+)/image)", file(true));
    s.Get("/api/workers", [this](const httplib::Request& req, httplib::Response& res) {
      if (!caller(req, res)) return;
      json workers = json::array();
      for (const auto& w : scheduler.workers()) workers.push_back(messageJson(w));
      res.set_content(dump(json{{"workers", std::move(workers)}}), kJson);
    });

    // On loopback, only requests that name a loopback host: a web page elsewhere that points
    // its own name at 127.0.0.1 (DNS rebinding) gets nothing, tokens or not.
    // Before any body is read: bodies are small JSON with a declared length (the largest it takes
    // is a sign-in), so that nobody can make the server hold a large one, compressed or chunked.
    // And on loopback, only requests that name a loopback host: a web page elsewhere that points
    // its own name at 127.0.0.1 (DNS rebinding) gets nothing, tokens or not.
    s.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
      auto refuse = [&](int status, const std::string& why) {
        error(res, status, why);
        res.set_header("Connection", "close");  // an unread body must not be taken for the next request
        return httplib::Server::HandlerResponse::Handled;
      };
      if (req.has_header("Transfer-Encoding") || req.has_header("Content-Encoding"))
        return refuse(415, "send the body plain, with a Content-Length");
      if (req.method != "GET" && req.method != "HEAD") {
        if (!req.has_header("Content-Length")) return refuse(411, "a Content-Length is needed");
        uint64_t length = 0;
        const std::string v = req.get_header_value("Content-Length");
        auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), length);
        if (ec != std::errc() || end != v.data() + v.size() || length > kMaxBody) return refuse(413, "bodies are at most 64 KiB");
      }
      if (!loopbackOnly) return httplib::Server::HandlerResponse::Unhandled;
      const std::string host = req.get_header_value("Host");
      const bool defaultPort = port == (opt.tlsCertPem.empty() ? 80 : 443);
      for (const char* h : {"127.0.0.1", "localhost", "[::1]"})
        if (host == h + (":" + std::to_string(port)) || (defaultPort && host == h)) return httplib::Server::HandlerResponse::Unhandled;
      return refuse(421, "this dashboard answers to 127.0.0.1, localhost or [::1] on port " + std::to_string(port) + " only");
    });
    s.set_payload_max_length(kMaxBody);

    // Every answer: no framing, no sniffing, no referrer, scripts and styles from here only (a
    // name that slipped past the page's escaping still could not run), API answers not cached.
    s.set_post_routing_handler([](const httplib::Request& req, httplib::Response& res) {
      res.set_header("Content-Security-Policy",
                     "default-src 'self'; img-src 'self'; script-src 'self'; style-src 'self'; object-src 'none'; "
                     "base-uri 'none'; frame-ancestors 'none'; form-action 'self'");
      res.set_header("X-Content-Type-Options", "nosniff");
      res.set_header("X-Frame-Options", "DENY");
      res.set_header("Referrer-Policy", "no-referrer");
      if (req.path.compare(0, 5, "/api/") == 0 && !res.has_header("Cache-Control")) res.set_header("Cache-Control", "no-store");
    });
  }
};

Dashboard::Dashboard(DashboardOptions options, const JobBook& book, const Scheduler& scheduler, const Authenticator& auth)
    : impl_(std::make_unique<Impl>(std::move(options), book, scheduler, auth)) {
  Impl& d = *impl_;
  auto [host, port] = splitAddress(d.opt.address);
  if (host == "localhost") host = "127.0.0.1";  // the name may resolve to ::1 first; the page is at 127.0.0.1
  const std::string hostPort = (host.find(':') != std::string::npos ? "[" + host + "]" : host) + ":" + std::to_string(port);
  d.loopbackOnly = wire::isLoopbackAddress(hostPort);
  if (!d.loopbackOnly && d.opt.tlsCertPem.empty()) {
    if (!d.opt.insecure)
      throw InputError("--http-address " + d.opt.address + " is not loopback: it needs TLS (--tls-cert and --tls-key) or --insecure");
    spdlog::warn("dashboard on {} without TLS (--insecure): anyone on the network can read it{}", hostPort,
                 d.auth.enabled(CallerRole::Client) ? ", session cookies included" : ", and without a client token anyone can open it");
  } else if (!d.loopbackOnly && !d.auth.enabled(CallerRole::Client)) {
    // Client certificates guard the gRPC port only: a browser brings none here.
    if (!d.opt.insecure)
      throw InputError("--http-address " + d.opt.address + " is not loopback: it needs client tokens (--client-token-file) or --insecure");
    spdlog::warn("dashboard on {} without client tokens (--insecure): anyone who reaches it can read every job", hostPort);
  }
  d.http = makeServer(d.opt);
  d.routes();
  d.host = host;
  d.port = port == 0 ? d.http->bind_to_any_port(host) : (d.http->bind_to_port(host, port) ? port : -1);
  if (d.port <= 0) throw InputError("--http-address " + d.opt.address + ": cannot listen there (address in use, or not a local address)");
  d.thread = std::thread([&d] { d.http->listen_after_bind(); });
  // stop() does nothing until the listener runs: wait for it, so that a quick shutdown cannot hang.
  for (int i = 0; i < 5000 && !d.http->is_running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

Dashboard::~Dashboard() {
  impl_->http->stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

int Dashboard::port() const { return impl_->port; }

std::string Dashboard::url() const {
  const std::string& h = impl_->host;
  return std::string(impl_->opt.tlsCertPem.empty() ? "http" : "https") + "://" + (h.find(':') != std::string::npos ? "[" + h + "]" : h) +
         ":" + std::to_string(impl_->port) + "/";
}

}  // namespace invr::server
