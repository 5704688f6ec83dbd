// The dashboard: a read-only web application that invr-server serves over HTTP, or HTTPS with
// the server's certificate (`--http-address`): the job list, a job's convergence, parameters and
// snapshots beside its targets, and the workers, updating live. The page polls a JSON API that
// scripts may use too (docs/dashboard.md). Its files, Chart.js included, are embedded in the
// binary: no CDN, no internet.
//
// With client tokens on, every /api/ call needs one: the page's sign-in form trades it for an
// HttpOnly, SameSite=Strict session cookie; scripts send `Authorization: Bearer TOKEN`. Nothing
// here changes a job; tokens never appear in a URL or a log line.
#pragma once

#include <memory>
#include <string>

namespace invr::server {

class JobBook;
class Scheduler;
class Authenticator;

struct DashboardOptions {
  std::string address;             // HOST:PORT, or a port alone (loopback); port 0 picks one
  std::string tlsCertPem, tlsKeyPem;  // both: HTTPS
  bool insecure = false;           // allow plain HTTP beyond loopback
  size_t maxSessions = 1024;       // signed-in browsers remembered; the oldest is dropped beyond
  double sessionHours = 12;        // a session cookie's lifetime
};

class Dashboard {
 public:
  // Listens at once (on its own threads). Throws InputError for a bad or refused address.
  Dashboard(DashboardOptions options, const JobBook& book, const Scheduler& scheduler, const Authenticator& auth);
  ~Dashboard();
  Dashboard(const Dashboard&) = delete;
  Dashboard& operator=(const Dashboard&) = delete;
  int port() const;
  std::string url() const;  // http(s)://host:port/

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace invr::server
