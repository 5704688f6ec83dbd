// Mitsuba 3 scene files (XML) imported as invr jobs: the supported subset is mapped onto invr's
// scene schema, and everything else is an error naming the element and its line, or a warning
// where ignoring it cannot change the image. docs/mitsuba-import.md has the mapping table.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "invr/v1/job.pb.h"

namespace invr {

struct MitsubaImportOptions {
  // Overrides of <default name=... value=...> (what `mitsuba -D name=value` does).
  std::map<std::string, std::string> defaults;
  int sphereRings = 64;  // analytic spheres become uv-sphere meshes of this many rings
  int diskSegments = 128;
  // When set, a file the scene names (a mesh, a bitmap, an included file) that does not exist is
  // listed here, relative to the scene file's folder as far as it lies below it, instead of
  // failing; the import goes on without it (an included file's contents are then missing). The
  // server's ResolveJob asks a client for these files this way.
  std::vector<std::string>* missingFiles = nullptr;
};

struct MitsubaImport {
  // name, scene and render settings; asset paths are relative to the XML file's folder (absolute
  // where the file gave them so).
  invr::v1::JobSpec job;
  std::vector<std::string> warnings;  // "<file>:<line>: <element>: what was ignored and why"
};

bool isMitsubaSceneFile(const std::string& path);  // by extension: .xml

// Throws InputError("<file>:<line>: <element>: <problem>") on anything unsupported or malformed.
MitsubaImport importMitsubaScene(const std::filesystem::path& xml, const MitsubaImportOptions& options = {});
// The same from text in memory; `baseDir` resolves relative file names, `sourceName` names it in errors.
MitsubaImport importMitsubaSceneText(const std::string& xml, const std::filesystem::path& baseDir, const std::string& sourceName,
                                     const MitsubaImportOptions& options = {});

}  // namespace invr
