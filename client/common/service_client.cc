#include "client/common/service_client.h"

#include <google/protobuf/util/json_util.h>

#include <cstdio>
#include <fstream>
#include <functional>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "client/common/exit_codes.h"
#include "client/common/job_argument.h"
#include "core/io/mitsuba_import.h"
#include "core/diff/gradient_stats.h"
#include "core/error.h"
#include "core/io/job_io.h"
#include "proto/wire/json_lines.h"
#include "proto/wire/wire.h"

namespace invr::cli {

namespace v1 = invr::v1;

void throwIfFailed(const grpc::Status& st, const std::string& what) {
  if (st.ok()) return;
  switch (st.error_code()) {
    case grpc::StatusCode::UNAVAILABLE:
    case grpc::StatusCode::DEADLINE_EXCEEDED:
      throw ExitError(exit_code::kServerUnavailable, what + ": server unavailable (" + st.error_message() + ")");
    case grpc::StatusCode::INVALID_ARGUMENT:
    case grpc::StatusCode::NOT_FOUND:
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
    case grpc::StatusCode::FAILED_PRECONDITION:
    case grpc::StatusCode::ALREADY_EXISTS:
      throw ExitError(exit_code::kInputError, what + ": " + st.error_message());
    case grpc::StatusCode::UNAUTHENTICATED:
    case grpc::StatusCode::PERMISSION_DENIED:
      throw ExitError(exit_code::kRefused, what + ": refused by the server: " + st.error_message() +
                                               " (the client token: --token-file or $INVR_TOKEN)");
    default:
      throw ExitError(exit_code::kInternal, what + ": " + st.error_message() + " (gRPC code " + std::to_string(int(st.error_code())) + ")");
  }
}

int exitCodeFor(v1::JobState s) {
  switch (s) {
    case v1::SUCCEEDED: return exit_code::kOk;
    case v1::CANCELLED: return exit_code::kCancelled;
    default: return exit_code::kJobFailed;
  }
}

ServiceClient::ServiceClient(const std::string& address, wire::ClientSecurity security)
    : address_(address), security_(std::move(security)), channel_(wire::channel(address, security_)) {
  stub_ = v1::InvrService::NewStub(channel_);
}

std::string ServiceClient::upload(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError("'" + file.string() + "': cannot read");
  grpc::ClientContext ctx;
  wire::addToken(ctx, security_);
  v1::AssetInfo info;
  auto w = stub_->UploadAsset(&ctx, &info);
  std::string buf(wire::kChunkBytes, '\0');
  while (in) {
    in.read(buf.data(), std::streamsize(buf.size()));
    v1::AssetChunk c;
    c.set_data(buf.data(), size_t(in.gcount()));
    if (!w->Write(c)) break;  // the server ended the call early; Finish says why
  }
  w->WritesDone();
  throwIfFailed(w->Finish(), "upload '" + file.string() + "'");
  return info.sha256();
}

void ServiceClient::uploadAssets(v1::JobSpec& job, const std::filesystem::path& baseDir) {
  forEachAssetRef(job, [&](v1::AssetRef& ref, const std::string& field) {
    if (!ref.has_path()) return;
    std::filesystem::path p(ref.path());
    if (p.is_relative()) p = baseDir / p;
    if (!std::filesystem::exists(p)) throw InputError(field + ".path: file '" + p.string() + "' not found");
    ref.set_sha256(upload(p));
  });
}

namespace {

// One unary call: the response, or an ExitError naming what failed.
template <class Resp, class Req, class Method>
Resp unary(v1::InvrService::Stub& stub, const wire::ClientSecurity& security, Method method, const Req& req, const std::string& what) {
  grpc::ClientContext ctx;
  wire::addToken(ctx, security);
  Resp resp;
  throwIfFailed((stub.*method)(&ctx, req, &resp), what);
  return resp;
}

v1::GetJobRequest jobRequest(const std::string& id) {
  v1::GetJobRequest r;
  r.set_job_id(id);
  return r;
}

}  // namespace

namespace {

// A job's JSON with every file it names by an absolute path uploaded and named by content: the
// server reads no file of this machine. The text as it was when nothing changed (its line numbers
// stay those of the user's file), or when it does not parse (the server names the error).
std::string absolutePathsByContent(const std::string& text, ServiceClient& c) {
  nlohmann::json doc = nlohmann::json::parse(text, nullptr, false);
  if (doc.is_discarded()) return text;
  bool changed = false;
  std::function<void(nlohmann::json&)> walk = [&](nlohmann::json& node) {
    if (node.is_object()) {
      for (auto& [key, v] : node.items()) {
        if (key != "mitsuba" && v.is_object() && v.size() == 1 && v.contains("path") && v["path"].is_string() &&
            std::filesystem::path(v["path"].get<std::string>()).is_absolute()) {
          const std::filesystem::path file = v["path"].get<std::string>();
          if (!std::filesystem::exists(file)) throw InputError(key + ".path: file '" + file.string() + "' not found");
          v = nlohmann::json{{"sha256", c.upload(file)}};
          changed = true;
        } else {
          walk(v);
        }
      }
    } else if (node.is_array()) {
      for (auto& v : node) walk(v);
    }
  };
  walk(doc);
  return changed ? doc.dump() : text;
}

}  // namespace

v1::JobSpec ServiceClient::resolve(const std::string& arg, const std::vector<std::string>& defines, const std::vector<std::string>& params,
                                   const std::vector<std::string>& sets, bool forOptimization) {
  namespace fs = std::filesystem;
  v1::ResolveJobRequest req;
  fs::path base = ".";
  auto readText = [](std::istream& in) {
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
  };
  // A job's JSON is checked here first (the same parser as the server's): a mistake in it is
  // named, by line and column, without a server.
  if (arg == "-") {  // the job's JSON on standard input; its relative paths from the working directory
    const std::string text = readText(std::cin);
    parseJobJson(text, "<stdin>");
    req.set_job_json(absolutePathsByContent(text, *this));
    req.set_name("<stdin>");
  } else if (isJobFile(arg)) {
    if (!fs::exists(arg)) throw InputError("job file '" + arg + "': not found");
    std::ifstream in(arg);
    if (!in) throw InputError("job file '" + arg + "': cannot open");
    base = fs::path(arg).has_parent_path() ? fs::path(arg).parent_path() : fs::path(".");
    const std::string text = readText(in);
    parseJobJson(text, arg);
    req.set_job_json(absolutePathsByContent(text, *this));
    req.set_name(arg);
  } else if (isMitsubaSceneFile(arg)) {
    if (!fs::exists(arg)) throw InputError("Mitsuba scene '" + arg + "': not found");
    base = fs::path(arg).has_parent_path() ? fs::path(arg).parent_path() : fs::path(".");
    const std::string key = fs::path(arg).filename().string();
    (*req.mutable_files())[key] = upload(arg);
    req.set_mitsuba_xml(key);
  } else {
    req.set_zoo(arg);
  }
  for (const auto& d : defines) req.add_defines(d);
  for (const auto& p : params) req.add_params(p);
  for (const auto& s : sets) req.add_sets(s);
  req.set_for_optimization(forOptimization);
  for (int round = 0; round < 64; ++round) {  // a Mitsuba <include> names its files once it is there
    const auto resp = unary<v1::ResolveJobResponse>(*stub_, security_, &v1::InvrService::Stub::ResolveJob, req, "resolve '" + arg + "'");
    for (const auto& w : resp.warnings()) std::cerr << "warning: " << w << "\n";
    if (resp.missing_files_size() == 0) return resp.spec();
    for (const auto& name : resp.missing_files()) {
      if (req.files().count(name)) throw ExitError(exit_code::kInternal, "the server asks again for '" + name + "', which was uploaded");
      const fs::path f = base / name;
      if (!fs::exists(f)) throw InputError("'" + arg + "' names '" + name + "', which is not at '" + f.string() + "'");
      (*req.mutable_files())[name] = upload(f);
    }
  }
  throw ExitError(exit_code::kInternal, "'" + arg + "': its files were still incomplete after 64 rounds of uploads");
}

v1::SubmitJobResponse ServiceClient::submit(const v1::JobSpec& job, const std::string& requestId) {
  v1::SubmitJobRequest req;
  req.set_request_id(requestId);
  *req.mutable_spec() = job;
  return unary<v1::SubmitJobResponse>(*stub_, security_, &v1::InvrService::Stub::SubmitJob, req, "submit");
}

v1::JobPlan ServiceClient::plan(const v1::JobSpec& job) {
  v1::PlanJobRequest req;
  *req.mutable_spec() = job;
  return unary<v1::JobPlan>(*stub_, security_, &v1::InvrService::Stub::PlanJob, req, "plan");
}

v1::SceneDescription ServiceClient::describe(const v1::JobSpec& job) {
  v1::DescribeSceneRequest req;
  *req.mutable_spec() = job;
  return unary<v1::SceneDescription>(*stub_, security_, &v1::InvrService::Stub::DescribeScene, req, "params");
}

v1::JobStatus ServiceClient::get(const std::string& job) {
  return unary<v1::JobStatus>(*stub_, security_, &v1::InvrService::Stub::GetJob, jobRequest(job), "status");
}

v1::ListJobsResponse ServiceClient::list() {
  return unary<v1::ListJobsResponse>(*stub_, security_, &v1::InvrService::Stub::ListJobs, v1::ListJobsRequest(), "list");
}

v1::JobStatus ServiceClient::cancel(const std::string& job) {
  v1::CancelJobRequest req;
  req.set_job_id(job);
  return unary<v1::JobStatus>(*stub_, security_, &v1::InvrService::Stub::CancelJob, req, "cancel");
}

v1::ListWorkersResponse ServiceClient::workers() {
  return unary<v1::ListWorkersResponse>(*stub_, security_, &v1::InvrService::Stub::ListWorkers, v1::ListWorkersRequest(), "workers");
}

bool ServiceClient::waitForWorkers(int n, double timeoutSeconds) {
  auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeoutSeconds);
  while (workers().workers_size() < n) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

std::optional<v1::JobStatus> ServiceClient::watch(const std::string& job, uint64_t from,
                                                  const std::function<void(const v1::ProgressEvent&)>& onEvent,
                                                  const std::atomic<bool>& interrupted) {
  uint64_t next = from;
  for (;;) {
    grpc::ClientContext ctx;
    wire::addToken(ctx, security_);
    v1::WatchJobRequest req;
    req.set_job_id(job);
    req.set_from_sequence(next);
    auto reader = stub_->WatchJob(&ctx, req);
    std::atomic<bool> done{false};
    // Ctrl-C cancels the call from this thread (a signal handler cannot).
    std::thread guard([&] {
      while (!done && !interrupted) std::this_thread::sleep_for(std::chrono::milliseconds(50));
      if (interrupted) ctx.TryCancel();
    });
    v1::ProgressEvent ev;
    std::optional<v1::JobStatus> final;
    while (reader->Read(&ev)) {
      next = ev.sequence() + 1;
      onEvent(ev);
      if (ev.has_final()) final = ev.final();
    }
    done = true;
    guard.join();
    grpc::Status st = reader->Finish();
    if (interrupted) return std::nullopt;
    if (final) return final;
    if (st.ok()) return get(job);  // watched from past the end: the job had already finished
    if (st.error_code() != grpc::StatusCode::UNAVAILABLE && st.error_code() != grpc::StatusCode::CANCELLED)
      throwIfFailed(st, "watch " + job);
    // A broken stream (the server may be restarting): wait for the channel to connect again,
    // within the deadline, then resume from the last sequence seen.
    auto deadline = std::chrono::system_clock::now() + std::chrono::duration_cast<std::chrono::system_clock::duration>(
                                                            std::chrono::duration<double>(reconnectSeconds_));
    bool ready = false;
    // A short pause first: a server shutting down gracefully can break the stream while the
    // channel still reads as connected.
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    while (!interrupted && std::chrono::system_clock::now() < deadline) {
      auto slice = std::min(deadline, std::chrono::system_clock::now() + std::chrono::milliseconds(200));
      if (channel_->WaitForConnected(slice)) {
        ready = true;
        break;
      }
    }
    if (interrupted) return std::nullopt;
    if (!ready)
      throw ExitError(exit_code::kServerUnavailable, "watch " + job + ": server unavailable for " + std::to_string(int(reconnectSeconds_)) +
                                                         " s (" + st.error_message() + "); resume with: invr watch " + job +
                                                         " --from " + std::to_string(next));
  }
}

void ServiceClient::fetchOne(const std::string& job, const std::string& name, const std::filesystem::path& dir) {
  // Result names are relative paths (snapshots/step10_view0.png); one that would leave the
  // folder is refused, whatever the server sends.
  const std::filesystem::path rel = std::filesystem::path(name).lexically_normal();
  if (name.empty() || rel.empty() || rel == "." || rel.is_absolute() || rel.has_root_name() || *rel.begin() == ".." || !rel.has_filename())
    throw InputError("fetch: the server named a result '" + name.substr(0, 256) + "' outside the results folder");
  std::filesystem::create_directories((dir / rel).parent_path());
  grpc::ClientContext ctx;
  wire::addToken(ctx, security_);
  v1::FetchResultRequest req;
  req.set_job_id(job);
  req.set_name(name);
  auto reader = stub_->FetchResult(&ctx, req);
  std::filesystem::path tmp = dir / (rel.string() + ".part");
  {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) throw InputError("-o: cannot write to '" + dir.string() + "'");
    v1::AssetChunk c;
    while (reader->Read(&c)) out.write(c.data().data(), std::streamsize(c.data().size()));
  }
  throwIfFailed(reader->Finish(), "fetch " + name);
  std::filesystem::rename(tmp, dir / rel);
}

