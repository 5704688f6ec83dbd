#include "server/job_resolver.h"

#include <stdlib.h>

#include <filesystem>
#include <set>

#include "core/error.h"
#include "core/io/job_io.h"
#include "core/job/job_source.h"

namespace invr::server {

namespace v1 = invr::v1;
namespace fs = std::filesystem;

namespace {

constexpr int kMaxFiles = 100000;

// A folder of its own for one request, removed with everything in it when the call ends.
class TempFolder {
 public:
  TempFolder() {
    std::string tmpl = (fs::temp_directory_path() / "invr-resolve-XXXXXX").string();
    if (!mkdtemp(tmpl.data())) throw std::runtime_error("cannot create a temporary folder in " + fs::temp_directory_path().string());
    path_ = tmpl;
  }
  ~TempFolder() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

grpc::Status invalid(const std::string& message) { return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, message); }

// A client's file name as a path below the job's folder, or "" if it is not one.
std::string normalisedName(const std::string& name) {
  if (name.empty() || name.find('\0') != std::string::npos || name.find('\\') != std::string::npos) return "";
  fs::path p = fs::path(name).lexically_normal();
  if (p.is_absolute() || p.empty() || p == "." || *p.begin() == "..") return "";
  return p.generic_string();
}

// Messages say the client's paths, not where the server linked them.
std::string withoutFolder(std::string text, const std::string& folder) {
  for (const std::string& f : {folder + "/", folder}) {
    size_t at;
    while ((at = text.find(f)) != std::string::npos) text.erase(at, f.size());
  }
  return text;
}

}  // namespace

grpc::Status resolveJobRequest(const v1::ResolveJobRequest& req, const AssetStore& assets, v1::ResolveJobResponse& resp) {
  if (req.source_case() == v1::ResolveJobRequest::SOURCE_NOT_SET) return invalid("ResolveJobRequest: no source: give zoo, job_json or mitsuba_xml");
  if (req.files_size() > kMaxFiles) return invalid("files: " + std::to_string(req.files_size()) + " files (limit " + std::to_string(kMaxFiles) + ")");
  std::map<std::string, std::string> files;  // normalised name -> sha256
  for (const auto& [name, sha] : req.files()) {
    const std::string key = normalisedName(name);
    if (key.empty())
      return invalid("files['" + name + "']: not a path inside the job's folder (relative, '/'-separated, not climbing out with '..'); "
                     "name a file outside it by content in the job instead ({\"sha256\": ...})");
    if (!AssetStore::validHash(sha)) return invalid("files['" + name + "']: '" + sha + "' is not a sha256 (64 lowercase hex digits)");
    if (!assets.has(sha)) return invalid("files['" + name + "']: no uploaded asset has sha256 " + sha + " (UploadAsset it first)");
    files[key] = sha;
  }
  TempFolder tmp;
  const fs::path root = tmp.path() / "job";
  fs::create_directories(root);
  for (const auto& [key, sha] : files) {
    const fs::path link = root / key;
    std::error_code ec;
    fs::create_directories(link.parent_path(), ec);
    if (!ec) fs::create_symlink(fs::absolute(assets.path(sha)), link, ec);
    if (ec) return invalid("files['" + key + "']: cannot be placed beside the others (" + ec.message() + ")");
  }
  JobSource src;
  switch (req.source_case()) {
    case v1::ResolveJobRequest::kZoo:
      src.kind = JobSource::Kind::Zoo;
      src.zoo = req.zoo();
      src.name = req.zoo();
      break;
    case v1::ResolveJobRequest::kJobJson:
      src.kind = JobSource::Kind::JobJson;
      src.json = req.job_json();
      src.baseDir = root;
      src.name = req.name().empty() ? "job" : req.name().substr(0, 256);
      break;
    default: {
      const std::string key = normalisedName(req.mitsuba_xml());
      if (key.empty()) return invalid("mitsuba_xml: '" + req.mitsuba_xml() + "' is not a path inside the job's folder");
      src.kind = JobSource::Kind::MitsubaXml;
      src.xml = root / key;
      src.name = key;
      break;
    }
  }
  JobOverrides ov;
  ov.params.assign(req.params().begin(), req.params().end());
  ov.defines.assign(req.defines().begin(), req.defines().end());
  ov.sets.assign(req.sets().begin(), req.sets().end());
  const std::string rootText = root.string();
  ResolvedJob r;
  try {
    r = resolveJob(src, ov, req.for_optimization(), /*collectMissing=*/true);
  } catch (const InputError& e) {
    return invalid(withoutFolder(e.what(), rootText));
  }
  std::set<std::string> missing;
  for (const auto& m : r.missing) {
    const std::string key = normalisedName(withoutFolder((r.baseDir / m).lexically_normal().string(), rootText));
    missing.insert(key.empty() ? m : key);
  }
  if (missing.empty()) {
    // Every file the resolved job names: by content, from the uploads.
    std::string error;
    *resp.mutable_spec() = r.job;
    forEachAssetRef(*resp.mutable_spec(), [&](v1::AssetRef& ref, const std::string& field) {
      if (!ref.has_path() || !error.empty()) return;
      fs::path p(ref.path());
      if (p.is_relative()) p = r.baseDir / p;
      const std::string key = normalisedName(withoutFolder(p.lexically_normal().string(), rootText));
      if (key.empty() || p.lexically_normal().string().rfind(rootText + "/", 0) != 0) {
        error = field + ": '" + ref.path() + "' lies outside the job's folder: give the file by content ({\"sha256\": ...}) or at a path relative to the job";
        return;
      }
      auto f = files.find(key);
      if (f == files.end()) {
        missing.insert(key);
        return;
      }
      ref.set_sha256(f->second);  // replaces the path (oneof)
    });
    if (!error.empty()) return invalid(error);
  }
  if (!missing.empty()) {
    resp.clear_spec();
    for (const auto& m : missing) resp.add_missing_files(m);
  }
  for (const auto& w : r.warnings) resp.add_warnings(withoutFolder(w, rootText));
  return grpc::Status::OK;
}

}  // namespace invr::server
