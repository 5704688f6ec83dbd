// `invr export`: a results folder (job.json, parameters.json and the files it names) written out
// as a Mitsuba 3 scene with the optimised values in it, and a job file over that scene.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/scene/mitsuba_export.h"
#include "core/scene/scene_builder.h"

namespace invr {

struct ResultsExport {
  MitsubaExport scene;             // the XML and its meshes and images
  std::filesystem::path job;       // <xml stem>.json
  std::vector<std::string> notes;  // the scene's notes, then the job's
};

// Builds the results' job (its assets through `assets`; baseDir should be the results folder),
// writes the optimised values into its scene and exports it to `xml`. The job file beside it
// names the XML as its scene; parameters the scene now holds start from it (their initial values
// dropped), sampling parameters keep their optimised values, group parameters (which Mitsuba
// cannot group) are dropped; a job whose targets were rendered gets the results' target_view<k>.exr
// as its target images when all views have one. Errors name the file at fault.
ResultsExport exportResults(const std::filesystem::path& resultsDir, const std::filesystem::path& xml, const AssetResolver& assets);

}  // namespace invr
