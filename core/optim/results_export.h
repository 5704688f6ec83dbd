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

// A job's scene as described (for a synthetic job, its ground truth) exported to `xml`, and the
// job over it with its parameters' initial values and its targets as given (a synthetic job
// renders its targets from the exported scene). `job` has its scene inline (a zoo scene or an
// imported one), its asset paths relative to assets.baseDir.
ResultsExport exportJob(const invr::v1::JobSpec& job, const std::filesystem::path& xml, const AssetResolver& assets);

}  // namespace invr