int ServiceClient::fetchAll(const std::string& job, const std::filesystem::path& dir) {
  v1::JobStatus s = get(job);
  std::filesystem::create_directories(dir);
  for (const auto& name : s.results()) fetchOne(job, name, dir);
  return s.results_size();
}

std::string describeEvent(const v1::ProgressEvent& e) {
  char buf[512];
  if (e.has_step()) {
    const auto& s = e.step();
    std::string err = s.param_error() >= 0 ? ("  param_error " + std::to_string(s.param_error())) : "";
    if (s.shape_error() > 0) err += "  shape_error " + std::to_string(s.shape_error());
    std::snprintf(buf, sizeof buf, "step %llu/%llu  loss %.6g  image_loss %.6g%s  %.1f s  %.2f steps/s  eta %.0f s", (unsigned long long)s.step(),
                  (unsigned long long)s.steps(), s.loss(), s.image_loss(), err.c_str(), s.seconds(), s.steps_per_second(), s.eta_seconds());
    std::string out = buf;
    const v1::GradientStats& st = s.stats();
    if (st.variance_term() != 0 || st.cost() != 0) {
      std::snprintf(buf, sizeof buf, "  (bias %.6g + variance %.6g, cost %.3g rays/sample)", st.bias_term(), st.variance_term(), st.cost());
      out += buf;
    }
    const double rays = double(st.rays().camera() + st.rays().shadow() + st.rays().bounce());
    std::snprintf(buf, sizeof buf, "  %.3g M rays", rays / 1e6);
    out += buf;
    if (const uint64_t dropped = droppedSamples(st)) out += "  non-finite " + std::to_string(dropped);
    return out;
  }
  if (e.has_final()) {
    const auto& f = e.final();
    std::string out = f.job_id() + " " + v1::JobState_Name(f.state());
    if (!f.reason().empty()) out += ": " + f.reason();
    return out;
  }
  return e.message();
}

std::string eventJson(const v1::ProgressEvent& e) { return wire::jsonLine(e); }

}  // namespace invr::cli
