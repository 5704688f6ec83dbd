// Where a job comes from and how it is resolved into one self-contained JobSpec: a zoo scene's
// built-in job, a job's JSON (whose scene may be a Mitsuba file), or a Mitsuba 3 scene file, with
// the overrides every front end offers (-D, --param, --set). The CLI resolves its arguments with
// it, and the server's ResolveJob answers clients (Python) that have no invr build.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "invr/v1/job.pb.h"

namespace invr {

struct JobSource {
  enum class Kind { Zoo, JobJson, MitsubaXml };
  Kind kind = Kind::Zoo;
  std::string zoo;               // Zoo: the scene's name
  std::string json;              // JobJson: the job's text
  std::filesystem::path xml;     // MitsubaXml: the scene file
  std::filesystem::path baseDir; // JobJson: what relative paths in the job resolve against
  std::string name;              // the argument as the user gave it, for errors ("job file 'x.json'")
};

struct JobOverrides {
  std::vector<std::string> defines;  // -D NAME=VALUE: a Mitsuba scene's <default>s
  std::vector<std::string> params;   // --param NAME[=V[,V,V]]: replaces the parameter list
  std::vector<std::string> sets;     // --set FIELD.PATH=VALUE: any job field, after loading
};

struct ResolvedJob {
  invr::v1::JobSpec job;
  std::filesystem::path baseDir;      // the job's relative asset paths resolve against it
  bool imported = false;              // the scene came from a Mitsuba file
  std::vector<std::string> warnings;  // the Mitsuba import's
  // Files the job or its Mitsuba scene names that do not exist (paths relative to baseDir, as
  // written), when resolving with `collectMissing`; the job is then incomplete.
  std::vector<std::string> missing;
};

// Resolves a source with its overrides. `forOptimization`: the job must name parameters (its own
// or --param's; the error says how to give them), and a Mitsuba scene's depth becomes the
// optimisation's. `collectMissing`: a missing file is listed in `missing` instead of an error.
// Throws InputError naming the source and the field at fault.
ResolvedJob resolveJob(const JobSource& source, const JobOverrides& overrides, bool forOptimization, bool collectMissing = false);

// Applies --set overrides: FIELD.PATH=VALUE with the job JSON's field names, list elements by index
// (optimization.parameters[0].learning_rate=0.05 or ...parameters.0...), VALUE as JSON (numbers,
// true, [..], {..}) or else a string. Errors are the job parser's, naming the field.
void applySets(invr::v1::JobSpec& job, const std::vector<std::string>& sets);

// -D NAME=VALUE pairs as a map (InputError naming a malformed one).
std::map<std::string, std::string> parseDefines(const std::vector<std::string>& defines);

// Rewrites the job's relative asset paths (relative to fromDir) relative to toDir, or absolute
// where toDir is far from them.
void rebaseAssetPaths(invr::v1::JobSpec& job, const std::filesystem::path& fromDir, const std::filesystem::path& toDir);

// Imports job.mitsuba into job.scene (asset paths relative to baseDir); render settings the job
// leaves unset come from the scene file. Warnings are appended to `warnings`; with `missing`, a
// file that does not exist is listed there (relative to baseDir) instead of failing.
void importMitsubaIntoJob(invr::v1::JobSpec& job, const std::filesystem::path& baseDir, std::vector<std::string>& warnings,
                          std::vector<std::string>* missing = nullptr);

}  // namespace invr
